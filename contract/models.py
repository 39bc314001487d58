"""Request and response models shared by the server and the client (pydantic only: no FastAPI, no NumPy).

``...Create`` models are request bodies, ``...Public`` models are responses (full-stack-fastapi-template style).
"""

from __future__ import annotations

import dataclasses
import math
from datetime import datetime
from enum import StrEnum
from typing import Annotated, Any, ClassVar, Literal, Self

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, WithJsonSchema, model_validator

from relight import reports
from relight.contract.brdfs import BrdfSpec
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

Digest = Annotated[str, Field(pattern=r"^[0-9a-f]{64}$", description="SHA-256, 64 lowercase hex digits")]


class Strict(BaseModel):
    """Request models: unknown keys and NaN/Inf are rejected (422 naming the field)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Public(BaseModel):
    model_config = ConfigDict(extra="ignore")


class JobState(StrEnum):
    queued = "queued"
    running = "running"
    succeeded = "succeeded"
    failed = "failed"
    cancelled = "cancelled"

    @property
    def terminal(self) -> bool:
        return self in (JobState.succeeded, JobState.failed, JobState.cancelled)


ACTIVE_STATES = (JobState.queued, JobState.running)


class Problem(Public):
    """RFC 9457 problem details (``application/problem+json``)."""

    type: str = "about:blank"
    title: str
    status: int
    detail: str | None = None
    instance: str | None = None
    errors: list[dict[str, Any]] | None = Field(default=None, description="per-field validation errors")


# -------------------------------------------------------------------------------------------------- envmaps
class EnvmapPublic(Public):
    id: Digest = Field(description="SHA-256 of the uploaded bytes")
    name: str | None = None
    format: str = Field(description="exr, hdr, png or jpeg")
    layout: str = Field(description="latlong, or the cube-map layout that was resampled")
    width: int
    height: int
    bytes: int
    min: list[float] = Field(description="per-channel minimum (after clamping negatives)")
    max: list[float]
    mean: list[float]
    negatives_clamped: int = Field(description="channel values below 0 that were set to 0")
    min_negative: float
    non_finite: int = Field(0, description="NaN/Inf values (always 0: such maps are rejected)")
    spectrum_lmax: int
    sh_power_spectrum: list[float] = Field(description="luminance energy per band l = 0..spectrum_lmax")
    total_energy: float = Field(description="integral of luminance^2 over the sphere")
    created_at: datetime
    links: dict[str, str] = {}


class EnvmapList(Public):
    items: list[EnvmapPublic]


# -------------------------------------------------------------------------------------------------- meshes
class MeshPublic(Public):
    """A mesh welded into relight's canonical vertex order (``docs/conventions.md``, "Meshes")."""

    id: Digest = Field(description="SHA-256 of the uploaded bytes")
    name: str | None = None
    format: str | None = Field(None, description="obj, gltf or glb")
    bytes: int
    vertices: int = Field(description="welded vertices, in the order every per-vertex result uses")
    faces: int
    bounds: dict[str, list[float]]
    bounding_radius: float
    surface_area: float
    watertight: bool
    tangent_source: str = Field(description="file (glTF TANGENT), uv (texture coordinates) or field")
    normal_weighting: str
    defects: dict[str, Any] = Field(description="boundary / non-manifold / inconsistently oriented edges, "
                                    "degenerate and collapsed faces, welded and unreferenced vertices (reported, "
                                    "not refused)")
    geometry: dict[str, Any] = Field(description="geometry.bin: sha256, byte size and the offset, dtype and shape "
                                     "of positions, normals, tangents and indices")
    created_at: datetime
    links: dict[str, str] = {}


class MeshList(Public):
    items: list[MeshPublic]


VisibilityKind = Literal["visibility", "diffuse_transfer", "shadow_matrix"]


class VisibilityCreate(Strict):
    """Per-vertex SH visibility / diffuse transfer / shadow matrix of a mesh by ray casting (``relight.visibility``;
    order F means l <= F, (F+1)^2 coefficients)."""

    mesh: Digest = Field(description="a mesh id from POST /meshes")
    order: int = Field(3, ge=0, le=8, description="SH order F")
    rays: int = Field(1024, ge=16, le=65536, description="rays per vertex (spherical Fibonacci, randomly rotated)")
    kind: VisibilityKind = "visibility"
    bounces: int = Field(0, ge=0, le=8, description="interreflection bounces (diffuse_transfer only)")
    albedo: float = Field(0.8, ge=0.0, le=1.0, description="albedo of the interreflections")
    seed: int = Field(0, ge=0, lt=2**31, description="rotation of the direction set")
    block: int = Field(1024, ge=64, le=65536, description="vertices per block (the unit fanned out over workers)")

    @model_validator(mode="after")
    def _bounces(self) -> VisibilityCreate:
        if self.bounces and self.kind != "diffuse_transfer":
            raise ValueError(f"bounces ({self.bounces}) need kind 'diffuse_transfer', got {self.kind!r}")
        return self


# -------------------------------------------------------------------------------------------------- seed 002
class GaussianFitCreate(Strict):
    """Gaussian lobes fitted to an isotropic BRDF at view elevations (seed 002 §4, ``relight.sgfit``)."""

    brdf: BrdfRef
    lobes: int = Field(3, ge=1, le=8, description="Gaussians K per elevation")
    max_lobes: int | None = Field(None, ge=1, le=8, description="add lobes up to this many where the error exceeds "
                                  "5 % (default: lobes + 2, at most 8; equal to lobes: the paper's fixed K)")
    elevations: int = Field(15, ge=2, le=64, description="view elevations N, equally spaced from 0")
    theta_max_deg: float = Field(87.0, gt=0.0, lt=90.0, description="largest elevation in degrees")

    @model_validator(mode="after")
    def _max_lobes(self) -> GaussianFitCreate:
        if self.max_lobes is not None and self.max_lobes < self.lobes:
            raise ValueError(f"max_lobes ({self.max_lobes}) must be >= lobes ({self.lobes})")
        return self


class GaussianChainCreate(Strict):
    """The Gaussian-prefiltered chain of an environment map (seed 002 §5.1, ``relight.gaussian_chain``)."""

    envmap: Digest
    ratio: Literal["2", "sqrt2"] = Field("2", description="sigma ratio between levels")
    levels: int | None = Field(None, ge=1, le=32, description="number of levels (default: up to 90 degrees)")
    epsilon: float = Field(0.01, gt=0.0, lt=1.0,
                           description="tolerance for every level's SH order (relight chain's default)")
    sigma0: float | None = Field(None, gt=0.0, le=math.pi, description="sharpest sigma in radians (default pi / H)")
    uniform_size: bool = Field(False, description="every level at the input's size (one GPU texture array)")


# -------------------------------------------------------------------------------------------------- brdfs
class BrdfPublic(Public):
    id: Digest = Field(description="SHA-256 of the canonical spec (or of the measured file)")
    kind: str
    spec: dict[str, Any] = Field(description="canonical parameters, as accepted by POST /brdfs")
    radially_symmetric: bool
    center: str | None = Field(None, description="R (reflection vector), N (normal) or T (tangent)")
    measured: bool = False
    created_at: datetime
    links: dict[str, str] = {}


BrdfRef = Annotated[
    Digest | BrdfSpec | str,
    Field(description="a BRDF id from POST /brdfs, a spec object, or a spec string such as 'phong:s=32'"),
]


# -------------------------------------------------------------------------------------------------- plan / jobs
class JobCreate(Strict):
    """What to compute: an environment map, a BRDF, and either a tolerance or explicit orders."""

    envmap: Digest
    brdf: BrdfRef
    epsilon: float | None = Field(None, gt=0.0, lt=1.0, description="energy fraction not captured (seed 000 §5.1)")
    order: int | None = Field(None, ge=0, description="explicit order F")
    p_order: int | None = Field(None, ge=0, description="explicit view order P (SHRMs)")
    size: int | None = Field(None, ge=2, description="output rows S (the map is S x 2S); default S ~ 10 F")

    @model_validator(mode="after")
    def _one_of(self) -> JobCreate:
        if self.epsilon is not None and self.order is not None:
            raise ValueError(f"give either epsilon ({self.epsilon}) or order ({self.order}), not both")
        return self


class PlanCreate(JobCreate):
    pass


class ShrmCreate(JobCreate):
    pass


class CoreReport(Public):
    """A model that wraps one of the core's typed reports (``relight.reports``) field for field: the same names
    (checked when this module loads, :func:`_same_fields`), built from the report's JSON form (:meth:`from_core`)."""

    core: ClassVar[type[Any]]

    @classmethod
    def from_core(cls, report: Any) -> Self:
        """The model of a core report instance (its ``to_json()``)."""
        if not isinstance(report, cls.core):
            raise TypeError(f"{cls.__name__} wraps {cls.core.__name__}, got {type(report).__name__}")
        return cls.model_validate(report.to_json())


class Orders(CoreReport):
    core: ClassVar[type[Any]] = reports.Orders

    F_L: int | None = None
    F_rho: int | None = None
    F_B: int
    P_B: int = 0


class ViewBand(CoreReport):
    """The predicted error for views with N.V in ``ndotv`` (``relight.reports.ViewBand``, issue 18)."""

    core: ClassVar[type[Any]] = reports.ViewBand

    ndotv: tuple[float, float]
    rms: float = Field(description="predicted relative RMS error in the band (average over orientations x margin)")
    rms_appendix_b: float = Field(description="App. B's bound on the band's average relative RMS error")
    rms_average: float = Field(description="the band's relative RMS error averaged over orientations of the light")
    epsilon: float
    epsilon_appendix_b: float
    epsilon_brdf: float = Field(description="the lobe's own uncaptured energy in the band")
    enforced: bool | None = Field(None, description="the band lies above the grazing limit: the tolerance holds")
    met: bool | None = Field(None, description="the orders meet the tolerance in the band")
    achievable_epsilon_brdf: float | None = Field(None, description="the smallest epsilon_brdf the band can reach "
                                                  "within the caps (F <= 1024, P <= 16)")


class PredictedError(CoreReport):
    core: ClassVar[type[Any]] = reports.PredictedError

    epsilon_lighting: float | None = None
    epsilon_brdf: float | None = None
    epsilon_min_of_errors: float | None = None
    rms_min_of_errors: float | None = Field(None, description="predicted relative RMS error (sqrt of epsilon)")
    epsilon_appendix_b: float | None = None
    rms_appendix_b: float | None = None
    by_view: list[ViewBand] | None = Field(None, description="the predicted error per view band (N.V in [0, 0.3], "
                                           "[0.3, 0.7], [0.7, 1])")
    grazing_limit: float | None = Field(None, description="the tolerance holds for views with N.V at least this")


def _same_fields(model: type[CoreReport]) -> None:
    core = {f.name for f in dataclasses.fields(model.core)}
    if set(model.model_fields) != core:
        raise TypeError(f"{model.__name__} must have the fields of {model.core.__qualname__}: {sorted(core)}")


for _m in (Orders, ViewBand, PredictedError):
    _same_fields(_m)


class OutputShape(Public):
    height: int
    width: int
    layers: int
    exr_bytes_estimate: int
    bin_bytes: int


class PlanPublic(Public):
    job_id: Digest = Field(description="the id a job with these inputs gets (identical requests share it)")
    cached: bool = Field(description="a finished result exists already")
    representation: str = Field(description="reflection_map (radially symmetric lobe) or shrm")
    reason: str
    orders: Orders
    predicted_error: PredictedError
    predicted_seconds: float
    output: OutputShape
    cost_model: dict[str, Any] | None = Field(None, description="the cost model behind predicted_seconds: calibrated "
                                              "on this machine (relight.costmodel) or the built-in defaults")


class JobSubmit(Strict):
    """``POST /jobs``: a job of any registered kind; ``request`` is validated by the kind's own model (for ``shrm``
    a ``ShrmCreate``, ``tradeoff`` a ``TradeoffCreate``, ``scene`` a ``SceneCreate``)."""

    kind: str = Field(min_length=1, max_length=32, description="a job kind of the server (GET /jobs/kinds)")
    request: dict[str, Any] = Field(description="the kind's request, as its own route takes it")


class JobKindList(Public):
    items: list[str] = Field(description="the job kinds POST /jobs takes")


class JobParams(Public):
    epsilon: float | None = None
    order: int | None = None
    p_order: int | None = None
    size: int | None = None


class Prediction(Public):
    seconds: float | None = None
    rms_error: float | None = None
    orders: Orders | None = None
    representation: str | None = None
    by_view: list[ViewBand] | None = Field(None, description="the plan's predicted error per view band")


class Measurement(Public):
    seconds: float | None = Field(None, description="wall time from the first submission to the result")
    task_seconds: float | None = Field(None, description="time inside the worker task")
    compute_seconds: float | None = Field(None, description="time in the numerical core")
    stage_seconds: dict[str, float] | None = Field(None, description="the core's seconds per stage")
    rms_error: float | None = Field(None, description="the core's error estimate from the full spectra")
    rms_bound: float | None = Field(None, description="App. B conservative bound on the relative RMS error")
    orders: Orders | None = None
    reused: bool = False
    processes: int | None = Field(None, description="worker processes that computed parts of the job (kinds fanned "
                                  "out by blocks)")


class JobPublic(Public):
    """A job of any kind; ``envmap`` / ``brdf`` / ``brdf_spec`` / ``params`` describe an ``shrm`` job (the map also
    a sweep's and a scene's), ``request`` is the kind's canonical request."""

    id: Digest
    kind: str = Field("shrm", description="shrm, tradeoff, scene, ... (the job kinds of the server)")
    state: JobState
    stage: str | None = None
    progress: float = 0.0
    envmap: Digest | None = None
    brdf: Digest | None = None
    brdf_spec: dict[str, Any] | None = None
    params: JobParams | None = None
    request: dict[str, Any] | None = Field(None, description="the canonical request the job's id is the hash of")
    predicted: Prediction | None = None
    measured: Measurement | None = None
    failure_reason: str | None = None
    runs: int = Field(0, description="times a worker started this job (> 1 after a worker died or a restart)")
    submissions: int = Field(0, description="times the server submitted it to the cluster")
    worker: str | None = None
    cached: bool = Field(False, description="in a POST /shrms answer: the result existed already")
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None
    links: dict[str, str] = {}


class JobList(Public):
    items: list[JobPublic]


# -------------------------------------------------------------------------------------------------- results
class LayerInfo(Public):
    index: int
    name: str = Field(description="EXR layer name ('' for plain R, G, B channels)")
    component: int = Field(0, description="lobe of a sum-of-lobes material")
    p: int
    q: int


class ShrmManifest(BaseModel):
    """The manifest of a finished result (``GET /shrms/{id}``); every file is content-addressed."""

    model_config = ConfigDict(extra="allow")

    format: str
    format_version: int
    id: Digest
    representation: str
    height: int
    width: int
    layers: list[LayerInfo]
    files: dict[str, dict[str, Any]]
    envmap: Digest
    brdf: dict[str, Any]
    params: dict[str, Any]
    algorithm_version: str
    orders: dict[str, Any] | None = None
    predicted: dict[str, Any] | None = None


# -------------------------------------------------------------------------------------------------- tradeoffs
Fraction = Annotated[float, Field(gt=0.0, lt=1.0)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3, description="x, y, z (normalised here)")]


class TradeoffCreate(Strict):
    """An accuracy–time sweep (``relight.tradeoff``): the frequency method at several tolerances and the angular
    method at several truncations, on one map and BRDF, measured against the untruncated angular reference."""

    envmap: Digest
    brdf: BrdfRef
    rows: int | None = Field(None, ge=8, le=256, description="area-average the map to this many rows (default 64)")
    size: int | None = Field(None, ge=4, le=128, description="output rows S of every map (default rows / 2)")
    epsilons: list[Fraction] | None = Field(None, min_length=1, max_length=10, description="frequency method")
    truncations: list[Fraction] | None = Field(None, max_length=10, description="angular method (App. D)")
    view: Vector3 | None = Field(None, description="view direction for view-dependent BRDFs")


class TradeoffPublic(Public):
    id: Digest
    state: JobState
    stage: str | None = None
    progress: float = 0.0
    failure_reason: str | None = None
    envmap: Digest
    brdf: Digest
    brdf_spec: dict[str, Any]
    params: dict[str, Any]
    points: list[dict[str, Any]] | None = Field(None, description="method, orders, predicted_error, measured_error, "
                                                "mitsuba_error (null without a Mitsuba 3 twin), image_error, "
                                                "predicted_seconds, measured_seconds, pareto, ... per point")
    meta: dict[str, Any] | None = Field(None, description="what the sweep ran on; mitsuba: the Mitsuba 3 "
                                        "comparison's settings, noise floor and reference_error, or computed "
                                        "false and the reason")
    created_at: datetime
    finished_at: datetime | None = None
    links: dict[str, str] = {}


# -------------------------------------------------------------------------------------------------- scenes
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


class Health(Public):
    status: str = Field(description="ok, or degraded (the reasons are in problems)")
    version: str
    algorithm_version: str
    scheduler: str = Field(description="embedded or external (the address is never published)")
    workers: int
    database: str
    problems: list[str] = Field(default_factory=list,
                                description="what is degraded: workers, scheduler, database, disk")


def parse_view(text: str) -> tuple[float, float, float]:
    """``"x,y,z"`` to a unit vector; raises ``ValueError`` quoting the text when it is not one."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"view must be three comma-separated numbers x,y,z, got {text!r}")
    try:
        v = tuple(float(p) for p in parts)
    except ValueError:
        raise ValueError(f"view must be three comma-separated numbers x,y,z, got {text!r}") from None
    if not all(math.isfinite(c) for c in v):
        raise ValueError(f"view components must be finite, got {text!r}")
    n = math.sqrt(sum(c * c for c in v))
    if n < 1e-12:
        raise ValueError(f"view must be a non-zero vector, got {text!r}")
    return (v[0] / n, v[1] / n, v[2] / n)
