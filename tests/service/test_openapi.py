"""Property-based run of the OpenAPI schema (schemathesis) against the live server: no 5xx, responses conform.

Bounded: a few examples per operation, no deadline per example, and a per-test time limit. The run has a server of
its own, stopped with its worker processes when the module ends: the jobs fuzzed GETs start (a 1024^2 DFG table, a
1024^2 cube chain: minutes of CPU each) must not keep the shared server's workers busy for the tests after it.
It runs on both databases (the ``database`` fixture): strings PostgreSQL refuses (a NUL character) were 500s there
while SQLite answered 404.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import (
    content_type_conformance,
    not_a_server_error,
    response_schema_conformance,
    status_code_conformance,
)

from .postgres import Backend
from .support import Server, start_server

MAX_EXAMPLES = 8


@pytest.fixture(scope="module")
def fuzz_server(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp(f"fuzz-{database.name}"), {"RELIGHT_PRELOAD_MESHES": "bunny,teapot"},
                       database=database)
    yield srv
    srv.stop()


@pytest.fixture
def api_schema(fuzz_server: Server) -> schemathesis.BaseSchema:
    return schemathesis.openapi.from_url(fuzz_server.url + "/openapi.json")


schema = schemathesis.pytest.from_fixture("api_schema")


# One test item runs every operation (as subtests), so its limit covers all ~40 of them (about 60 s on an idle
# machine, 210 s measured with the machine shared by a dozen test runs); each request has its own 60 s limit.
@pytest.mark.timeout(900)
@schema.parametrize()
@settings(max_examples=MAX_EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None)
def test_no_server_errors(case: Any) -> None:
    case.call_and_validate(checks=[not_a_server_error, status_code_conformance, content_type_conformance,
                                   response_schema_conformance], timeout=60)
