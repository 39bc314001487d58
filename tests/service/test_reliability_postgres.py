"""Issue 12, item 10: the service on a real PostgreSQL (``tests/service/postgres.py``), the documented scale-out
database, which had never run.

Two servers (each with its embedded cluster) share one database and one blob store: the same request submitted to
both at once is one job (the duplicate-insert path: the second INSERT meets the primary key), computed once, its
result equal to the library's bit for bit; uploads, BRDFs and rejections go through the same tables; a server
restarted on the database finds its finished job and serves the result.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pytest

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
                                                        "RELIGHT_BLOB_DIR": str(shared)}, log_name=f"{name}.log")


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
        # Not asserted: runs == 1. Each server's watcher submits the job to its own embedded cluster, so two
        # servers on one database compute it twice (identical results, one row); issue 12 item 10 finding, for
        # the job system (a claim on the row before submitting).


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
