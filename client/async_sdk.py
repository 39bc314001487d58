"""``AsyncRelightClient``: the asynchronous twin of :class:`relight.client.sdk.RelightClient`, with the same
operations over the same request descriptions (:mod:`relight.client.calls`); only how a call is sent differs.
"""

from __future__ import annotations

import time
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import httpx
from httpx_sse import aconnect_sse
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


class AsyncRelightClient:
    """Asynchronous client with the same operations as :class:`RelightClient`."""

    def __init__(self, base_url: str = DEFAULT_URL, *, api_key: str | None = None, timeout: float = 60.0,
                 transport: httpx.AsyncBaseTransport | None = None, limits: httpx.Limits | None = None,
                 retry_429_s: float = RETRY_429_S) -> None:
        self.base_url = base_url.rstrip("/")
        self.retry_429_s = retry_429_s
        self._http = httpx.AsyncClient(base_url=self.base_url, headers=headers_for(api_key), timeout=timeout,
                                       transport=transport, limits=limits or httpx.Limits())

    async def __aenter__(self) -> AsyncRelightClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        await self._http.aclose()

    async def _do(self, call: Call[T]) -> T:
        import asyncio

        deadline = time.monotonic() + self.retry_429_s
        while True:
            try:
                resp = await self._http.request(call.method, call.path, **call.kwargs)
            except httpx.HTTPError as exc:
                raise from_httpx(exc) from exc
            wait = retry_wait(resp, call, deadline, time.monotonic())
            if wait is None:
                break
            await asyncio.sleep(wait)
        if resp.status_code >= 400:
            raise from_response(resp)
        return call.parse(resp)

    async def health(self) -> Health:
        return await self._do(Calls.health())

    async def upload_envmap(self, source: Source, *, name: str | None = None) -> EnvmapPublic:
        if isinstance(source, bytes):
            return await self._do(Calls.upload_envmap(source, name))
        path = Path(source)

        async def chunks() -> AsyncIterator[bytes]:
            import anyio

            async with await anyio.open_file(path, "rb") as fh:
                while chunk := await fh.read(CHUNK):
                    yield chunk

        return await self._do(Calls.upload_envmap(chunks(), name or path.name))

    async def list_envmaps(self, limit: int = 100) -> list[EnvmapPublic]:
        return await self._do(Calls.list_envmaps(limit))

    async def get_envmap(self, envmap_id: str) -> EnvmapPublic:
        return await self._do(Calls.get_envmap(envmap_id))

    async def envmap_preview(self, envmap_id: str) -> bytes:
        return await self._do(Calls.envmap_preview(envmap_id))

    async def create_brdf(self, spec: dict[str, Any] | BaseModel) -> BrdfPublic:
        return await self._do(Calls.create_brdf(spec))

    async def upload_measured_brdf(self, source: Source) -> BrdfPublic:
        data = source if isinstance(source, bytes) else Path(source).read_bytes()
        return await self._do(Calls.upload_measured_brdf(data))

    async def get_brdf(self, brdf_id: str) -> BrdfPublic:
        return await self._do(Calls.get_brdf(brdf_id))

    async def plan(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
                   p_order: int | None = None, size: int | None = None,
                   sun: str | None = None) -> PlanPublic:
        return await self._do(Calls.plan(job_body(envmap, brdf, epsilon, order, p_order, size, sun)))

    async def submit(self, envmap: str, brdf: Spec, *, epsilon: float | None = None, order: int | None = None,
                     p_order: int | None = None, size: int | None = None, sun: str | None = None) -> JobPublic:
        return await self._do(Calls.submit(job_body(envmap, brdf, epsilon, order, p_order, size, sun)))

    async def submit_job(self, kind: str, request: dict[str, Any] | BaseModel) -> JobPublic:
        return await self._do(Calls.submit_job(kind, request))

    async def job_result(self, job_id: str) -> dict[str, Any]:
        return await self._do(Calls.job_result(job_id))

    async def job_file(self, job_id: str, name: str) -> bytes:
        return await self._do(Calls.job_file(job_id, name))

    async def get_job(self, job_id: str) -> JobPublic:
        return await self._do(Calls.get_job(job_id))

    async def list_jobs(self, state: str | None = None, limit: int = 100) -> list[JobPublic]:
        return await self._do(Calls.list_jobs(state, limit))

    async def cancel_job(self, job_id: str) -> JobPublic:
        return await self._do(Calls.cancel_job(job_id))

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
                    return check_final(job)
        except TransportError:
            pass
        while True:
            job = await self.get_job(job_id)
            if on_update:
                on_update(job)
            if job.state.terminal:
                return check_final(job)
            if deadline is not None and time.monotonic() > deadline:
                raise TransportError(f"job {job_id} still {job.state} after {timeout} s")
            await anyio.sleep(poll_interval)

    async def ibl(self, envmap: str, *, target: str = "three", format: str = "ktx2", size: int = 256,
                  levels: int | None = None, epsilon: float = 2.5e-5, sun: str = "keep",
                  pixel_format: str = "rgba16f", timeout: float | None = None,
                  brdf: str | None = None) -> IblExport:
        """:meth:`RelightClient.ibl`."""
        call = Calls.ibl(envmap, ibl_params(target, format, size, levels, epsilon, sun, pixel_format, brdf))
        answer = await self._do(call)
        while answer.data is None:
            await self.wait(answer.job_id, timeout=timeout)
            answer = await self._do(call)
        return IblExport(answer.data, (await self.job_result(answer.job_id))["manifest"], answer.job_id)

    async def get_shrm(self, shrm_id: str) -> ShrmManifest:
        return await self._do(Calls.get_shrm(shrm_id))

    async def download(self, shrm_id: str, name: str = "coefficients.exr") -> bytes:
        return await self._do(Calls.download(shrm_id, name))

    async def reflection(self, shrm_id: str, view: tuple[float, float, float] | str) -> bytes:
        return await self._do(Calls.reflection(shrm_id, view))

    async def gaussian_render(self, fit: str, chain: str, view: tuple[float, float, float] | str = "0,0,1", *,
                              size: int = 128, visibility: str | None = None, mode: str = "none",
                              fmt: str = "exr") -> bytes:
        """The async twin of :meth:`RelightClient.gaussian_render`."""
        return await self._do(Calls.gaussian_render(fit, chain, view, size, visibility, mode, fmt))

    async def create_tradeoff(self, envmap: str, brdf: Spec, *, rows: int | None = None, size: int | None = None,
                              epsilons: list[float] | None = None, truncations: list[float] | None = None,
                              view: tuple[float, float, float] | None = None) -> TradeoffPublic:
        return await self._do(Calls.create_tradeoff(
            tradeoff_body(envmap, brdf, rows, size, epsilons, truncations, view)))

    async def get_tradeoff(self, tradeoff_id: str) -> TradeoffPublic:
        return await self._do(Calls.get_tradeoff(tradeoff_id))

    async def wait_tradeoff(self, tradeoff_id: str, *, timeout: float | None = None,
                            poll_interval: float = 0.5) -> TradeoffPublic:
        await self.wait(tradeoff_id, timeout=timeout, poll_interval=poll_interval)
        return check_analysis(await self.get_tradeoff(tradeoff_id))

    async def wait_scene(self, scene_id: str, *, timeout: float | None = None,
                         poll_interval: float = 0.5) -> ScenePublic:
        await self.wait(scene_id, timeout=timeout, poll_interval=poll_interval)
        return check_analysis(await self.get_scene(scene_id))

    async def create_scene(self, scene: dict[str, Any] | SceneCreate) -> ScenePublic:
        return await self._do(Calls.create_scene(scene_body(scene)))

    async def get_scene(self, scene_id: str) -> ScenePublic:
        return await self._do(Calls.get_scene(scene_id))
