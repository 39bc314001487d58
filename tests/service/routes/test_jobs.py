"""``/jobs`` and ``/plan`` basics, unknown ids, and requests that name what is wrong."""

from __future__ import annotations

import re

import httpx
import pytest

from relight.client.sdk import RelightClient

from ..postgres import Backend
from ..support import assert_healthy, assert_problem

pytestmark = pytest.mark.timeout(120)
UNKNOWN = "f" * 64


def test_unknown_ids_are_404(http: httpx.Client) -> None:
    for path in (f"/jobs/{UNKNOWN}", f"/jobs/{UNKNOWN}/events", f"/shrms/{UNKNOWN}",
                 f"/shrms/{UNKNOWN}/coefficients.exr", f"/shrms/{UNKNOWN}/coefficients.bin",
                 f"/shrms/{UNKNOWN}/reflection.exr", f"/tradeoffs/{UNKNOWN}/events", f"/scenes/{UNKNOWN}/events",
                 "/no/such/route"):
        assert_problem(http.get(path), 404)
    for path in (f"/jobs/{UNKNOWN}", f"/tradeoffs/{UNKNOWN}", f"/scenes/{UNKNOWN}"):
        assert_problem(http.delete(path), 404, UNKNOWN)
    assert_problem(http.post("/shrms", json={"envmap": UNKNOWN, "brdf": "phong:s=8"}), 404, UNKNOWN)
    assert_problem(http.post("/plan", json={"envmap": UNKNOWN, "brdf": "phong:s=8"}), 404, UNKNOWN)
    assert_healthy(http)


def test_invalid_job_requests(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    cases = [
        ({"envmap": env.id, "brdf": "phong:s=8", "epsilon": 1.5}, "epsilon"),
        ({"envmap": env.id, "brdf": "phong:s=8", "epsilon": 0.1, "order": 3}, "not both"),
        ({"envmap": env.id, "brdf": "phong:s=8", "order": -1}, "order"),
        ({"envmap": env.id, "brdf": "phong:s=8", "order": 100000}, "100000"),
        ({"envmap": env.id, "brdf": "phong:s=8", "size": 10**9}, "1000000000"),
        ({"envmap": env.id, "brdf": "phong:s=-3"}, "brdf"),
        ({"envmap": env.id, "brdf": "nonsense:x=1"}, "nonsense"),
        ({"envmap": env.id, "brdf": "phong:s=8", "colour": "red"}, "colour"),
        ({"envmap": "xyz", "brdf": "phong:s=8"}, "envmap"),
    ]
    for body, fragment in cases:
        for path in ("/plan", "/shrms"):
            assert_problem(http.post(path, json=body), 422, fragment)
    assert_healthy(http)


def test_list_and_finished_job_cannot_be_cancelled(client: RelightClient, http: httpx.Client,
                                                   sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    job = client.wait(client.submit(env.id, "phong:s=4", epsilon=0.05).id, timeout=60)
    assert job.id in {j.id for j in client.list_jobs(state="succeeded")}
    assert_problem(http.delete(f"/jobs/{job.id}"), 409, "succeeded")
    events = http.get(f"/jobs/{job.id}/events")  # a finished job's stream is its state, then "end"
    assert events.headers["content-type"].startswith("text/event-stream")
    assert "event: end" in events.text and '"succeeded"' in events.text


def test_metrics_and_health(http: httpx.Client, database: Backend) -> None:
    text = http.get("/metrics").text
    for name in ('relight_jobs{state="succeeded"}', "relight_job_duration_seconds_count", "relight_cache_hits_total",
                 "relight_workers"):
        assert name in text, name
    h = http.get("/health").json()
    assert h["status"] == "ok" and h["workers"] == 2 and h["database"] == database.name
    # start-up froze its objects out of the garbage collector's scans (relight.server.run.settle_heap): 0 without
    # it; a server with FastAPI, SQLAlchemy, NumPy and a Dask scheduler loaded holds well over 50 000 objects
    frozen = re.search(r"^relight_gc_frozen_objects (\d+)$", text, re.M)
    assert frozen is not None and int(frozen[1]) > 50_000, text[-1500:]
    full = re.search(r'^relight_gc_pause_seconds_count\{generation="2"\} (\d+)$', text, re.M)
    assert full is not None, text[-1500:]
