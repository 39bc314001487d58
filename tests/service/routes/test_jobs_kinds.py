"""The one job system, for every kind of job (``shrm``, ``tradeoff``, ``scene``), against a real server:

* each kind's job streams its progress as server-sent events (``GET /jobs/{id}/events``) to a terminal state;
* each kind's job can be cancelled mid-run (``DELETE``): it ends ``cancelled``, its result is never stored, and
  its slot under the active-job cap is free again;
* the cap holds under concurrent submissions (exactly ``max_active_jobs`` accepted, the rest 429 + Retry-After);
* jobs of every kind left running by a killed server are resumed by the next one.

The server runs with ``RELIGHT_TEST_JOB_DELAY_S`` (TEST ONLY): every job of every kind first waits that long,
reporting progress, so "mid-run" is a state the test observes rather than a race.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest
from httpx_sse import ServerSentEvent, connect_sse

from relight.worker.blobs import BlobStore
from relight.worker.results import existing_result

from ..postgres import Backend
from ..support import Server, assert_problem, exr_bytes, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(300)
DELAY_S = 1.5
CAP = 4
#: The cap test's jobs wait this long: far longer than answering 20 submissions takes on a loaded machine.
CAP_DELAY_S = 60.0
ENV = {"RELIGHT_TEST_JOB_DELAY_S": str(DELAY_S), "RELIGHT_MAX_ACTIVE_JOBS": str(CAP)}


def shrm(env: str, k: int) -> dict[str, Any]:
    return {"envmap": env, "brdf": "phong:s=16", "epsilon": 0.05, "size": 8 + k}


def tradeoff(env: str, k: int) -> dict[str, Any]:
    return {"envmap": env, "brdf": "phong:s=16", "rows": 16, "size": 8, "epsilons": [0.1 + 0.01 * k],
            "truncations": [0.1]}


def scene(env: str, k: int) -> dict[str, Any]:
    return {"environment": env, "epsilon": 0.05, "size": 8 + k, "objects": [
        {"name": "chalk", "size": 1, "distance": 10, "material": "lambert:albedo=0.7"}]}


#: kind -> (submission path, request body of variant k, the kind's own resource path, the kind's DELETE path)
KINDS: dict[str, tuple[str, Callable[[str, int], dict[str, Any]], str, str]] = {
    "shrm": ("/shrms", shrm, "/jobs", "/jobs"),
    "tradeoff": ("/tradeoffs", tradeoff, "/tradeoffs", "/tradeoffs"),
    "scene": ("/scenes", scene, "/scenes", "/scenes"),
}
#: A stage each kind's task reports after the test delay (worker/tasks.py, worker/analysis.py).
WORK_STAGE = {"shrm": "prefiltering", "tradeoff": "sweeping", "scene": "running"}


@pytest.fixture(scope="module")
def slow(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, Any]]:
    data = tmp_path_factory.mktemp("kinds")
    state: dict[str, Any] = {"data": data, "database": database, "server": start_server(data, ENV, database=database)}
    with httpx.Client(base_url=state["server"].url, timeout=60) as http:
        r = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=31), data))
        assert r.status_code in (200, 201), r.text
        state["env"] = r.json()["id"]
    yield state
    state["server"].stop()


@pytest.fixture
def http(slow: dict[str, Any]) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=slow["server"].url, timeout=60) as c:
        yield c


def events(http: httpx.Client, path: str) -> Iterator[ServerSentEvent]:
    with connect_sse(http, "GET", path, timeout=httpx.Timeout(120.0, connect=10.0)) as source:
        assert source.response.status_code == 200
        assert source.response.headers["content-type"].startswith("text/event-stream")
        yield from source.iter_sse()


def active(http: httpx.Client) -> set[str]:
    return {j["id"] for st in ("queued", "running") for j in http.get("/jobs", params={"state": st}).json()["items"]}


def submit(http: httpx.Client, kind: str, env: str, k: int) -> str:
    path, body, _, _ = KINDS[kind]
    r = http.post(path, json=body(env, k))
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_streams_progress_to_the_end(slow: dict[str, Any], http: httpx.Client, kind: str) -> None:
    job_id = submit(http, kind, slow["env"], 0)
    assert http.get(f"/jobs/{job_id}").json()["kind"] == kind
    stream = list(events(http, f"/jobs/{job_id}/events"))
    names = [e.event for e in stream]
    assert names[-1] == "end" and set(names[:-1]) == {"job"}, names
    ids = [int(e.id) for e in stream]
    assert ids == sorted(set(ids)), ids
    jobs = [json.loads(e.data) for e in stream]
    assert all(j["id"] == job_id and j["kind"] == kind for j in jobs)
    assert jobs[-1]["state"] == "succeeded" and jobs[-1]["progress"] == 1.0, jobs[-1]
    running = [j for j in jobs if j["state"] == "running"]
    assert any(0.0 < j["progress"] < 1.0 for j in running), [(j["state"], j["progress"]) for j in jobs]
    stages = {j["stage"] for j in running}
    assert {"test_delay", WORK_STAGE[kind]} <= stages, stages
    progress = [j["progress"] for j in jobs]
    assert progress == sorted(progress), progress  # one submission: progress never goes back
    # the kind's own resource says the same, and a finished job's stream is its state, then "end"
    _, _, resource, _ = KINDS[kind]
    assert http.get(f"{resource}/{job_id}").json()["state"] == "succeeded"
    again = [(e.event, json.loads(e.data)["state"]) for e in events(http, f"{resource}/{job_id}/events")]
    assert again == [("job", "succeeded"), ("end", "succeeded")]
    assert_problem(http.delete(f"/jobs/{job_id}"), 409, "succeeded")
    # one table, but each kind's own routes know only their kind
    for other in {"/shrms", "/tradeoffs", "/scenes"} - {KINDS[kind][0]}:
        assert_problem(http.get(f"{other}/{job_id}"), 404, job_id)
    assert kind in {j["kind"] for j in http.get("/jobs", params={"kind": kind}).json()["items"]}
    assert job_id not in {j["id"] for j in http.get("/jobs", params={"kind": "none"}).json()["items"]}


def no_result(slow: dict[str, Any], http: httpx.Client, kind: str, job_id: str) -> None:
    """The job stays cancelled with no stored result (checked for longer than the task would have needed)."""
    deadline = time.monotonic() + 4 * DELAY_S
    while time.monotonic() < deadline:
        job = http.get(f"/jobs/{job_id}").json()
        assert job["state"] == "cancelled" and job["stage"] == "cancelled", job
        if kind == "shrm":
            assert_problem(http.get(f"/shrms/{job_id}"), 409, "cancelled")
            assert existing_result(BlobStore(Path(slow["data"]) / "blobs"), job_id) is None
        elif kind == "tradeoff":
            assert http.get(f"/tradeoffs/{job_id}").json()["points"] is None
        else:
            body = http.get(f"/scenes/{job_id}").json()
            assert body["files"] is None and body["plan"] is None
        time.sleep(0.25)


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_cancels_mid_run(slow: dict[str, Any], http: httpx.Client, kind: str) -> None:
    job_id = submit(http, kind, slow["env"], 1)
    _, _, _, delete = KINDS[kind]
    seen: list[tuple[str, str, str | None]] = []
    cancelled = False
    for e in events(http, f"/jobs/{job_id}/events"):
        job = json.loads(e.data)
        seen.append((e.event, job["state"], job["stage"]))
        if job["state"] == "running" and job["stage"] == "test_delay" and not cancelled:
            cancelled = True
            r = http.delete(f"{delete}/{job_id}")
            assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
            assert job_id not in active(http)  # its slot under the cap is free at once
        if e.event == "end":
            break
    assert seen[-1] == ("end", "cancelled", "cancelled"), seen
    assert ("job", "running", "test_delay") in seen
    no_result(slow, http, kind, job_id)
    assert http.delete(f"{delete}/{job_id}").json()["state"] == "cancelled"  # idempotent


def test_the_active_job_cap_is_atomic(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> None:
    """20 concurrent submissions of distinct jobs under a cap of 4: exactly 4 accepted, 16 answered 429 with
    Retry-After; cancelling frees the slots for the next ones. (Its own server, whose jobs wait long enough that
    none can finish while the submissions are answered, however loaded the machine.)"""
    data = tmp_path_factory.mktemp("cap")
    server = start_server(data, {**ENV, "RELIGHT_TEST_JOB_DELAY_S": str(CAP_DELAY_S)}, database=database)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            env = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=32), data)).json()["id"]

            def post(k: int) -> httpx.Response:
                with httpx.Client(base_url=server.url, timeout=120) as c:
                    return c.post("/shrms", json=shrm(env, k))

            with ThreadPoolExecutor(20) as pool:
                answers = list(pool.map(post, range(20)))
            accepted = [r.json()["id"] for r in answers if r.status_code == 202]
            rejected = [k for k, r in enumerate(answers) if r.status_code == 429]
            assert len(accepted) == CAP and len(rejected) == 20 - CAP, [r.status_code for r in answers]
            for k in rejected:
                body = assert_problem(answers[k], 429, f"limit {CAP}")
                assert int(answers[k].headers["retry-after"]) > 0, body
            assert active(http) == set(accepted)
            for job_id in accepted:
                assert http.delete(f"/jobs/{job_id}").json()["state"] == "cancelled"
            assert active(http) == set()
            freed = [http.post("/shrms", json=shrm(env, k)) for k in rejected[:CAP]]
            assert [r.status_code for r in freed] == [202] * CAP
            assert_problem(http.post("/shrms", json=shrm(env, rejected[CAP])), 429, "limit")
            for r in freed:
                assert http.delete(f"/jobs/{r.json()['id']}").json()["state"] == "cancelled"
    finally:
        server.stop()


def test_every_kind_resumes_after_a_server_restart(slow: dict[str, Any]) -> None:
    """Jobs of every kind running or queued when the server is killed are submitted again by the next server
    process and finish there."""
    server: Server = slow["server"]
    with httpx.Client(base_url=server.url, timeout=60) as http:
        wait_until(lambda: not active(http), 120, "earlier jobs to end")
        ids = {kind: submit(http, kind, slow["env"], 2) for kind in KINDS}

        def two_running() -> bool:  # two workers: two jobs run, the third waits queued; none can finish yet
            states = [http.get(f"/jobs/{i}").json()["state"] for i in ids.values()]
            assert set(states) <= {"queued", "running"}, states
            return states.count("running") == 2

        wait_until(two_running, 60, "two jobs to run")
    server.kill()  # SIGKILL: server, scheduler and workers die at once
    slow["server"] = restarted = start_server(slow["data"], ENV, log_name="server2.log",
                                               database=slow["database"])
    with httpx.Client(base_url=restarted.url, timeout=60) as http:
        for kind, job_id in ids.items():
            final = json.loads([e for e in events(http, f"/jobs/{job_id}/events")][-1].data)
            assert final["state"] == "succeeded" and final["kind"] == kind, final
            assert final["submissions"] == 2, final  # once by each server process
        assert http.get(f"/tradeoffs/{ids['tradeoff']}").json()["points"]
        assert http.get(f"/scenes/{ids['scene']}").json()["files"]
        assert http.get(f"/shrms/{ids['shrm']}").status_code == 200
