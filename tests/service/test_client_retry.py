"""The SDK follows ``Retry-After`` when the server's active-job cap is full (429), by itself (issue 12, item 6):
against a mock transport (what is retried, for how long) and against a real server with a cap of 2, where 8
concurrent submissions all end in a succeeded job and no 5xx."""

from __future__ import annotations

import asyncio
import re
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from relight.client.async_sdk import AsyncRelightClient
from relight.client.calls import RETRY_JITTER
from relight.client.errors import ApiError
from relight.client.sdk import RelightClient
from relight.contract.models import JobState

from .postgres import Backend
from .support import exr_bytes, make_envmap, start_server

JOB = {"id": "a" * 64, "kind": "shrm", "state": "queued", "stage": "queued", "progress": 0.0, "runs": 0,
       "submissions": 0, "cached": False, "created_at": "2026-01-01T00:00:00Z", "links": {}}
PROBLEM = {"type": "about:blank", "title": "Too Many Requests", "status": 429, "detail": "4 jobs (limit 4)"}


def transport(refusals: int, seen: list[float], retry_after: str = "0.05") -> httpx.MockTransport:
    def handle(request: httpx.Request) -> httpx.Response:
        seen.append(time.monotonic())
        if len(seen) <= refusals:
            return httpx.Response(429, json=PROBLEM, headers={"Retry-After": retry_after,
                                                              "content-type": "application/problem+json"})
        return httpx.Response(202, json=JOB)

    return httpx.MockTransport(handle)


def test_submissions_follow_retry_after() -> None:
    seen: list[float] = []
    with RelightClient("http://relight.test", transport=transport(3, seen)) as c:
        assert c.submit("b" * 64, "phong:s=8", epsilon=0.1).id == JOB["id"]
    assert len(seen) == 4
    gaps = [b - a for a, b in zip(seen, seen[1:], strict=False)]
    assert all(0.05 <= g < 0.05 * (1 + RETRY_JITTER) + 0.5 for g in gaps), gaps  # waited as told, with jitter


def test_async_submissions_follow_retry_after() -> None:
    seen: list[float] = []

    async def go() -> str:
        async with AsyncRelightClient("http://relight.test", transport=transport(2, seen)) as c:  # type: ignore[arg-type]
            return (await c.submit("b" * 64, "phong:s=8", epsilon=0.1)).id

    assert asyncio.run(go()) == JOB["id"] and len(seen) == 3


def test_retrying_stops_at_its_limit_and_for_streamed_uploads() -> None:
    seen: list[float] = []
    with RelightClient("http://relight.test", transport=transport(100, seen), retry_429_s=0.3) as c:
        with pytest.raises(ApiError) as info:
            c.submit("b" * 64, "phong:s=8", epsilon=0.1)
    assert info.value.status == 429 and 2 <= len(seen) <= 8
    seen.clear()
    with RelightClient("http://relight.test", transport=transport(100, seen, "0"), retry_429_s=0.0) as c:
        with pytest.raises(ApiError):
            c.submit("b" * 64, "phong:s=8", epsilon=0.1)
    assert len(seen) == 1  # retry_429_s=0: no retry
    seen.clear()
    with RelightClient("http://relight.test", transport=transport(100, seen, "0")) as c, pytest.raises(ApiError):
        c.upload_envmap(Path(__file__))  # a streamed body cannot be sent twice
    assert len(seen) == 1


@pytest.mark.timeout(300)
def test_a_full_cap_is_waited_out_by_the_sdk(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> None:
    data = tmp_path_factory.mktemp("retry")
    server = start_server(data, {"RELIGHT_MAX_ACTIVE_JOBS": "2", "RELIGHT_TEST_JOB_DELAY_S": "1"}, database=database)
    try:
        with server.client() as c:
            env = c.upload_envmap(exr_bytes(make_envmap(32, seed=700), data))

            def one(k: int) -> str:
                with server.client() as ck:
                    job = ck.submit(env.id, "phong:s=16", epsilon=0.05, size=8 + k)
                    return ck.wait(job.id, timeout=240).state

            with ThreadPoolExecutor(8) as pool:
                states = list(pool.map(one, range(8)))
            assert states == [JobState.succeeded] * 8
        log = server.output()
        assert " 500 " not in log and "Traceback" not in log, log[-3000:]
        metrics = httpx.get(f"{server.url}/metrics", timeout=30).text
        assert re.search(r"^relight_jobs_succeeded_total 8(\.0)?$", metrics, re.M), metrics[:2000]
    finally:
        server.stop()
