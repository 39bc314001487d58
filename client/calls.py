"""The API as request descriptions shared by both SDK clients (:mod:`relight.client.sdk`): one :class:`Call` per
operation (method, path, how to parse the answer into a :mod:`relight.contract.models` model), the request bodies
built from keyword arguments, and the checks of a finished job."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import httpx
from pydantic import BaseModel

from relight.client.errors import JobFailed
from relight.contract.models import (
    BrdfPublic,
    EnvmapList,
    EnvmapPublic,
    Health,
    JobList,
    JobPublic,
    JobState,
    PlanPublic,
    SceneCreate,
    ScenePublic,
    ShrmManifest,
    TradeoffPublic,
)

T = TypeVar("T")
Source = str | os.PathLike[str] | bytes
Spec = str | dict[str, Any] | BaseModel
CHUNK = 1 << 20
DEFAULT_URL = "http://127.0.0.1:8000"


def model_parser(cls: type[BaseModel]) -> Callable[[httpx.Response], Any]:
    return lambda r: cls.model_validate_json(r.content)


def raw_bytes(r: httpx.Response) -> bytes:
    return r.content


@dataclass
class Call(Generic[T]):
    method: str
    path: str
    parse: Callable[[httpx.Response], T]
    kwargs: dict[str, Any] = field(default_factory=dict)


#: Seconds a client keeps following ``Retry-After`` on 429 (the server's active-job cap is full) before giving up.
RETRY_429_S = 300.0
#: Each wait is ``Retry-After`` times a random factor in [1, 1 + RETRY_JITTER]: clients refused together do not all
#: come back in the same instant.
RETRY_JITTER = 0.5


def retry_wait(resp: httpx.Response, call: Call[Any], deadline: float, now: float) -> float | None:
    """Seconds to wait before sending ``call`` again after ``resp``, or None: only a 429 with ``Retry-After``, only a
    call whose body can be sent again (JSON or bytes; a streamed upload is never refused for the cap), and only
    while the wait ends before ``deadline`` (a ``time.monotonic`` value)."""
    import random

    if resp.status_code != 429:
        return None
    content = call.kwargs.get("content")
    if content is not None and not isinstance(content, bytes):
        return None
    try:
        after = max(0.0, float(resp.headers.get("retry-after", "")))
    except ValueError:
        return None
    wait = after * (1.0 + RETRY_JITTER * random.random())  # noqa: S311 - spreading retries, not a secret
    return wait if now + wait < deadline else None


@dataclass(frozen=True)
class IblAnswer:
    """One answer of ``GET /envmaps/{id}/ibl``: the file (200) or, while it is computed, the job (202)."""

    job_id: str
    data: bytes | None
    job: JobPublic | None = None


def ibl_answer(r: httpx.Response) -> IblAnswer:
    if r.status_code == 202:
        job = JobPublic.model_validate_json(r.content)
        return IblAnswer(job.id, None, job)
    return IblAnswer(r.headers["X-Relight-Job"], r.content)


@dataclass(frozen=True)
class IblExport:
    """An engine export from the service: ``data`` (the KTX2 chain or the SH JSON, byte-identical to ``relight
    export``'s), ``manifest`` (``relight export``'s sidecar) and the job that computed it."""

    data: bytes
    manifest: dict[str, Any]
    job_id: str


def with_seconds(manifest: dict[str, Any], stages: dict[str, Any]) -> dict[str, Any]:
    """``relight export``'s sidecar from an ``ibl`` job's result: its ``manifest`` (stored without timings, so that
    a job computed again writes the same bytes) with the seconds of the run that computed it put back from the
    result's ``stage_seconds``, per stage (``seconds``) and per level (``levels[i].seconds``, stage ``level_NN``).
    An SH export has no levels and no seconds."""
    if "levels" not in manifest:
        return manifest
    levels = [{**row, "seconds": stages.get(f"level_{int(row['level']):02d}")} for row in manifest["levels"]]
    return {**manifest, "levels": levels,
            "seconds": {k: v for k, v in stages.items() if not str(k).startswith("level_")}}


def ibl_params(target: str, format: str, size: int, levels: int | None, epsilon: float,
               sun: str, pixel_format: str = "rgba16f", brdf: str | None = None) -> dict[str, Any]:
    params: dict[str, Any] = {"target": target, "format": format, "size": size, "epsilon": epsilon, "sun": sun,
                              "pixel_format": pixel_format}
    if levels is not None:
        params["levels"] = levels
    if brdf is not None:
        params["brdf"] = brdf
    return params


def job_body(envmap: str, brdf: Spec, epsilon: float | None, order: int | None, p_order: int | None,
              size: int | None, sun: str | None = None) -> dict[str, Any]:
    ref: Any = brdf.model_dump(mode="json", exclude_none=True) if isinstance(brdf, BaseModel) else brdf
    body: dict[str, Any] = {"envmap": envmap, "brdf": ref}
    for k, v in (("epsilon", epsilon), ("order", order), ("p_order", p_order), ("size", size), ("sun", sun)):
        if v is not None:
            body[k] = v
    return body


class Calls:
    """The API, one request description per operation (shared by both clients)."""

    @staticmethod
    def health() -> Call[Health]:
        return Call("GET", "/health", model_parser(Health))

    @staticmethod
    def list_envmaps(limit: int) -> Call[list[EnvmapPublic]]:
        return Call("GET", "/envmaps", lambda r: EnvmapList.model_validate_json(r.content).items,
                     {"params": {"limit": limit}})

    @staticmethod
    def get_envmap(envmap_id: str) -> Call[EnvmapPublic]:
        return Call("GET", f"/envmaps/{envmap_id}", model_parser(EnvmapPublic))

    @staticmethod
    def envmap_preview(envmap_id: str) -> Call[bytes]:
        return Call("GET", f"/envmaps/{envmap_id}/preview.png", raw_bytes)

    @staticmethod
    def upload_envmap(content: Any, name: str | None) -> Call[EnvmapPublic]:
        params = {"name": name} if name else {}
        return Call("POST", "/envmaps", model_parser(EnvmapPublic),
                     {"content": content, "params": params, "headers": {"Content-Type": "application/octet-stream"}})

    @staticmethod
    def create_brdf(spec: Spec) -> Call[BrdfPublic]:
        if isinstance(spec, str):
            raise TypeError("create_brdf takes a spec object (dict or model); pass strings to submit/plan directly")
        body = spec.model_dump(mode="json", exclude_none=True) if isinstance(spec, BaseModel) else spec
        return Call("POST", "/brdfs", model_parser(BrdfPublic), {"json": body})

    @staticmethod
    def upload_measured_brdf(content: Any) -> Call[BrdfPublic]:
        return Call("POST", "/brdfs/measured", model_parser(BrdfPublic),
                     {"content": content, "headers": {"Content-Type": "application/octet-stream"}})

    @staticmethod
    def get_brdf(brdf_id: str) -> Call[BrdfPublic]:
        return Call("GET", f"/brdfs/{brdf_id}", model_parser(BrdfPublic))

    @staticmethod
    def plan(body: dict[str, Any]) -> Call[PlanPublic]:
        return Call("POST", "/plan", model_parser(PlanPublic), {"json": body})

    @staticmethod
    def submit(body: dict[str, Any]) -> Call[JobPublic]:
        return Call("POST", "/shrms", model_parser(JobPublic), {"json": body})

    @staticmethod
    def submit_job(kind: str, request: dict[str, Any] | BaseModel) -> Call[JobPublic]:
        body = request.model_dump(mode="json", exclude_none=True) if isinstance(request, BaseModel) else request
        return Call("POST", "/jobs", model_parser(JobPublic), {"json": {"kind": kind, "request": body}})

    @staticmethod
    def job_result(job_id: str) -> Call[dict[str, Any]]:
        return Call("GET", f"/jobs/{job_id}/result", lambda r: dict(r.json()))

    @staticmethod
    def job_file(job_id: str, name: str) -> Call[bytes]:
        return Call("GET", f"/jobs/{job_id}/files/{name}", raw_bytes)

    @staticmethod
    def get_job(job_id: str) -> Call[JobPublic]:
        return Call("GET", f"/jobs/{job_id}", model_parser(JobPublic))

    @staticmethod
    def list_jobs(state: str | None, limit: int) -> Call[list[JobPublic]]:
        params: dict[str, Any] = {"limit": limit}
        if state:
            params["state"] = state
        return Call("GET", "/jobs", lambda r: JobList.model_validate_json(r.content).items, {"params": params})

    @staticmethod
    def cancel_job(job_id: str) -> Call[JobPublic]:
        return Call("DELETE", f"/jobs/{job_id}", model_parser(JobPublic))

    @staticmethod
    def ibl(envmap_id: str, params: dict[str, Any]) -> Call[IblAnswer]:
        return Call("GET", f"/envmaps/{envmap_id}/ibl", ibl_answer, {"params": params})

    @staticmethod
    def get_shrm(shrm_id: str) -> Call[ShrmManifest]:
        return Call("GET", f"/shrms/{shrm_id}", model_parser(ShrmManifest))

    @staticmethod
    def download(shrm_id: str, name: str) -> Call[bytes]:
        if name not in ("coefficients.exr", "coefficients.bin"):
            raise ValueError(f"unknown result file {name!r}: expected coefficients.exr or coefficients.bin")
        return Call("GET", f"/shrms/{shrm_id}/{name}", raw_bytes)

    @staticmethod
    def reflection(shrm_id: str, view: tuple[float, float, float] | str) -> Call[bytes]:
        v = view if isinstance(view, str) else ",".join(f"{c:.17g}" for c in view)
        return Call("GET", f"/shrms/{shrm_id}/reflection.exr", raw_bytes, {"params": {"view": v}})

    @staticmethod
    def gaussian_render(fit: str, chain: str, view: tuple[float, float, float] | str, size: int,
                        visibility: str | None, mode: str, fmt: str) -> Call[bytes]:
        """``GET /gaussian/render.{fmt}``: a gaussian_fit job lit by a gaussian_chain job (seed 002)."""
        if fmt not in ("png", "exr"):
            raise ValueError(f"unknown image format {fmt!r}: expected png or exr")
        v = view if isinstance(view, str) else ",".join(f"{c:.17g}" for c in view)
        params: dict[str, Any] = {"fit": fit, "chain": chain, "view": v, "size": size, "mode": mode}
        if visibility is not None:
            params["visibility"] = visibility
        return Call("GET", f"/gaussian/render.{fmt}", raw_bytes, {"params": params})

    @staticmethod
    def create_tradeoff(body: dict[str, Any]) -> Call[TradeoffPublic]:
        return Call("POST", "/tradeoffs", model_parser(TradeoffPublic), {"json": body})

    @staticmethod
    def get_tradeoff(tradeoff_id: str) -> Call[TradeoffPublic]:
        return Call("GET", f"/tradeoffs/{tradeoff_id}", model_parser(TradeoffPublic))

    @staticmethod
    def create_scene(body: dict[str, Any]) -> Call[ScenePublic]:
        return Call("POST", "/scenes", model_parser(ScenePublic), {"json": body})

    @staticmethod
    def get_scene(scene_id: str) -> Call[ScenePublic]:
        return Call("GET", f"/scenes/{scene_id}", model_parser(ScenePublic))


def tradeoff_body(envmap: str, brdf: Spec, rows: int | None, size: int | None, epsilons: list[float] | None,
                   truncations: list[float] | None, view: tuple[float, float, float] | None) -> dict[str, Any]:
    ref: Any = brdf.model_dump(mode="json", exclude_none=True) if isinstance(brdf, BaseModel) else brdf
    body: dict[str, Any] = {"envmap": envmap, "brdf": ref}
    for k, v in (("rows", rows), ("size", size), ("epsilons", epsilons), ("truncations", truncations),
                 ("view", list(view) if view is not None else None)):
        if v is not None:
            body[k] = v
    return body


def scene_body(scene: dict[str, Any] | BaseModel) -> dict[str, Any]:
    if isinstance(scene, BaseModel):
        return scene.model_dump(mode="json", exclude_none=True)
    return SceneCreate.model_validate(scene).model_dump(mode="json", exclude_none=True)


A = TypeVar("A", TradeoffPublic, ScenePublic)


def check_analysis(pub: A) -> A:
    """A finished sweep or scene: itself, or :class:`JobFailed` when it failed or was cancelled."""
    if pub.state in (JobState.failed, JobState.cancelled):
        raise JobFailed(pub)
    return pub


def headers_for(api_key: str | None) -> dict[str, str]:
    return {"Authorization": f"Bearer {api_key}"} if api_key else {}


def check_final(job: JobPublic) -> JobPublic:
    if job.state in (JobState.failed, JobState.cancelled):
        raise JobFailed(job)
    return job
