"""The route tests run on both databases the service supports (issue 12, item 10): every test of this folder once
on SQLite (the default, a file in the server's data directory) and once on PostgreSQL (Debian's ``postgresql``,
started once for the session by :mod:`tests.service.postgres`, one database per server data directory).

``database`` is a session-scoped parametrised fixture, so pytest runs the whole folder on SQLite first and then on
PostgreSQL (test ids end in ``[sqlite]`` / ``[postgresql]``); every server of this folder is started with it
(``start_server(..., database=database)``), the shared ``server`` included. ``RELIGHT_TEST_DATABASES=sqlite`` (or
``postgresql``) runs one of them only, for a quicker local run; CI runs both.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from ..postgres import Backend, start_postgres
from ..support import Server, start_server

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
def server(database: Backend, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """The shared test server of the route tests (as tests/service/conftest.py's), on ``database``."""
    srv = start_server(tmp_path_factory.mktemp(f"server-{database.name}"), {"RELIGHT_PRELOAD_MESHES": "bunny,teapot"},
                       database=database)
    yield srv
    srv.stop()
