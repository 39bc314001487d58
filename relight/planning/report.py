"""The scene plan as a typed report (``relight.reports``): what each object needs, what is shared, what is skipped
and why, and the predicted error and seconds (:func:`relight.planning.plan_scene`). Field names are the keys of the
plan's JSON (``relight scene plan --json``, ``plan.json``, the API's ``ScenePublic.plan``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from relight.reports import OMIT_NONE, Report


@dataclass(frozen=True, kw_only=True)
class ErrorSummary(Report):
    """An object's (and the scene's) worst predicted error: minimum of orders (§5.1) and App. B's bound."""

    rms_min_of_errors: float | None = None
    rms_appendix_b: float | None = None
    epsilon_min_of_errors: float | None = None
    epsilon_appendix_b: float | None = None

    @classmethod
    def of(cls, predicted: dict[str, float]) -> ErrorSummary:
        return cls(**{k: predicted.get(k) for k in ("rms_min_of_errors", "rms_appendix_b", "epsilon_min_of_errors",
                                                      "epsilon_appendix_b")})


@dataclass(frozen=True, kw_only=True)
class Computation(Report):
    """One lobe at one output size, computed once and shared by the objects in ``shared_by``. ``predicted`` holds the
    lobe's predicted errors (``relight.reports.PredictedError``'s keys; SHRM lobes add ``rms_brdf``)."""

    id: str
    lobe: dict[str, Any]
    kind: str
    center: str
    representation: str
    structure: str
    reason: str
    F_rho: int
    P_rho: int
    F_L: int | None
    F_B: int
    P_B: int
    n_maps: int
    n_coefficients: int
    size: int
    epsilon_rho: float
    epsilon_rho_below: dict[str, float]
    predicted: dict[str, float]
    shared_by: list[str] = field(default_factory=list)
    order_search_probes: list[list[int]] | None = None
    #: SHRM lobes: the view-band order search's verdict (``relight.shrm.order_search.BandSearch.as_dict``:
    #: ``tolerance_met``, ``grazing_limit``, ``unmet_bands``, ``achievable_by_view``), as ``create_shrm`` reports it
    order_search: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class Effect(Report):
    """An effect simulated or skipped for an object, and why."""

    effect: str
    simulated: bool
    reason: str


@dataclass(frozen=True, kw_only=True)
class ShadowPlan(Report):
    """The per-vertex diffuse transfer an object's run computes (``relight.planning.shadows``): mesh, order F, rays
    per vertex, the predicted Monte Carlo error (i.i.d. bound on the per-vertex norm, absolute and relative to an
    unoccluded vertex's transfer) and seconds, and the Lambertian computations it shadows."""

    kind: str
    mesh: str
    vertices: int
    order: int
    coefficients: int
    rays: int
    predicted_monte_carlo_error: float
    predicted_relative_error: float
    predicted_seconds: float
    lobes: list[str]


@dataclass(frozen=True, kw_only=True)
class Alternative(Report):
    """A representation considered for a lobe and not chosen, and why."""

    representation: str
    why_not: str


@dataclass(frozen=True, kw_only=True)
class LobeRepresentation(Report):
    """Planner v2's choice for one lobe of one object (``relight.planning.represent``): the representation, its
    seed, why, its terms (orders, K, coefficients), the shadows it simulates, the predicted relative RMS error
    (``error_kind``: ``bounded`` by the tolerance's rules, or ``approximate`` where no bound exists and tests
    measure it: seed 002's shadows, and SH tables and PRT matrices, whose prediction is an average over views and
    lighting orientations) with its parts, the predicted precompute seconds of its jobs (before sharing) and
    milliseconds per frame, the jobs (ids of ``ScenePlan.jobs``) and the alternatives."""

    lobe: Any
    kind: str
    representation: str
    seed: str
    reason: str
    terms: dict[str, Any]
    shadows: str
    predicted_error: float
    error_kind: str
    error_parts: dict[str, float]
    predicted_precompute_s: float
    per_frame_ms: float
    jobs: list[str]
    computation: str | None = None
    executed: bool = True
    not_executed_reason: str | None = field(default=None, metadata=OMIT_NONE)
    note: str | None = field(default=None, metadata=OMIT_NONE)
    alternatives: list[Alternative] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class PlannedJob(Report):
    """One precomputation of the plan, shared by every object listed (one chain per environment, one fit or table
    per material, one transfer per mesh and order)."""

    id: str
    kind: str
    params: dict[str, Any]
    predicted_seconds: float
    shared_by: list[str] = field(default_factory=list)
    executed: bool = True


@dataclass(frozen=True, kw_only=True)
class FramePlan(Report):
    """The per-frame cost of drawing the scene (``relight.planning.costs``) against the frame budget."""

    budget_ms: float | None
    predicted_ms: float
    met: bool | None
    per_object_ms: dict[str, float]
    downgrades: list[str] = field(default_factory=list)
    note: str = ("milliseconds on the machine the per-frame constants were fitted on (relight.planning.costs); "
                 "pixels from the object's size and distance on a 1024 x 1024 canvas at 45 degrees")


@dataclass(frozen=True, kw_only=True)
class ObjectPlan(Report):
    """One object: itself (``relight.planning.scene.SceneObject``'s fields), its viewer (distant: one V, the global
    SHRM, eq. 7; near: V per pixel, the local SHRM, eq. 6), output rows, computations, worst error and effects."""

    name: str
    shape: str
    size: float
    distance: float
    material: Any
    view: list[float]
    view_dependent: bool
    viewer: str
    shrm: str
    view_spread_deg: float
    p_delta: float
    near_below_distance: float
    output_rows: int
    computations: list[str]
    predicted_error: ErrorSummary
    effects: list[Effect]
    #: the diffuse transfer the run computes (``relight.planning.shadows``), None without shadows
    shadows: ShadowPlan | None = field(default=None, metadata=OMIT_NONE)
    #: planner v2 (issue 16 item 4): the object's requests and each lobe's representation
    shadows_requested: str = "auto"
    interreflections: bool = False
    mesh: str | None = field(default=None, metadata=OMIT_NONE)
    tangent: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)
    material_edited: bool = False
    representations: list[LobeRepresentation] = field(default_factory=list)
    per_frame_ms: float = 0.0


@dataclass(frozen=True, kw_only=True)
class LightingPlan(Report):
    """The lighting projection, done once to the largest order any lobe needs and shared (App. C)."""

    F_proj: int
    projected_once: bool = True
    input: dict[str, int]
    seconds: float
    shared_by: list[str]
    reason: str = "projected once to the largest order any lobe needs, then shared (App. C)"


@dataclass(frozen=True, kw_only=True)
class BudgetStep(Report):
    """One tolerance tried under a time budget."""

    epsilon: float
    predicted_seconds: float
    fits: bool
    predicted_rms: float | None


@dataclass(frozen=True, kw_only=True)
class CostModelInfo(Report):
    """Which cost model predicted the seconds (``relight.costmodel``)."""

    calibrated: bool
    key: str
    note: str = ("includes the BRDF order search and coefficients, the projection, every map and one eq. 12 view per "
                 "object; not file writing")


@dataclass(frozen=True, kw_only=True)
class ScenePlan(Report):
    """A planned scene (module docstring). The budget keys are present only under a time budget."""

    format: str = "relight-scene-plan"
    relight_version: str
    scene: str
    environment: str
    epsilon: float
    time_budget_s: float | None
    mode: str
    lighting: LightingPlan
    computations: list[Computation]
    objects: list[ObjectPlan]
    brdf_seconds: float
    predicted_seconds: float
    predicted_stages: dict[str, float]
    predicted_error: ErrorSummary
    cost_model: CostModelInfo
    budget_met: bool | None = field(default=None, metadata=OMIT_NONE)
    budget_ladder: list[BudgetStep] | None = field(default=None, metadata=OMIT_NONE)
    #: planner v2: the scene's lighting mode, the shared jobs and the per-frame cost against the frame budget
    lighting_mode: str = "static"
    jobs: list[PlannedJob] = field(default_factory=list)
    frame: FramePlan | None = field(default=None, metadata=OMIT_NONE)
    budget_note: str | None = field(default=None, metadata=OMIT_NONE)


# ------------------------------------------------------------------------------------------------ a plan's run
@dataclass(frozen=True, kw_only=True)
class ObjectFiles(Report):
    """The files written for one object (names inside the run's folder; the service stores each as a blob): its
    SHRM (``relight.shrm_io``) and manifest, the eq. 12 map for its view, the optional sphere preview and, in the
    service, the viewer's float16 texture and its manifest."""

    shrm: str | None = field(default=None, metadata=OMIT_NONE)
    manifest: str | None = field(default=None, metadata=OMIT_NONE)
    view_map: str | None = field(default=None, metadata=OMIT_NONE)
    sphere_png: str | None = field(default=None, metadata=OMIT_NONE)
    coefficients_bin: str | None = field(default=None, metadata=OMIT_NONE)
    texture: str | None = field(default=None, metadata=OMIT_NONE)
    #: the per-vertex shadowed transfer of a Lambertian mesh object (``relight.planning.shadows``)
    transfer: str | None = field(default=None, metadata=OMIT_NONE)
    #: in the service, the viewer's form of that transfer (``relight.worker.scene_prt``: ``{name}.prt.json``)
    prt: str | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class ObjectResult(Report):
    """One object of a run: its viewer and SHRM layout (from its :class:`ObjectPlan`), output rows, files and, for
    Lambertian lobes, the irradiance coefficients (per computation id: 3 colours x (F + 1)^2 real SH)."""

    name: str
    viewer: str
    shrm: str
    output_rows: int
    files: ObjectFiles = field(default_factory=ObjectFiles)
    irradiance_real_sh: dict[str, list[list[float]]] | None = field(default=None, metadata=OMIT_NONE)
    #: what the shadowed transfer was computed with and its measured Monte Carlo errors (``relight.planning.shadows``)
    shadows: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class JobRun(Report):
    """One planner-v2 job as run (``relight.planning.run_jobs``): its files (names inside the run's folder), a
    summary of what it computed, measured seconds next to the predicted ones; ``executed = False``: listed only."""

    id: str
    kind: str
    shared_by: list[str]
    executed: bool
    files: list[str] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)
    measured_seconds: float | None = field(default=None, metadata=OMIT_NONE)
    predicted_seconds: float


@dataclass(frozen=True, kw_only=True)
class SceneResult(Report):
    """What running a plan did (:func:`relight.planning.run_plan`; ``result.json``, the API's
    ``ScenePublic.result``): the objects, the computations run (each once), and measured seconds per stage next to
    the predicted ones."""

    format: str = "relight-scene-result"
    relight_version: str
    scene: str
    epsilon: float
    objects: list[ObjectResult]
    computed: list[str]
    lighting_projections: int = 1
    measured_seconds: float
    measured_stages: dict[str, float]
    predicted_seconds: float
    predicted_stages: dict[str, float]
    #: planner v2's jobs (Gaussian fits and chains, SH tables, visibility, transfer matrices, in-out transport)
    jobs: list[JobRun] = field(default_factory=list)
