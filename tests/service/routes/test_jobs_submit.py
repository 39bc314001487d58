"""``POST /jobs``: any registered kind through one generic route, against a real server.

* the three kinds with their own routes: ``POST /jobs {"kind": k, "request": body}`` is the same job (same id, the
  SHA-256 of the same canonical request) as ``POST /shrms|/tradeoffs|/scenes`` with ``body``: 202 + ``Location``
  while pending, 200 once finished, whichever route asked first;
* a kind that is only a task function plus a registration (``registered_kind.py``, loaded through
  ``RELIGHT_JOB_KIND_MODULES``): submitted, streamed to the end, its result and file read through the generic
  routes, and cancelled mid-run;
* every registered kind (a sample request each, which a new kind must add): one job watched over SSE to the end,
  one cancelled mid-run;
* the cap (429 + Retry-After) and validation (422 naming the field or the known kinds) hold on the generic route.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from httpx_sse import connect_sse

from ..postgres import Backend
from ..support import assert_problem, exr_bytes, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(300)
DELAY_S = 1.0
CAP = 2
ENV = {"RELIGHT_TEST_JOB_DELAY_S": str(DELAY_S), "RELIGHT_MAX_ACTIVE_JOBS": str(CAP),
       "RELIGHT_JOB_KIND_MODULES": "tests.service.routes.registered_kind"}


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, Any]]:
    data = tmp_path_factory.mktemp("submit")
    server = start_server(data, ENV, database=database)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            r = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=41), data))
            assert r.status_code in (200, 201), r.text
            m = http.post("/meshes", content=TETRAHEDRON, params={"name": "tetrahedron.obj"})
            assert m.status_code in (200, 201), m.text
            yield {"url": server.url, "env": r.json()["id"], "mesh": m.json()["id"]}
    finally:
        server.stop()


@pytest.fixture
def http(served: dict[str, Any]) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=served["url"], timeout=60) as c:
        yield c


def stream(http: httpx.Client, job_id: str) -> list[tuple[str, dict[str, Any]]]:
    with connect_sse(http, "GET", f"/jobs/{job_id}/events", timeout=httpx.Timeout(120.0, connect=10.0)) as source:
        assert source.response.status_code == 200
        return [(e.event, json.loads(e.data)) for e in source.iter_sse()]


def idle(http: httpx.Client) -> bool:
    return not any(http.get("/jobs", params={"state": s}).json()["items"] for s in ("queued", "running"))


#: kind -> (its own route, a request body that route takes)
def bodies(env: str) -> dict[str, tuple[str, dict[str, Any]]]:
    return {
        "shrm": ("/shrms", {"envmap": env, "brdf": "phong:s=16", "epsilon": 0.05, "size": 12}),
        "tradeoff": ("/tradeoffs", {"envmap": env, "brdf": "phong:s=16", "rows": 16, "size": 8,
                                    "epsilons": [0.1], "truncations": [0.1]}),
        "scene": ("/scenes", {"environment": env, "epsilon": 0.05, "size": 12, "objects": [
            {"name": "chalk", "size": 1, "distance": 10, "material": "lambert:albedo=0.7"}]}),
    }


#: A closed tetrahedron (OBJ): the smallest mesh a visibility job takes.
TETRAHEDRON = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"

#: kind -> request of variant k (distinct k: distinct jobs). Every registered kind needs one here (the acceptance
#: test of the job system runs each kind to the end and cancels one mid-run).
SAMPLES: dict[str, Callable[[dict[str, Any], int], dict[str, Any]]] = {
    "shrm": lambda s, k: {**bodies(s["env"])["shrm"][1], "size": 20 + k},
    "tradeoff": lambda s, k: {**bodies(s["env"])["tradeoff"][1], "epsilons": [0.2 + 0.01 * k]},
    "scene": lambda s, k: {**bodies(s["env"])["scene"][1], "size": 20 + k},
    "squares": lambda s, k: {"n": 300 + k},
    "visibility": lambda s, k: {"mesh": s["mesh"], "order": 1, "rays": 16, "seed": 1 + k},
    "sh_table": lambda s, k: {"brdf": "ashikhmin-shirley:nu=24,nv=8", "order": 2, "resolution": 8 + k,
                              "layout": "hemi-octahedral"},
    "gaussian_fit": lambda s, k: {"brdf": "phong:s=16", "lobes": 1, "max_lobes": 1, "elevations": 2 + k},
    "gaussian_chain": lambda s, k: {"envmap": s["env"], "levels": 2 + k},
    "ibl": lambda s, k: {"envmap": s["env"], "target": "gltf", "size": 4, "levels": 2 + k},
    "dfg": lambda s, k: {"size": 16 + k, "format": "ktx2"},
    "factorization": lambda s, k: {"brdf": "phong:s=8", "resolution": 8 + k, "factors": 2},
    "inout_prt": lambda s, k: {"mesh": s["mesh"], "brdf": "phong:s=4", "terms": 3, "order": 1, "rays": 16 + k},
    "sh_transfer": lambda s, k: {"mesh": s["mesh"], "brdf": "phong:s=4", "order": 1, "resolution": 4,
                                 "rays": 16 + k},
}


def test_every_registered_kind_has_a_sample(http: httpx.Client) -> None:
    kinds = set(http.get("/jobs/kinds").json()["items"])
    assert kinds == set(SAMPLES), (f"kinds without a sample request: {sorted(kinds - set(SAMPLES))} (add one to "
                                   "SAMPLES in tests/service/routes/test_jobs_submit.py); samples of no kind: "
                                   f"{sorted(set(SAMPLES) - kinds)}")


@pytest.mark.parametrize("kind", sorted(SAMPLES))
def test_every_kind_streams_to_the_end_and_cancels_mid_run(served: dict[str, Any], http: httpx.Client,
                                                           kind: str) -> None:
    """Through ``POST /jobs``: one job of the kind watched over SSE until it succeeds, a second one cancelled while
    it runs (it ends ``cancelled`` and keeps no result)."""
    wait_until(lambda: idle(http), 120, "earlier jobs to end")
    r = http.post("/jobs", json={"kind": kind, "request": SAMPLES[kind](served, 0)})
    assert r.status_code == 202, r.text
    events = stream(http, r.json()["id"])
    assert [e for e, _ in events][-1] == "end" and events[-1][1]["state"] == "succeeded", events[-1]
    assert any(j["state"] == "running" and 0 < j["progress"] < 1 for _, j in events), [j for _, j in events]
    r = http.post("/jobs", json={"kind": kind, "request": SAMPLES[kind](served, 1)})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    seen = []
    with connect_sse(http, "GET", f"/jobs/{job_id}/events", timeout=httpx.Timeout(120.0, connect=10.0)) as source:
        for e in source.iter_sse():
            job = json.loads(e.data)
            seen.append((e.event, job["state"], job["stage"]))
            if job["state"] == "running" and job["stage"] == "test_delay" and ("cancel",) not in seen:
                seen.append(("cancel",))
                assert http.delete(f"/jobs/{job_id}").json()["state"] == "cancelled"
            if e.event == "end":
                break
    assert ("cancel",) in seen and seen[-1] == ("end", "cancelled", "cancelled"), seen
    assert_problem(http.get(f"/jobs/{job_id}/result"), 409, "cancelled")


def test_kinds_are_listed(http: httpx.Client) -> None:
    kinds = set(http.get("/jobs/kinds").json()["items"])
    assert {"shrm", "tradeoff", "scene", "squares", "visibility", "sh_table"} <= kinds


@pytest.mark.parametrize("kind", ["shrm", "tradeoff", "scene"])
def test_generic_route_and_own_route_share_one_job(served: dict[str, Any], http: httpx.Client, kind: str) -> None:
    wait_until(lambda: idle(http), 120, "earlier jobs to end")
    route, body = bodies(served["env"])[kind]
    generic = http.post("/jobs", json={"kind": kind, "request": body})
    assert generic.status_code == 202, generic.text
    job = generic.json()
    assert generic.headers["location"] == f"/jobs/{job['id']}" and job["kind"] == kind
    own = http.post(route, json=body)
    assert own.status_code == 202 and own.json()["id"] == job["id"], own.text
    events = stream(http, job["id"])
    assert events[-1][0] == "end" and events[-1][1]["state"] == "succeeded", events[-1]
    again = http.post("/jobs", json={"kind": kind, "request": body})
    assert again.status_code == 200 and again.json()["id"] == job["id"], again.text
    assert http.post(route, json=body).status_code == 200
    result = http.get(f"/jobs/{job['id']}/result")
    assert result.status_code == 200, result.text
    assert {"shrm": "manifest_sha256", "tradeoff": "points", "scene": "files"}[kind] in result.json()
    if kind == "scene":  # the scene's files are served by the generic route too, byte for byte
        files = result.json()["files"]
        name = next(iter(files))
        a, b = http.get(f"/jobs/{job['id']}/files/{name}"), http.get(f"/scenes/{job['id']}/files/{name}")
        assert a.status_code == 200 and a.content == b.content and a.headers["etag"] == b.headers["etag"]


def test_a_kind_that_is_only_a_registration(http: httpx.Client) -> None:
    """Submit, stream to the end, read the result and its file: nothing but ``registered_kind.py`` exists."""
    wait_until(lambda: idle(http), 120, "earlier jobs to end")
    n = 1000
    r = http.post("/jobs", json={"kind": "squares", "request": {"n": n}})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    events = stream(http, job_id)
    names = [e for e, _ in events]
    assert names[-1] == "end" and set(names[:-1]) == {"job"}, names
    stages = {j["stage"] for _, j in events if j["state"] == "running"}
    assert {"test_delay", "squaring"} <= stages, stages
    final = events[-1][1]
    assert final["state"] == "succeeded" and final["request"] == {"n": n}
    assert final["links"]["result"] == f"/jobs/{job_id}/result"
    result = http.get(final["links"]["result"]).json()
    assert result["sum"] == n * (n - 1) * (2 * n - 1) // 6  # closed form of sum_{k<n} k^2
    f = http.get(final["links"]["squares.bin"])
    assert f.status_code == 200 and f.headers["etag"] == f'"{result["files"]["squares.bin"]["sha256"]}"'
    assert np.array_equal(np.frombuffer(f.content, "<i8"), np.arange(n, dtype=np.int64) ** 2)
    assert http.get(final["links"]["squares.bin"], headers={"If-None-Match": f.headers["etag"]}).status_code == 304
    assert_problem(http.get(f"/jobs/{job_id}/files/nothing.bin"), 404, "nothing.bin")
    # identical request, same job: 200 with the finished job
    again = http.post("/jobs", json={"kind": "squares", "request": {"n": n}})
    assert again.status_code == 200 and again.json()["id"] == job_id


def test_a_registered_kind_cancels_mid_run(http: httpx.Client) -> None:
    wait_until(lambda: idle(http), 120, "earlier jobs to end")
    r = http.post("/jobs", json={"kind": "squares", "request": {"n": 7}})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    seen = []
    with connect_sse(http, "GET", f"/jobs/{job_id}/events", timeout=httpx.Timeout(120.0, connect=10.0)) as source:
        for e in source.iter_sse():
            job = json.loads(e.data)
            seen.append((e.event, job["state"], job["stage"]))
            if job["state"] == "running" and job["stage"] == "test_delay" and len(seen) < 100:
                assert http.delete(f"/jobs/{job_id}").json()["state"] == "cancelled"
            if e.event == "end":
                break
    assert seen[-1] == ("end", "cancelled", "cancelled"), seen
    assert_problem(http.get(f"/jobs/{job_id}/result"), 409, "cancelled")
    assert http.get(f"/jobs/{job_id}").json()["state"] == "cancelled"


def test_the_cap_holds_on_the_generic_route(http: httpx.Client) -> None:
    wait_until(lambda: idle(http), 120, "earlier jobs to end")
    accepted = [http.post("/jobs", json={"kind": "squares", "request": {"n": 100 + k}}) for k in range(CAP)]
    assert [a.status_code for a in accepted] == [202] * CAP, [a.text for a in accepted]
    over = http.post("/jobs", json={"kind": "squares", "request": {"n": 100 + CAP}})
    assert_problem(over, 429, f"limit {CAP}")
    assert int(over.headers["retry-after"]) > 0
    for a in accepted:
        assert http.delete(f"/jobs/{a.json()['id']}").json()["state"] == "cancelled"


def test_bad_submissions_name_what_is_wrong(http: httpx.Client) -> None:
    body = assert_problem(http.post("/jobs", json={"kind": "nonsense", "request": {}}), 422, "nonsense", "squares")
    assert body["errors"][0]["field"] == "kind"
    body = assert_problem(http.post("/jobs", json={"kind": "squares", "request": {"n": -3}}), 422, "request.n")
    assert body["errors"][0]["value"] == -3
    assert_problem(http.post("/jobs", json={"kind": "squares", "request": {"n": 3, "m": 1}}), 422, "request.m")
    assert_problem(http.post("/jobs", json={"kind": "squares"}), 422, "request")
    assert_problem(http.post("/jobs", json={"kind": "tradeoff", "request": {"envmap": "0" * 64,
                                                                            "brdf": "phong:s=8"}}), 404, "0" * 16)
    assert_problem(http.get(f"/jobs/{'f' * 64}/result"), 404)


def test_a_coloured_brdf_for_interreflections_is_a_422_and_no_job(served: dict[str, Any], http: httpx.Client
                                                                    ) -> None:
    """sh_transfer holds one matrix per vertex: a coloured BRDF (its bounces differ per channel) is refused before a
    job exists, naming the BRDF, as any other bad parameter; the grey form of the same material is accepted."""
    before = http.get("/jobs").json()
    base = {"mesh": served["mesh"], "order": 1, "resolution": 4, "rays": 16}
    coloured = [{"kind": "ward", "rho_d": 0.1, "rho_s": [0.5, 0.3, 0.2], "alpha": 0.2},
                [{"kind": "lambert", "albedo": [0.8, 0.5, 0.2]}, {"kind": "phong", "s": 8}]]
    for brdf in coloured:
        assert_problem(http.post("/jobs", json={"kind": "sh_transfer", "request": {**base, "brdf": brdf}}),
                       422, "brdf", "grey")
    assert http.get("/jobs").json() == before
    grey = http.post("/jobs", json={"kind": "sh_transfer", "request": {**base, "brdf": "ward:rho_d=0.1,rho_s=0.5,"
                                                                                       "alpha=0.2"}})
    assert grey.status_code in (200, 202), grey.text


def test_the_sdks_submit_any_kind(served: dict[str, Any]) -> None:
    """``RelightClient.submit_job`` / ``job_result`` / ``job_file`` and their async twins."""
    import anyio

    from relight.client.async_sdk import AsyncRelightClient
    from relight.client.sdk import RelightClient

    with RelightClient(served["url"]) as c:
        wait_until(lambda: not c.list_jobs("queued") and not c.list_jobs("running"), 120, "earlier jobs to end")
        job = c.submit_job("squares", {"n": 50})
        assert c.wait(job.id, timeout=120).state == "succeeded"
        result = c.job_result(job.id)
        assert result["sum"] == 50 * 49 * 99 // 6
        assert np.array_equal(np.frombuffer(c.job_file(job.id, "squares.bin"), "<i8"), np.arange(50) ** 2)

    async def run() -> None:
        async with AsyncRelightClient(served["url"]) as a:
            job = await a.submit_job("squares", {"n": 51})
            assert (await a.wait(job.id, timeout=120)).state == "succeeded"
            assert (await a.job_result(job.id))["sum"] == 51 * 50 * 101 // 6
            assert len(await a.job_file(job.id, "squares.bin")) == 51 * 8

    anyio.run(run)
