"""Issue 12, item 10: the service on a real PostgreSQL (``tests/service/postgres.py``), the documented scale-out
database, which had never run.

Two servers (each with its embedded cluster) share one database and one blob store: the same request submitted to
both at once is one job (the duplicate-insert path: the second INSERT meets the primary key), computed once (the
claim in the job table: one owner, one submission, one run), its result equal to the library's bit for bit;
uploads, BRDFs and rejections go through the same tables. A job computed by one server streams its progress on
the other (the stream reads the row); a cancel sent to the other server stops the owner's task; a killed server's
job is taken over once its claim lapses. A server restarted on the database finds its finished job and serves the
result.
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pytest
from httpx_sse import connect_sse

from .postgres import Postgres, start_postgres
from .support import (
    Server,
    assert_problem,
    exr_bytes,
    library_map,
    make_envmap,
    read_exr,
    start_server,
    wait_done,
    wait_until,
)

pytestmark = pytest.mark.timeout(300)
#: TEST ONLY: every job of these servers first waits this long (reporting progress, honouring cancel), so a test can
#: watch a job run on one server from the other, cancel it, or kill its server while it runs.
DELAY_S = 3.0


@pytest.fixture(scope="module")
def pg() -> Iterator[Postgres]:
    db = start_postgres()
    yield db
    db.stop()


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("shared-blobs")


def pg_server(tmp_path_factory: pytest.TempPathFactory, pg: Postgres, shared: Path, name: str) -> Server:
    return start_server(tmp_path_factory.mktemp(name), {"RELIGHT_DATABASE_URL": pg.url,
                                                        "RELIGHT_BLOB_DIR": str(shared),
                                                        "RELIGHT_TEST_JOB_DELAY_S": str(DELAY_S)},
                        log_name=f"{name}.log")


def submissions_total(h: httpx.Client) -> float:
    """Jobs this server has submitted to its own cluster (its ``/metrics``)."""
    m = re.search(r"^relight_job_submissions_total (\S+)$", h.get("/metrics").text, re.M)
    return float(m.group(1)) if m else 0.0


def stream(h: httpx.Client, job_id: str) -> list[dict[str, object]]:
    """Every update of the job's event stream on this server, to its end."""
    with connect_sse(h, "GET", f"/jobs/{job_id}/events", timeout=httpx.Timeout(180.0, connect=10.0)) as source:
        assert source.response.status_code == 200
        return [json.loads(e.data) for e in source.iter_sse()]


def manifests_for(blobs: Path, job_id: str) -> int:
    """Result manifests of ``job_id`` in the shared store (small JSON blobs naming the job)."""
    n = 0
    for p in (blobs / "sha256").rglob("*"):
        if p.is_file() and p.stat().st_size < 1 << 16:
            try:
                n += json.loads(p.read_bytes()).get("id") == job_id
            except (ValueError, UnicodeDecodeError, AttributeError):
                continue
    return n


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory, pg: Postgres, shared: Path) -> Iterator[list[Server]]:
    servers = [pg_server(tmp_path_factory, pg, shared, n) for n in ("pg-a", "pg-b")]
    yield servers
    for s in servers:
        s.stop()


def test_two_servers_share_one_postgres_database(pair: list[Server], pg: Postgres, tmp_path: Path) -> None:
    a, b = pair
    exr = exr_bytes(make_envmap(32, seed=21), tmp_path)
    with httpx.Client(base_url=a.url, timeout=120) as ha, httpx.Client(base_url=b.url, timeout=120) as hb:
        for h in (ha, hb):
            health = h.get("/health").json()
            assert health["database"] == "postgresql" and health["status"] == "ok", health
        env = ha.post("/envmaps", content=exr)
        assert env.status_code == 201, env.text
        again = hb.post("/envmaps", content=exr)  # known to the other server through the database
        assert again.status_code == 200 and again.json()["id"] == env.json()["id"]
        env_id = env.json()["id"]
        assert pg.count(f"SELECT count(*) FROM envmaps WHERE id = '{env_id}'") == 1

        assert_problem(hb.post("/plan", json={"envmap": env_id, "brdf": "lambert+" * 8 + "lambert"}), 422, "terms")

        body = {"envmap": env_id, "brdf": "phong:s=24", "order": 8, "size": 16}
        with ThreadPoolExecutor(8) as pool:  # both servers at once: the duplicate INSERT path
            answers = list(pool.map(lambda i: (ha, hb)[i % 2].post("/shrms", json=body), range(8)))
        assert all(r.status_code in (200, 202) for r in answers), [r.text for r in answers]
        ids = {r.json()["id"] for r in answers}
        assert len(ids) == 1
        job_id = ids.pop()
        assert pg.count(f"SELECT count(*) FROM jobs WHERE id = '{job_id}'") == 1
        # Polled on both servers: each streams events only from its own cluster (the job may run on either).
        done = wait_until(lambda: all(h.get(f"/jobs/{job_id}").json()["state"] == "succeeded" for h in (ha, hb)),
                          180, "the shared job to succeed on both servers", interval=0.5)
        assert done
        got_a = ha.get(f"/shrms/{job_id}/coefficients.exr")
        got_b = hb.get(f"/shrms/{job_id}/coefficients.exr")
        assert got_a.status_code == got_b.status_code == 200
        assert got_a.content == got_b.content
        assert hashlib.sha256(got_a.content).hexdigest() == got_a.headers["etag"].strip('"')
        expected = library_map(exr, "phong:s=24", order=8, size=16)
        got = read_exr(got_a.content)[""]
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32)), "differs from the library bit for bit"
        # One claim: only the server that inserted the row submitted it, once, and one worker started it once.
        final = ha.get(f"/jobs/{job_id}").json()
        assert final["runs"] == 1 and final["submissions"] == 1, final
        assert pg.count(f"SELECT count(*) FROM jobs WHERE id = '{job_id}' AND owner IS NOT NULL") == 1


def test_a_job_computed_by_one_server_streams_and_cancels_on_the_other(pair: list[Server], pg: Postgres,
                                                                      shared: Path, tmp_path: Path) -> None:
    a, b = pair
    exr = exr_bytes(make_envmap(32, seed=23), tmp_path)
    with httpx.Client(base_url=a.url, timeout=120) as ha, httpx.Client(base_url=b.url, timeout=120) as hb:
        env_id = ha.post("/envmaps", content=exr).json()["id"]
        before = submissions_total(ha), submissions_total(hb)
        body = {"envmap": env_id, "brdf": "phong:s=12", "order": 6, "size": 16}
        r = ha.post("/shrms", json=body)
        assert r.status_code == 202, r.text
        job_id = r.json()["id"]
        assert hb.post("/shrms", json=body).json()["id"] == job_id  # asked of B too: still A's job
        updates = stream(hb, job_id)  # B computes nothing: its stream follows A's progress through the row
        running = [u for u in updates if u["state"] == "running" and u["stage"] == "test_delay"]
        assert running and all(0.0 <= float(str(u["progress"])) < 1.0 for u in running), updates
        assert len({u["progress"] for u in running}) >= 2, f"one progress value only: {running}"
        assert updates[-1]["state"] == "succeeded" and updates[-1]["runs"] == 1, updates[-1]
        assert updates[-1]["submissions"] == 1
        assert (submissions_total(ha), submissions_total(hb)) == (before[0] + 1, before[1])
        expected = library_map(exr, "phong:s=12", order=6, size=16)
        got = read_exr(hb.get(f"/shrms/{job_id}/coefficients.exr").content)[""]
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))

        # Cancelled through B while A's worker runs it: A cancels its task (its lease loop sees the row), the
        # worker stops inside the test delay, and no result is ever written.
        r = ha.post("/shrms", json={**body, "brdf": "phong:s=14"})
        job_id = r.json()["id"]
        wait_until(lambda: hb.get(f"/jobs/{job_id}").json()["state"] == "running", 60, "A's worker to start it")
        gone = hb.delete(f"/jobs/{job_id}")
        assert gone.status_code == 200 and gone.json()["state"] == "cancelled", gone.text
        assert stream(ha, job_id)[-1]["state"] == "cancelled"
        wait_until(lambda: "no longer this server's" in a.output(), 30, "A to cancel its task")
        time.sleep(DELAY_S + 5.0)  # past the end of the delay and a computation of this size (< 1 s) had it run on
        assert manifests_for(shared, job_id) == 0, "the cancelled job was computed anyway"
        final = hb.get(f"/jobs/{job_id}").json()
        assert final["state"] == "cancelled" and final["runs"] == 1 and final["submissions"] == 1, final


def test_a_killed_servers_job_is_taken_over_once_its_claim_lapses(
        tmp_path_factory: pytest.TempPathFactory, pair: list[Server], pg: Postgres, shared: Path,
        tmp_path: Path) -> None:
    doomed = pg_server(tmp_path_factory, pg, shared, "pg-doomed")
    exr = exr_bytes(make_envmap(32, seed=24), tmp_path)
    try:
        with httpx.Client(base_url=doomed.url, timeout=120) as h:
            env_id = h.post("/envmaps", content=exr).json()["id"]
            job_id = h.post("/shrms", json={"envmap": env_id, "brdf": "phong:s=16", "order": 6, "size": 16}
                            ).json()["id"]
            wait_until(lambda: h.get(f"/jobs/{job_id}").json()["state"] == "running", 60, "the job to start")
    finally:
        doomed.kill()  # SIGKILL: no release of its claim; the others must wait for the lease to lapse
    killed_at = time.monotonic()
    with httpx.Client(base_url=pair[1].url, timeout=120) as hb:
        final = stream(hb, job_id)[-1]
        assert final["state"] == "succeeded", final
        assert time.monotonic() - killed_at > 5.0  # not before the dead server's lease (10 s, TEST_ENV) lapsed
        assert final["submissions"] == 2 and final["runs"] == 2, final  # the dead server's run, and the new one
        got = read_exr(hb.get(f"/shrms/{job_id}/coefficients.exr").content)[""]
    expected = library_map(exr, "phong:s=16", order=6, size=16)
    assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))
    assert manifests_for(shared, job_id) == 1


def test_a_restarted_server_finds_its_jobs_in_postgres(tmp_path_factory: pytest.TempPathFactory, pg: Postgres,
                                                       shared: Path, tmp_path: Path) -> None:
    first = pg_server(tmp_path_factory, pg, shared, "pg-restart")
    exr = exr_bytes(make_envmap(32, seed=22), tmp_path)
    try:
        with httpx.Client(base_url=first.url, timeout=120) as h:
            env_id = h.post("/envmaps", content=exr).json()["id"]
            r = h.post("/shrms", json={"envmap": env_id, "brdf": "lambert", "order": 2, "size": 8})
            job = wait_done(h, f"/jobs/{r.json()['id']}")
            assert job["state"] == "succeeded", job
            before = h.get(f"/shrms/{job['id']}/coefficients.exr").content
    finally:
        first.stop()
    second = start_server(Path(first.args[first.args.index("--data") + 1]),
                          {"RELIGHT_DATABASE_URL": pg.url, "RELIGHT_BLOB_DIR": str(shared)}, log_name="again.log")
    try:
        with httpx.Client(base_url=second.url, timeout=120) as h:
            assert h.get(f"/jobs/{job['id']}").json()["state"] == "succeeded"
            r = h.post("/shrms", json={"envmap": env_id, "brdf": "lambert", "order": 2, "size": 8})
            assert r.status_code == 200, r.text  # finished: not computed again
            assert h.get(f"/shrms/{job['id']}/coefficients.exr").content == before
    finally:
        second.stop()
