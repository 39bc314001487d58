"""Fixtures of the service tests: the shared server (real uvicorn on a free loopback port, embedded Dask cluster
with two worker processes) and clients for it. Helpers live in :mod:`support`."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from relight.client.sdk import RelightClient

from .support import Server, assert_healthy, assert_problem, exr_bytes, make_envmap, start_server

# Re-exported: tests elsewhere (tests/web) import these helpers from here.
__all__ = ["Server", "assert_healthy", "assert_problem", "exr_bytes", "make_envmap", "start_server"]


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


