"""The route tests run on both databases the service supports (issue 12, item 10): every server of this folder is
started with the ``database`` fixture (tests/service/conftest.py), the shared ``server`` included."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from ..postgres import Backend
from ..support import Server, start_server


@pytest.fixture(scope="session")
def server(database: Backend, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """The shared test server of the route tests (as tests/service/conftest.py's), on ``database``."""
    srv = start_server(tmp_path_factory.mktemp(f"server-{database.name}"), {"RELIGHT_PRELOAD_MESHES": "bunny,teapot"},
                       database=database)
    yield srv
    srv.stop()
