"""Jobs: the SHRM request (``POST /shrms``, ``POST /plan``), the generic ``POST /jobs`` submission, a job of any
kind as the API shows it, and a finished SHRM's manifest.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from relight.contract.base import Digest, JobState, Public, Strict
from relight.contract.engine import SUN_PATTERN
from relight.contract.reports import Orders, PredictedError, ViewBand
from relight.contract.resources import BrdfRef


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


class ShrmCreate(JobCreate):
    sun: str = Field("keep", max_length=40, pattern=SUN_PATTERN,
                     description="extract: prefilter the map without its sun (the result's input.sun holds it as a "
                                 "directional light), clamp=V: pixel luminance <= V (removed energy recorded), keep; "
                                 "relight.sun. The plan is of the map as uploaded")


class PlanCreate(ShrmCreate):
    """``POST /plan``: the body ``POST /shrms`` takes; with ``sun=extract`` and a tolerance the plan's ``sun`` shows
    the order each lobe needs with and without the sun."""


class OutputShape(Public):
    height: int
    width: int
    layers: int
    exr_bytes_estimate: int
    bin_bytes: int


class SunLobeOrders(Public):
    """One lobe's order with and without the sun (``relight.planning.sun_orders``)."""

    kind: str
    center: str
    F_B: int = Field(description="the lobe's planned order")
    P_B: int = Field(description="the lobe's planned view order")
    order_with_sun: int = Field(description="smallest F <= F_B whose predicted error per view band meets epsilon "
                                "under the map as uploaded (F_B when none does)")
    met_with_sun: bool
    order_without_sun: int = Field(description="the residual's order when the output is its SHRM plus the sun as "
                                   "a point light: their errors (triangle inequality) held to epsilon of the map's "
                                   "output energy")
    met_without_sun: bool
    order_residual_alone: int = Field(description="the residual's order held to epsilon of its own output energy")
    met_residual_alone: bool
    factor: float = Field(description="order_with_sun / order_without_sun: the order reduction the extraction buys")


class SunPlan(Public):
    extracted: dict[str, Any] = Field(description="the sun relight.sun.extract_sun finds (as the job's input.sun)")
    epsilon: float
    lobes: list[SunLobeOrders]


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
    sun: SunPlan | None = Field(None, description="sun=extract with a tolerance: per lobe the order with and without "
                                "the sun")


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
    sun: str | None = Field(None, description="the sun step (ShrmCreate.sun) when not keep")


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
