"""Scenes for the planner (``POST /scenes``, ``relight.planning``): the scene schema and a run's plan and result.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Field, StrictBool, WithJsonSchema, model_validator

from relight.contract.base import Digest, JobState, Public, Strict, Vector3
from relight.contract.resources import BrdfRef
from relight.planning.report import ScenePlan, SceneResult
from relight.planning.scene import (
    LIGHTING_MODES,
    MAX_FRAME_BUDGET_MS,
    MAX_OBJECT_DISTANCE,
    MAX_OBJECT_SIZE,
    MAX_SCENE_OBJECTS,
    MAX_SCENE_SIZE,
    MAX_TIME_BUDGET_S,
    MIN_SCENE_SIZE,
    NAME_PATTERN,
    SHADOW_MODES,
    SHAPES,
)

# The scene schema is the core's (relight.planning.scene): its limits, shapes and name pattern are imported, so a
# scene the CLI accepts the API accepts. Only the previews' size is a service limit (the core renders none).
SceneName = Annotated[str, Field(pattern=NAME_PATTERN)]
#: Service limit on the N x N sphere previews of a scene run.
MAX_PREVIEW_SIZE = 256


def _shape(value: str) -> str:
    if value not in SHAPES:
        raise ValueError(f"must be one of {list(SHAPES)}, got {value!r}")
    return value


Shape = Annotated[str, AfterValidator(_shape), WithJsonSchema({"type": "string", "enum": list(SHAPES)})]


class TangentField(Strict):
    """A tangent field for anisotropic materials (``relight.planning.scene.TANGENT_KINDS``)."""

    kind: Literal["azimuthal", "project", "mesh"]
    axis: Vector3 | None = Field(None, description="azimuthal: the field's axis (default +Y)")
    direction: Vector3 | None = Field(None, description="project: the brushing direction projected on the surface")

    @model_validator(mode="after")
    def _keys(self) -> TangentField:
        if self.kind == "project" and self.direction is None:
            raise ValueError("kind 'project' needs a direction")
        if self.kind != "azimuthal" and self.axis is not None:
            raise ValueError("axis belongs to kind 'azimuthal'")
        if self.kind != "project" and self.direction is not None:
            raise ValueError("direction belongs to kind 'project'")
        return self


class SceneObjectCreate(Strict):
    name: SceneName | None = None
    shape: Shape | None = Field(None, description="a sample shape (default sphere); or give mesh")
    mesh: Digest | None = Field(None, description="an uploaded mesh (POST /meshes) instead of a sample shape")
    size: float = Field(gt=0.0, le=MAX_OBJECT_SIZE, description="bounding radius")
    distance: float = Field(gt=0.0, le=MAX_OBJECT_DISTANCE,
                            description="from the viewer to the object's centre (> size)")
    material: BrdfRef
    view: Vector3 | None = Field(None, description="direction from the object toward the viewer (default +Z)")
    shadows: Literal[SHADOW_MODES] = Field(  # type: ignore[valid-type]
        "auto", description="none, approximate (seed 002), exact (seeds 003/004) or auto (on for meshes)")
    interreflections: StrictBool = Field(False, description="simulate light bouncing within the object")
    tangent: TangentField | None = Field(None, description="tangent field of anisotropic materials")

    @model_validator(mode="after")
    def _shape_or_mesh(self) -> SceneObjectCreate:
        if self.mesh is not None and self.shape is not None:
            raise ValueError("give either shape (a sample shape) or mesh (an uploaded mesh), not both")
        if self.tangent is not None and self.tangent.kind == "mesh" and self.mesh is None and self.shape in (
                None, "sphere"):
            raise ValueError("tangent kind 'mesh' needs a mesh (the analytic sphere has no stored tangents)")
        return self


class SceneCreate(Strict):
    """A scene for the planner (``relight.planning``): a map, objects, and a tolerance or a time budget."""

    name: SceneName = "scene"
    environment: Digest
    objects: list[SceneObjectCreate] = Field(min_length=1, max_length=MAX_SCENE_OBJECTS)
    epsilon: float | None = Field(None, gt=0.0, lt=1.0, description="tolerance (seed 000 §5.1)")
    time_budget_s: float | None = Field(None, gt=0.0, le=MAX_TIME_BUDGET_S, description="or a time budget in seconds")
    size: int | None = Field(None, ge=MIN_SCENE_SIZE, le=MAX_SCENE_SIZE,
                             description="output rows of every map (default S ~ 10 F)")
    preview_size: int = Field(0, ge=0, le=MAX_PREVIEW_SIZE, description="also render N x N sphere previews")
    lighting: Literal[LIGHTING_MODES] = Field(  # type: ignore[valid-type]
        "static", description="static, rotating or dynamic (new lighting every frame)")
    material_edits: StrictBool | list[SceneName] = Field(
        False, description="materials edited live: true for all, or the names of the edited objects")
    frame_budget_ms: float | None = Field(None, gt=0.0, le=MAX_FRAME_BUDGET_MS,
                                          description="per-frame budget of the viewer, milliseconds")

    @model_validator(mode="after")
    def _one_of(self) -> SceneCreate:
        if (self.epsilon is None) == (self.time_budget_s is None):
            raise ValueError("give exactly one of epsilon or time_budget_s")
        if isinstance(self.material_edits, list):
            names = [o.name or f"object{k}" for k, o in enumerate(self.objects)]
            missing = sorted(set(self.material_edits) - set(names))
            if missing:
                raise ValueError(f"material_edits names no object {missing[0]!r}")
        return self


class ScenePublic(Public):
    id: Digest
    state: JobState
    stage: str | None = None
    progress: float = 0.0
    failure_reason: str | None = None
    scene: dict[str, Any]
    plan: ScenePlan | None = Field(None, description="per object: what is simulated, what is skipped and why "
                                                     "(the core's relight.planning.ScenePlan)")
    result: SceneResult | None = Field(None, description="what the run did (the core's relight.planning.SceneResult)")
    files: dict[str, dict[str, Any]] | None = Field(None, description="name -> sha256, bytes, media_type")
    created_at: datetime
    finished_at: datetime | None = None
    links: dict[str, str] = {}
