"""``RelightClient``: the synchronous SDK client over httpx (its asynchronous twin is
:mod:`relight.client.async_sdk`).

Both clients build their requests from the same descriptions (:mod:`relight.client.calls`) and parse answers into
the shared models (:mod:`relight.contract.models`); they differ only in how a call is sent. Every failure is a
:class:`relight.client.errors.RelightError`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
from httpx_sse import connect_sse
from pydantic import BaseModel

from relight.client.calls import (
    CHUNK,
    DEFAULT_URL,
    RETRY_429_S,
    Call,
    Calls,
    IblExport,
    Source,
    Spec,
    T,
    check_analysis,
    check_final,
    headers_for,
    ibl_params,
    job_body,
    retry_wait,
    scene_body,
    tradeoff_body,
    with_seconds,
)
from relight.client.errors import TransportError, from_httpx, from_response
from relight.contract.models import (
    BrdfPublic,
    EnvmapPublic,
    Health,
    JobPublic,
    PlanPublic,
    SceneCreate,
    ScenePublic,
    ShrmManifest,
    TradeoffPublic,
)


class RelightClient:
    """Synchronous client. ``with RelightClient(url) as c: job = c.submit(...); c.wait(job.id)``."""

    def __init__(self, base_url: str = DEFAULT_URL, *, api_key: str | None = None, timeout: float = 60.0,
                 transport: httpx.BaseTransport | None = None, retry_429_s: float = RETRY_429_S) -> None:
        self.base_url = base_url.rstrip("/")
        self.retry_429_s = retry_429_s  # how long to follow Retry-After when the server's job cap is full
        self._http = httpx.Client(base_url=self.base_url, headers=headers_for(api_key), timeout=timeout,
                                  transport=transport)

    def __enter__(self) -> RelightClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._http.close()

    def _do(self, call: Call[T]) -> T:
        deadline = time.monotonic() + self.retry_429_s
        while True:
            try:
                resp = self._http.request(call.method, call.path, **call.kwargs)
            except httpx.HTTPError as exc:
                raise from_httpx(exc) from exc
            wait = retry_wait(resp, call, deadline, time.monotonic())
            if wait is None:
                break
            time.sleep(wait)
        if resp.status_code >= 400:
            raise from_response(resp)
        return call.parse(resp)

    # -- operations -------------------------------------------------------------------------------------------
    def health(self) -> Health:
        return self._do(Calls.health())

    def upload_envmap(self, source: Source, *, name: str | None = None) -> EnvmapPublic:
        """Upload a file (streamed from disk) or bytes; returns the map's metadata."""
        if isinstance(source, bytes):
            return self._do(Calls.upload_envmap(source, name))
        path = Path(source)
        with open(path, "rb") as fh:
            return self._do(Calls.upload_envmap(iter(lambda: fh.read(CHUNK), b""), name or path.name))

    def list_envmaps(self, limit: int = 100) -> list[EnvmapPublic]:
        return self._do(Calls.list_envmaps(limit))

    def get_envmap(self, envmap_id: str) -> EnvmapPublic:
        return self._do(Calls.get_envmap(envmap_id))

    def envmap_preview(self, envmap_id: str) -> bytes:
        return self._do(Calls.envmap_preview(envmap_id))

    def create_brdf(self, spec: dict[str, Any] | BaseModel) -> BrdfPublic:
        return self._do(Calls.create_brdf(spec))

    def upload_measured_brdf(self, source: Source) -> BrdfPublic:
        data = source if isinstance(source, bytes) else Path(source).read_bytes()
        return self._do(Calls.upload_measured_brdf(data))

    def get_brdf(self, brdf_id: str) -> BrdfPublic:
        return self._do(Calls.get_brdf(brdf_id))

    def plan(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
             p_order: int | None = None, size: int | None = None,
             sun: str | None = None) -> PlanPublic:
        """``POST /plan``; ``sun="extract"`` with a tolerance adds the order each lobe needs with and without the
        sun (``plan.sun``)."""
        return self._do(Calls.plan(job_body(envmap, brdf, epsilon, order, p_order, size, sun)))

    def submit(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
               p_order: int | None = None, size: int | None = None, sun: str | None = None) -> JobPublic:
        """Start (or join) a job; ``job.cached`` is True when the result existed already. ``sun``: extract,
        clamp=V or keep (``ShrmCreate.sun``)."""
        return self._do(Calls.submit(job_body(envmap, brdf, epsilon, order, p_order, size, sun)))

    def submit_job(self, kind: str, request: dict[str, Any] | BaseModel) -> JobPublic:
        """Start (or join) a job of any kind (``POST /jobs``); ``request`` as the kind's own route takes it."""
        return self._do(Calls.submit_job(kind, request))

    def job_result(self, job_id: str) -> dict[str, Any]:
        """A succeeded job's JSON result (``GET /jobs/{id}/result``)."""
        return self._do(Calls.job_result(job_id))

    def job_file(self, job_id: str, name: str) -> bytes:
        """A file a succeeded job's result lists under ``files``."""
        return self._do(Calls.job_file(job_id, name))

    def get_job(self, job_id: str) -> JobPublic:
        return self._do(Calls.get_job(job_id))

    def list_jobs(self, state: str | None = None, limit: int = 100) -> list[JobPublic]:
        return self._do(Calls.list_jobs(state, limit))

    def cancel_job(self, job_id: str) -> JobPublic:
        return self._do(Calls.cancel_job(job_id))

    def events(self, job_id: str, *, timeout: float | None = None) -> Iterator[JobPublic]:
        """Job updates from ``GET /jobs/{id}/events`` (any kind of job) until the job ends (the last one is final)."""
        try:
            with connect_sse(self._http, "GET", f"/jobs/{job_id}/events",
                             timeout=httpx.Timeout(timeout, connect=10.0)) as source:
                if source.response.status_code >= 400:
                    source.response.read()
                    raise from_response(source.response)
                for sse in source.iter_sse():
                    if sse.event not in ("job", "end"):
                        continue
                    yield JobPublic.model_validate_json(sse.data)
                    if sse.event == "end":
                        return
        except httpx.HTTPError as exc:  # SSEError (not an event stream) is one
            raise from_httpx(exc) from exc

    def wait(self, job_id: str, *, timeout: float | None = None,
             on_update: Callable[[JobPublic], None] | None = None, poll_interval: float = 0.5) -> JobPublic:
        """Block until the job ends; raise :class:`JobFailed` if it failed or was cancelled.

        Follows the event stream (``httpx-sse``), and falls back to polling if the stream breaks.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        last: JobPublic | None = None
        try:
            for job in self.events(job_id, timeout=timeout):
                last = job
                if on_update:
                    on_update(job)
                if job.state.terminal:
                    return check_final(job)
        except TransportError:
            pass
        while True:
            job = self.get_job(job_id)
            if on_update and (last is None or job != last):
                on_update(job)
            last = job
            if job.state.terminal:
                return check_final(job)
            if deadline is not None and time.monotonic() > deadline:
                raise TransportError(f"job {job_id} still {job.state} after {timeout} s")
            time.sleep(poll_interval)

    def ibl(self, envmap: str, *, target: str = "three", format: str = "ktx2", size: int = 256,
            levels: int | None = None, epsilon: float = 2.5e-5, sun: str = "keep", pixel_format: str = "rgba16f",
            timeout: float | None = None, brdf: str | None = None) -> IblExport:
        """An engine export of an uploaded map (``GET /envmaps/{id}/ibl``, computed as a job and cached): waits for
        the job, then returns the file and its manifest; ``brdf`` is ``relight export --brdf SPEC``."""
        call = Calls.ibl(envmap, ibl_params(target, format, size, levels, epsilon, sun, pixel_format, brdf))
        answer = self._do(call)
        while answer.data is None:
            self.wait(answer.job_id, timeout=timeout)
            answer = self._do(call)
        result = self.job_result(answer.job_id)
        return IblExport(answer.data, with_seconds(result["manifest"], result.get("stage_seconds") or {}),
                         answer.job_id)

    def get_shrm(self, shrm_id: str) -> ShrmManifest:
        return self._do(Calls.get_shrm(shrm_id))

    def download(self, shrm_id: str, name: str = "coefficients.exr") -> bytes:
        return self._do(Calls.download(shrm_id, name))

    def reflection(self, shrm_id: str, view: tuple[float, float, float] | str) -> bytes:
        return self._do(Calls.reflection(shrm_id, view))

    def gaussian_render(self, fit: str, chain: str, view: tuple[float, float, float] | str = "0,0,1", *,
                        size: int = 128, visibility: str | None = None, mode: str = "none",
                        fmt: str = "exr") -> bytes:
        """A ``gaussian_fit`` job's lobes lit by a ``gaussian_chain`` job (seed 002 §5): the sphere, or with a
        ``visibility`` job its mesh shadowed per ``mode`` (none, ao, sh, sh-lobe); EXR (linear) or PNG bytes."""
        return self._do(Calls.gaussian_render(fit, chain, view, size, visibility, mode, fmt))

    def create_tradeoff(self, envmap: str, brdf: Spec, *, rows: int | None = None, size: int | None = None,
                        epsilons: list[float] | None = None, truncations: list[float] | None = None,
                        view: tuple[float, float, float] | None = None) -> TradeoffPublic:
        """``POST /tradeoffs``: start (or join) an accuracy–time sweep; finished already when it existed."""
        return self._do(Calls.create_tradeoff(tradeoff_body(envmap, brdf, rows, size, epsilons, truncations, view)))

    def get_tradeoff(self, tradeoff_id: str) -> TradeoffPublic:
        return self._do(Calls.get_tradeoff(tradeoff_id))

    def wait_tradeoff(self, tradeoff_id: str, *, timeout: float | None = None,
                      poll_interval: float = 0.5) -> TradeoffPublic:
        """Follow the sweep's job until it ends; raise :class:`JobFailed` if it failed or was cancelled."""
        self.wait(tradeoff_id, timeout=timeout, poll_interval=poll_interval)
        return check_analysis(self.get_tradeoff(tradeoff_id))

    def wait_scene(self, scene_id: str, *, timeout: float | None = None, poll_interval: float = 0.5) -> ScenePublic:
        """Follow the scene's job until it ends; raise :class:`JobFailed` if it failed or was cancelled."""
        self.wait(scene_id, timeout=timeout, poll_interval=poll_interval)
        return check_analysis(self.get_scene(scene_id))

    def create_scene(self, scene: dict[str, Any] | SceneCreate) -> ScenePublic:
        """``POST /scenes``: store the scene and run its plan (validated locally as ``SceneCreate`` first)."""
        return self._do(Calls.create_scene(scene_body(scene)))

    def get_scene(self, scene_id: str) -> ScenePublic:
        return self._do(Calls.get_scene(scene_id))
