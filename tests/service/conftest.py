"""Fixtures of the service tests: the shared server (real uvicorn on a free loopback port, embedded Dask cluster
with two worker processes) and clients for it. Helpers live in :mod:`support`.

``database`` runs a test on both databases the service supports (issue 12, item 10): once on SQLite (the default,
a file in the server's data directory) and once on PostgreSQL (Debian's ``postgresql``, started once for the
session by :mod:`tests.service.postgres`, one database per server data directory). It is a session-scoped
parametrised fixture, so pytest runs the tests that use it on SQLite first and then on PostgreSQL (ids end in
``[sqlite]`` / ``[postgresql]``); a suite opts in by starting its servers with ``start_server(...,
database=database)``: every route test (tests/service/routes/), resume after a kill and cancellation
(test_resilience), the fault-injection kills of the embedded and of the deployment-form cluster (scheduler killed),
SIGTERM and resume (test_faults), the scale-out cluster (test_scale_out), and every reliability suite with a server
of its own (test_reliability_*, test_client_retry, test_interactive_slots, test_envmap_streaming). The stateless
schemathesis run (test_openapi) too: on PostgreSQL it met strings SQLite takes and PostgreSQL refuses (NUL). One
database each: test_reliability_postgres (PostgreSQL by construction: two servers on one database), the stateful
fuzz run (test_openapi_stateful: its budget is minutes per run) and test_reliability_compute
(the planning sandboxes, which read one envmap row: its server burns 20 CPU seconds per plan, about 3 minutes per
leg on a loaded 2-core machine). ``RELIGHT_TEST_DATABASES=sqlite`` (or
``postgresql``) runs one of them only, for a quicker local run; CI runs both.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from relight.client.sdk import RelightClient

from .postgres import Backend, start_postgres
from .support import Server, assert_healthy, assert_problem, exr_bytes, make_envmap, start_server

# Re-exported: tests elsewhere (tests/web) import these helpers from here.
__all__ = ["Server", "assert_healthy", "assert_problem", "exr_bytes", "make_envmap", "start_server"]


DATABASES = [d.strip() for d in os.environ.get("RELIGHT_TEST_DATABASES", "sqlite,postgresql").split(",")
             if d.strip()]
if not set(DATABASES) <= {"sqlite", "postgresql"} or not DATABASES:
    raise pytest.UsageError(f"RELIGHT_TEST_DATABASES: sqlite and/or postgresql, not {DATABASES}")


@pytest.fixture(scope="session", params=DATABASES)
def database(request: pytest.FixtureRequest) -> Iterator[Backend]:
    if request.param == "sqlite":
        yield Backend("sqlite")
        return
    pg = start_postgres()
    try:
        yield Backend("postgresql", pg)
    finally:
        pg.stop()


@pytest.fixture(scope="session")
def data_tmp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("data")


@pytest.fixture(scope="session")
def sample_exr(data_tmp: Path) -> bytes:
    return exr_bytes(make_envmap(64, seed=1), data_tmp)


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """The shared test server: embedded cluster with two worker processes; the small sample meshes preloaded."""
    srv = start_server(tmp_path_factory.mktemp("server"), {"RELIGHT_PRELOAD_MESHES": "bunny,teapot"})
    yield srv
    srv.stop()


@pytest.fixture
def client(server: Server) -> Iterator[RelightClient]:
    with server.client() as c:
        yield c


@pytest.fixture
def http(server: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=server.url, timeout=60.0) as c:
        yield c


