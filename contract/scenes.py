"""Scenes for the planner (``POST /scenes``, ``relight.planning``): the scene schema and a run's plan and result.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from pydantic import AfterValidator, Field, WithJsonSchema, model_validator

from relight.contract.base import Digest, JobState, Public, Strict, Vector3
from relight.contract.resources import BrdfRef
from relight.planning.report import ScenePlan, SceneResult
from relight.planning.scene import (
    MAX_OBJECT_DISTANCE,
    MAX_OBJECT_SIZE,
    MAX_SCENE_OBJECTS,
    MAX_SCENE_SIZE,
    MAX_TIME_BUDGET_S,
    MIN_SCENE_SIZE,
    NAME_PATTERN,
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


class SceneObjectCreate(Strict):
    name: SceneName | None = None
    shape: Shape = "sphere"
    size: float = Field(gt=0.0, le=MAX_OBJECT_SIZE, description="bounding radius")
    distance: float = Field(gt=0.0, le=MAX_OBJECT_DISTANCE,
                            description="from the viewer to the object's centre (> size)")
    material: BrdfRef
    view: Vector3 | None = Field(None, description="direction from the object toward the viewer (default +Z)")


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

    @model_validator(mode="after")
    def _one_of(self) -> SceneCreate:
        if (self.epsilon is None) == (self.time_budget_s is None):
            raise ValueError("give exactly one of epsilon or time_budget_s")
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
