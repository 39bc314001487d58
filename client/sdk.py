"""``RelightClient`` (sync) and ``AsyncRelightClient`` over httpx.

Both build their requests from the same :class:`_Call` descriptions and parse answers into the shared models
(:mod:`relight.contract.models`); they differ only in how a call is sent. Every failure is a
:class:`relight.client.errors.RelightError`.
"""

from __future__ import annotations

import os
import time
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import httpx
from httpx_sse import aconnect_sse, connect_sse
from pydantic import BaseModel

from relight.client.errors import JobFailed, TransportError, from_httpx, from_response
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
_CHUNK = 1 << 20
DEFAULT_URL = "http://127.0.0.1:8000"


def _model(cls: type[BaseModel]) -> Callable[[httpx.Response], Any]:
    return lambda r: cls.model_validate_json(r.content)


def _bytes(r: httpx.Response) -> bytes:
    return r.content


@dataclass
class _Call(Generic[T]):
    method: str
    path: str
    parse: Callable[[httpx.Response], T]
    kwargs: dict[str, Any] = field(default_factory=dict)


def _job_body(envmap: str, brdf: Spec, epsilon: float | None, order: int | None, p_order: int | None,
              size: int | None) -> dict[str, Any]:
    ref: Any = brdf.model_dump(mode="json", exclude_none=True) if isinstance(brdf, BaseModel) else brdf
    body: dict[str, Any] = {"envmap": envmap, "brdf": ref}
    for k, v in (("epsilon", epsilon), ("order", order), ("p_order", p_order), ("size", size)):
        if v is not None:
            body[k] = v
    return body


class _Calls:
    """The API, one request description per operation (shared by both clients)."""

    @staticmethod
    def health() -> _Call[Health]:
        return _Call("GET", "/health", _model(Health))

    @staticmethod
    def list_envmaps(limit: int) -> _Call[list[EnvmapPublic]]:
        return _Call("GET", "/envmaps", lambda r: EnvmapList.model_validate_json(r.content).items,
                     {"params": {"limit": limit}})

    @staticmethod
    def get_envmap(envmap_id: str) -> _Call[EnvmapPublic]:
        return _Call("GET", f"/envmaps/{envmap_id}", _model(EnvmapPublic))

    @staticmethod
    def envmap_preview(envmap_id: str) -> _Call[bytes]:
        return _Call("GET", f"/envmaps/{envmap_id}/preview.png", _bytes)

    @staticmethod
    def upload_envmap(content: Any, name: str | None) -> _Call[EnvmapPublic]:
        params = {"name": name} if name else {}
        return _Call("POST", "/envmaps", _model(EnvmapPublic),
                     {"content": content, "params": params, "headers": {"Content-Type": "application/octet-stream"}})

    @staticmethod
    def create_brdf(spec: Spec) -> _Call[BrdfPublic]:
        if isinstance(spec, str):
            raise TypeError("create_brdf takes a spec object (dict or model); pass strings to submit/plan directly")
        body = spec.model_dump(mode="json", exclude_none=True) if isinstance(spec, BaseModel) else spec
        return _Call("POST", "/brdfs", _model(BrdfPublic), {"json": body})

    @staticmethod
    def upload_measured_brdf(content: Any) -> _Call[BrdfPublic]:
        return _Call("POST", "/brdfs/measured", _model(BrdfPublic),
                     {"content": content, "headers": {"Content-Type": "application/octet-stream"}})

    @staticmethod
    def get_brdf(brdf_id: str) -> _Call[BrdfPublic]:
        return _Call("GET", f"/brdfs/{brdf_id}", _model(BrdfPublic))

    @staticmethod
    def plan(body: dict[str, Any]) -> _Call[PlanPublic]:
        return _Call("POST", "/plan", _model(PlanPublic), {"json": body})

    @staticmethod
    def submit(body: dict[str, Any]) -> _Call[JobPublic]:
        return _Call("POST", "/shrms", _model(JobPublic), {"json": body})

    @staticmethod
    def submit_job(kind: str, request: dict[str, Any] | BaseModel) -> _Call[JobPublic]:
        body = request.model_dump(mode="json", exclude_none=True) if isinstance(request, BaseModel) else request
        return _Call("POST", "/jobs", _model(JobPublic), {"json": {"kind": kind, "request": body}})

    @staticmethod
    def job_result(job_id: str) -> _Call[dict[str, Any]]:
        return _Call("GET", f"/jobs/{job_id}/result", lambda r: dict(r.json()))

    @staticmethod
    def job_file(job_id: str, name: str) -> _Call[bytes]:
        return _Call("GET", f"/jobs/{job_id}/files/{name}", _bytes)

    @staticmethod
    def get_job(job_id: str) -> _Call[JobPublic]:
        return _Call("GET", f"/jobs/{job_id}", _model(JobPublic))

    @staticmethod
    def list_jobs(state: str | None, limit: int) -> _Call[list[JobPublic]]:
        params: dict[str, Any] = {"limit": limit}
        if state:
            params["state"] = state
        return _Call("GET", "/jobs", lambda r: JobList.model_validate_json(r.content).items, {"params": params})

    @staticmethod
    def cancel_job(job_id: str) -> _Call[JobPublic]:
        return _Call("DELETE", f"/jobs/{job_id}", _model(JobPublic))

    @staticmethod
    def get_shrm(shrm_id: str) -> _Call[ShrmManifest]:
        return _Call("GET", f"/shrms/{shrm_id}", _model(ShrmManifest))

    @staticmethod
    def download(shrm_id: str, name: str) -> _Call[bytes]:
        if name not in ("coefficients.exr", "coefficients.bin"):
            raise ValueError(f"unknown result file {name!r}: expected coefficients.exr or coefficients.bin")
        return _Call("GET", f"/shrms/{shrm_id}/{name}", _bytes)

    @staticmethod
    def reflection(shrm_id: str, view: tuple[float, float, float] | str) -> _Call[bytes]:
        v = view if isinstance(view, str) else ",".join(f"{c:.17g}" for c in view)
        return _Call("GET", f"/shrms/{shrm_id}/reflection.exr", _bytes, {"params": {"view": v}})

    @staticmethod
    def create_tradeoff(body: dict[str, Any]) -> _Call[TradeoffPublic]:
        return _Call("POST", "/tradeoffs", _model(TradeoffPublic), {"json": body})

    @staticmethod
    def get_tradeoff(tradeoff_id: str) -> _Call[TradeoffPublic]:
        return _Call("GET", f"/tradeoffs/{tradeoff_id}", _model(TradeoffPublic))

    @staticmethod
    def create_scene(body: dict[str, Any]) -> _Call[ScenePublic]:
        return _Call("POST", "/scenes", _model(ScenePublic), {"json": body})

    @staticmethod
    def get_scene(scene_id: str) -> _Call[ScenePublic]:
        return _Call("GET", f"/scenes/{scene_id}", _model(ScenePublic))


def _tradeoff_body(envmap: str, brdf: Spec, rows: int | None, size: int | None, epsilons: list[float] | None,
                   truncations: list[float] | None, view: tuple[float, float, float] | None) -> dict[str, Any]:
    ref: Any = brdf.model_dump(mode="json", exclude_none=True) if isinstance(brdf, BaseModel) else brdf
    body: dict[str, Any] = {"envmap": envmap, "brdf": ref}
    for k, v in (("rows", rows), ("size", size), ("epsilons", epsilons), ("truncations", truncations),
                 ("view", list(view) if view is not None else None)):
        if v is not None:
            body[k] = v
    return body


def _scene_body(scene: dict[str, Any] | BaseModel) -> dict[str, Any]:
    if isinstance(scene, BaseModel):
        return scene.model_dump(mode="json", exclude_none=True)
    return SceneCreate.model_validate(scene).model_dump(mode="json", exclude_none=True)


A = TypeVar("A", TradeoffPublic, ScenePublic)


def _check_analysis(pub: A) -> A:
    """A finished sweep or scene: itself, or :class:`JobFailed` when it failed or was cancelled."""
    if pub.state in (JobState.failed, JobState.cancelled):
        raise JobFailed(pub)
    return pub


def _headers(api_key: str | None) -> dict[str, str]:
    return {"Authorization": f"Bearer {api_key}"} if api_key else {}


def _check_final(job: JobPublic) -> JobPublic:
    if job.state in (JobState.failed, JobState.cancelled):
        raise JobFailed(job)
    return job


class RelightClient:
    """Synchronous client. ``with RelightClient(url) as c: job = c.submit(...); c.wait(job.id)``."""

    def __init__(self, base_url: str = DEFAULT_URL, *, api_key: str | None = None, timeout: float = 60.0,
                 transport: httpx.BaseTransport | None = None) -> None:
        self.base_url = base_url.rstrip("/")
        self._http = httpx.Client(base_url=self.base_url, headers=_headers(api_key), timeout=timeout,
                                  transport=transport)

    def __enter__(self) -> RelightClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._http.close()

    def _do(self, call: _Call[T]) -> T:
        try:
            resp = self._http.request(call.method, call.path, **call.kwargs)
        except httpx.HTTPError as exc:
            raise from_httpx(exc) from exc
        if resp.status_code >= 400:
            raise from_response(resp)
        return call.parse(resp)

    # -- operations -------------------------------------------------------------------------------------------
    def health(self) -> Health:
        return self._do(_Calls.health())

    def upload_envmap(self, source: Source, *, name: str | None = None) -> EnvmapPublic:
        """Upload a file (streamed from disk) or bytes; returns the map's metadata."""
        if isinstance(source, bytes):
            return self._do(_Calls.upload_envmap(source, name))
        path = Path(source)
        with open(path, "rb") as fh:
            return self._do(_Calls.upload_envmap(iter(lambda: fh.read(_CHUNK), b""), name or path.name))

    def list_envmaps(self, limit: int = 100) -> list[EnvmapPublic]:
        return self._do(_Calls.list_envmaps(limit))

    def get_envmap(self, envmap_id: str) -> EnvmapPublic:
        return self._do(_Calls.get_envmap(envmap_id))

    def envmap_preview(self, envmap_id: str) -> bytes:
        return self._do(_Calls.envmap_preview(envmap_id))

    def create_brdf(self, spec: dict[str, Any] | BaseModel) -> BrdfPublic:
        return self._do(_Calls.create_brdf(spec))

    def upload_measured_brdf(self, source: Source) -> BrdfPublic:
        data = source if isinstance(source, bytes) else Path(source).read_bytes()
        return self._do(_Calls.upload_measured_brdf(data))

    def get_brdf(self, brdf_id: str) -> BrdfPublic:
        return self._do(_Calls.get_brdf(brdf_id))

    def plan(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
             p_order: int | None = None, size: int | None = None) -> PlanPublic:
        return self._do(_Calls.plan(_job_body(envmap, brdf, epsilon, order, p_order, size)))

    def submit(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
               p_order: int | None = None, size: int | None = None) -> JobPublic:
        """Start (or join) a job; ``job.cached`` is True when the result existed already."""
        return self._do(_Calls.submit(_job_body(envmap, brdf, epsilon, order, p_order, size)))

    def submit_job(self, kind: str, request: dict[str, Any] | BaseModel) -> JobPublic:
        """Start (or join) a job of any kind (``POST /jobs``); ``request`` as the kind's own route takes it."""
        return self._do(_Calls.submit_job(kind, request))

    def job_result(self, job_id: str) -> dict[str, Any]:
        """A succeeded job's JSON result (``GET /jobs/{id}/result``)."""
        return self._do(_Calls.job_result(job_id))

    def job_file(self, job_id: str, name: str) -> bytes:
        """A file a succeeded job's result lists under ``files``."""
        return self._do(_Calls.job_file(job_id, name))

    def get_job(self, job_id: str) -> JobPublic:
        return self._do(_Calls.get_job(job_id))

    def list_jobs(self, state: str | None = None, limit: int = 100) -> list[JobPublic]:
        return self._do(_Calls.list_jobs(state, limit))

    def cancel_job(self, job_id: str) -> JobPublic:
        return self._do(_Calls.cancel_job(job_id))

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
                    return _check_final(job)
        except TransportError:
            pass
        while True:
            job = self.get_job(job_id)
            if on_update and (last is None or job != last):
                on_update(job)
            last = job
            if job.state.terminal:
                return _check_final(job)
            if deadline is not None and time.monotonic() > deadline:
                raise TransportError(f"job {job_id} still {job.state} after {timeout} s")
            time.sleep(poll_interval)

    def get_shrm(self, shrm_id: str) -> ShrmManifest:
        return self._do(_Calls.get_shrm(shrm_id))

    def download(self, shrm_id: str, name: str = "coefficients.exr") -> bytes:
        return self._do(_Calls.download(shrm_id, name))

    def reflection(self, shrm_id: str, view: tuple[float, float, float] | str) -> bytes:
        return self._do(_Calls.reflection(shrm_id, view))

    def create_tradeoff(self, envmap: str, brdf: Spec, *, rows: int | None = None, size: int | None = None,
                        epsilons: list[float] | None = None, truncations: list[float] | None = None,
                        view: tuple[float, float, float] | None = None) -> TradeoffPublic:
        """``POST /tradeoffs``: start (or join) an accuracy–time sweep; finished already when it existed."""
        return self._do(_Calls.create_tradeoff(_tradeoff_body(envmap, brdf, rows, size, epsilons, truncations, view)))

    def get_tradeoff(self, tradeoff_id: str) -> TradeoffPublic:
        return self._do(_Calls.get_tradeoff(tradeoff_id))

    def wait_tradeoff(self, tradeoff_id: str, *, timeout: float | None = None,
                      poll_interval: float = 0.5) -> TradeoffPublic:
        """Follow the sweep's job until it ends; raise :class:`JobFailed` if it failed or was cancelled."""
        self.wait(tradeoff_id, timeout=timeout, poll_interval=poll_interval)
        return _check_analysis(self.get_tradeoff(tradeoff_id))

    def wait_scene(self, scene_id: str, *, timeout: float | None = None, poll_interval: float = 0.5) -> ScenePublic:
        """Follow the scene's job until it ends; raise :class:`JobFailed` if it failed or was cancelled."""
        self.wait(scene_id, timeout=timeout, poll_interval=poll_interval)
        return _check_analysis(self.get_scene(scene_id))

    def create_scene(self, scene: dict[str, Any] | SceneCreate) -> ScenePublic:
        """``POST /scenes``: store the scene and run its plan (validated locally as ``SceneCreate`` first)."""
        return self._do(_Calls.create_scene(_scene_body(scene)))

    def get_scene(self, scene_id: str) -> ScenePublic:
        return self._do(_Calls.get_scene(scene_id))


class AsyncRelightClient:
    """Asynchronous client with the same operations as :class:`RelightClient`."""

    def __init__(self, base_url: str = DEFAULT_URL, *, api_key: str | None = None, timeout: float = 60.0,
                 transport: httpx.AsyncBaseTransport | None = None, limits: httpx.Limits | None = None) -> None:
        self.base_url = base_url.rstrip("/")
        self._http = httpx.AsyncClient(base_url=self.base_url, headers=_headers(api_key), timeout=timeout,
                                       transport=transport, limits=limits or httpx.Limits())

    async def __aenter__(self) -> AsyncRelightClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        await self._http.aclose()

    async def _do(self, call: _Call[T]) -> T:
        try:
            resp = await self._http.request(call.method, call.path, **call.kwargs)
        except httpx.HTTPError as exc:
            raise from_httpx(exc) from exc
        if resp.status_code >= 400:
            raise from_response(resp)
        return call.parse(resp)

    async def health(self) -> Health:
        return await self._do(_Calls.health())

    async def upload_envmap(self, source: Source, *, name: str | None = None) -> EnvmapPublic:
        if isinstance(source, bytes):
            return await self._do(_Calls.upload_envmap(source, name))
        path = Path(source)

        async def chunks() -> AsyncIterator[bytes]:
            import anyio

            async with await anyio.open_file(path, "rb") as fh:
                while chunk := await fh.read(_CHUNK):
                    yield chunk

        return await self._do(_Calls.upload_envmap(chunks(), name or path.name))

    async def list_envmaps(self, limit: int = 100) -> list[EnvmapPublic]:
        return await self._do(_Calls.list_envmaps(limit))

    async def get_envmap(self, envmap_id: str) -> EnvmapPublic:
        return await self._do(_Calls.get_envmap(envmap_id))

    async def envmap_preview(self, envmap_id: str) -> bytes:
        return await self._do(_Calls.envmap_preview(envmap_id))

    async def create_brdf(self, spec: dict[str, Any] | BaseModel) -> BrdfPublic:
        return await self._do(_Calls.create_brdf(spec))

    async def upload_measured_brdf(self, source: Source) -> BrdfPublic:
        data = source if isinstance(source, bytes) else Path(source).read_bytes()
        return await self._do(_Calls.upload_measured_brdf(data))

    async def get_brdf(self, brdf_id: str) -> BrdfPublic:
        return await self._do(_Calls.get_brdf(brdf_id))

    async def plan(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
                   p_order: int | None = None, size: int | None = None) -> PlanPublic:
        return await self._do(_Calls.plan(_job_body(envmap, brdf, epsilon, order, p_order, size)))

    async def submit(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
                     p_order: int | None = None, size: int | None = None) -> JobPublic:
        return await self._do(_Calls.submit(_job_body(envmap, brdf, epsilon, order, p_order, size)))

    async def submit_job(self, kind: str, request: dict[str, Any] | BaseModel) -> JobPublic:
        return await self._do(_Calls.submit_job(kind, request))

    async def job_result(self, job_id: str) -> dict[str, Any]:
        return await self._do(_Calls.job_result(job_id))

    async def job_file(self, job_id: str, name: str) -> bytes:
        return await self._do(_Calls.job_file(job_id, name))

    async def get_job(self, job_id: str) -> JobPublic:
        return await self._do(_Calls.get_job(job_id))

    async def list_jobs(self, state: str | None = None, limit: int = 100) -> list[JobPublic]:
        return await self._do(_Calls.list_jobs(state, limit))

    async def cancel_job(self, job_id: str) -> JobPublic:
        return await self._do(_Calls.cancel_job(job_id))

    async def events(self, job_id: str, *, timeout: float | None = None) -> AsyncIterator[JobPublic]:
        try:
            async with aconnect_sse(self._http, "GET", f"/jobs/{job_id}/events",
                                    timeout=httpx.Timeout(timeout, connect=10.0)) as source:
                if source.response.status_code >= 400:
                    await source.response.aread()
                    raise from_response(source.response)
                async for sse in source.aiter_sse():
                    if sse.event not in ("job", "end"):
                        continue
                    yield JobPublic.model_validate_json(sse.data)
                    if sse.event == "end":
                        return
        except httpx.HTTPError as exc:  # SSEError (not an event stream) is one
            raise from_httpx(exc) from exc

    async def wait(self, job_id: str, *, timeout: float | None = None,
                   on_update: Callable[[JobPublic], None] | None = None, poll_interval: float = 0.5) -> JobPublic:
        import anyio

        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            async for job in self.events(job_id, timeout=timeout):
                if on_update:
                    on_update(job)
                if job.state.terminal:
                    return _check_final(job)
        except TransportError:
            pass
        while True:
            job = await self.get_job(job_id)
            if on_update:
                on_update(job)
            if job.state.terminal:
                return _check_final(job)
            if deadline is not None and time.monotonic() > deadline:
                raise TransportError(f"job {job_id} still {job.state} after {timeout} s")
            await anyio.sleep(poll_interval)

    async def get_shrm(self, shrm_id: str) -> ShrmManifest:
        return await self._do(_Calls.get_shrm(shrm_id))

    async def download(self, shrm_id: str, name: str = "coefficients.exr") -> bytes:
        return await self._do(_Calls.download(shrm_id, name))

    async def reflection(self, shrm_id: str, view: tuple[float, float, float] | str) -> bytes:
        return await self._do(_Calls.reflection(shrm_id, view))

    async def create_tradeoff(self, envmap: str, brdf: Spec, *, rows: int | None = None, size: int | None = None,
                              epsilons: list[float] | None = None, truncations: list[float] | None = None,
                              view: tuple[float, float, float] | None = None) -> TradeoffPublic:
        return await self._do(_Calls.create_tradeoff(
            _tradeoff_body(envmap, brdf, rows, size, epsilons, truncations, view)))

    async def get_tradeoff(self, tradeoff_id: str) -> TradeoffPublic:
        return await self._do(_Calls.get_tradeoff(tradeoff_id))

    async def wait_tradeoff(self, tradeoff_id: str, *, timeout: float | None = None,
                            poll_interval: float = 0.5) -> TradeoffPublic:
        await self.wait(tradeoff_id, timeout=timeout, poll_interval=poll_interval)
        return _check_analysis(await self.get_tradeoff(tradeoff_id))

    async def wait_scene(self, scene_id: str, *, timeout: float | None = None,
                         poll_interval: float = 0.5) -> ScenePublic:
        await self.wait(scene_id, timeout=timeout, poll_interval=poll_interval)
        return _check_analysis(await self.get_scene(scene_id))

    async def create_scene(self, scene: dict[str, Any] | SceneCreate) -> ScenePublic:
        return await self._do(_Calls.create_scene(_scene_body(scene)))

    async def get_scene(self, scene_id: str) -> ScenePublic:
        return await self._do(_Calls.get_scene(scene_id))
