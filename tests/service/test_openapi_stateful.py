"""schemathesis against the API-key server with OpenAPI links and valid-magic bodies (issue 12, item 8).

``test_openapi.py`` sends random bodies, which stop at the upload's magic-byte check, so no parser sees them. Here:

- the server requires an API key (``RELIGHT_API_KEY_HASHES``) and every request sends it;
- upload bodies (``POST``/``PUT /envmaps``, ``POST /meshes``) are real small files (OpenEXR, Radiance RGBE, OBJ,
  glTF) mutated after their magic bytes (overwrites with boundary integers, NaN/Inf floats, huge decimal numbers,
  truncation), so the EXR/RGBE header checks, the decoders and the mesh parsers are reached; ``POST /jobs`` bodies
  are ``sh_table`` requests with drawn BRDF parameters, orders and resolutions (in and out of range);
- OpenAPI links (added to the server's document before loading) go from every create (``POST``/``PUT /envmaps``,
  ``POST /meshes``, ``POST /jobs``) to each operation on the created resource that takes its id alone
  (``GET /envmaps/{id}``, its texture and previews, ``GET /meshes/{id}`` and its files, ``GET``/``DELETE
  /jobs/{id}``, ...), so the stateful run follows the resources it created.

Budget: ``UPLOAD_EXAMPLES`` = 200 mutated bodies per upload route (3 routes, 600 uploads) and ``JOB_EXAMPLES`` =
100 job bodies; the stateful run is ``SCENARIOS`` = 500 scenarios of at most ``STEPS`` = 12 calls (about 3,900 calls
measured). Both tests took 82 s at load average 3 on the shared 2-core machine, so well under 3 minutes idle.
Checks: no 5xx, status codes, content types and bodies conform to the document. Both tests also count what reached
the parsers and which links were followed, and fail if the bodies never got past the magic check or a link was never
taken (so the run cannot pass by testing nothing).
"""

from __future__ import annotations

import copy
import hashlib
import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import requests
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from hypothesis.errors import FlakyStrategyDefinition
from schemathesis.checks import (
    content_type_conformance,
    not_a_server_error,
    response_schema_conformance,
    status_code_conformance,
)
from schemathesis.core.result import Ok

from .support import Server, exr_bytes, hdr_bytes, make_envmap, start_server

API_KEY = "fuzz-key-5e21"
UPLOAD_EXAMPLES = 200
JOB_EXAMPLES = 100
SCENARIOS = 500
STEPS = 12
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]
UPLOADS = {("POST", "/envmaps"), ("PUT", "/envmaps"), ("POST", "/meshes")}
CREATES = {**{k: "/envmaps" for k in [("POST", "/envmaps"), ("PUT", "/envmaps")]},
           ("POST", "/meshes"): "/meshes", ("POST", "/jobs"): "/jobs"}

OBJ = b"""# tetrahedron
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vn 0 0 1
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""


def gltf_bytes() -> bytes:
    import base64

    import numpy as np

    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    idx = np.array([0, 1, 2], np.uint32).tobytes()
    buf = pos + idx
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
    }
    return json.dumps(doc).encode()


#: Replacements written over a seed file: boundary integers (little-endian), NaN/Inf/huge floats, decimal text.
SPECIALS = [b"\xff\xff\xff\xff", b"\xff\xff\xff\x7f", b"\x00\x00\x00\x80", b"\x00\x00\x00\x00", b"\x00\x00\x80\x7f",
            b"\x00\x00\xc0\x7f", b"\xff\xff\x7f\x7f", b"\x01", b"1e308", b"-1", b"nan", b"99999999999", b"\n", b"/"]


def mutated(seeds: list[bytes]) -> st.SearchStrategy[bytes]:
    """A seed file with up to 4 overwrites after its first 4 bytes (the magic stays) and an optional truncation."""
    edit = st.tuples(st.integers(0, 1 << 20), st.sampled_from(SPECIALS) | st.binary(min_size=1, max_size=8))

    def apply(args: tuple[bytes, list[tuple[int, bytes]], int | None]) -> bytes:
        seed, edits, cut = args
        data = bytearray(seed)
        for pos, chunk in edits:
            at = 4 + pos % (len(data) - 4)
            data[at:at + len(chunk)] = chunk
        if cut is not None:
            data = data[:4 + cut % (len(data) - 3)]
        return bytes(data)

    return st.tuples(st.sampled_from(seeds), st.lists(edit, max_size=4), st.none() | st.integers(0, 1 << 20)).map(apply)


def job_bodies() -> st.SearchStrategy[dict[str, Any]]:
    """``sh_table`` submissions: small, mostly valid, some out of range (orders, resolutions, BRDF parameters)."""
    num = st.sampled_from([0.5, 2, 8, 24, 1e308, -1, 0]) | st.floats(0.01, 100)
    brdf = st.one_of(st.just("lambert"), num.map(lambda s: f"phong:s={s}"),
                     st.tuples(num, num).map(lambda t: f"ashikhmin-shirley:nu={t[0]},nv={t[1]}"),
                     num.map(lambda s: {"kind": "phong", "s": s}))
    request = st.fixed_dictionaries({"brdf": brdf, "order": st.integers(-1, 10), "resolution": st.integers(0, 20)})
    return st.fixed_dictionaries({"kind": st.sampled_from(["sh_table", "sh_table", "no_such_kind"]),
                                  "request": request})


def add_links(raw: dict[str, Any]) -> int:
    """OpenAPI links from each create to every operation on ``{prefix}/{id}`` (and its sub-paths with no other
    path parameter, event streams excepted: they stay open while a job runs). Returns how many were added."""
    added = 0
    for (method, path), prefix in CREATES.items():
        op = raw["paths"][path][method.lower()]
        links: dict[str, Any] = {}
        for target, item in raw["paths"].items():
            if not target.startswith(prefix + "/{") or target.count("{") != 1 or target.endswith("/events"):
                continue
            param = target[len(prefix) + 2:].split("}")[0]
            for tm, top in item.items():
                if tm in ("get", "delete", "post", "put"):
                    links[f"{tm}_{top['operationId']}"] = {"operationId": top["operationId"],
                                                          "parameters": {param: "$response.body#/id"}}
        for code in ("200", "201", "202"):
            if code in op["responses"]:
                op["responses"][code]["links"] = copy.deepcopy(links)
                added += len(links)
    return added


@pytest.fixture(scope="module")
def keyed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp("keyed-fuzz"),
                       {"RELIGHT_API_KEY_HASHES": hashlib.sha256(API_KEY.encode()).hexdigest()})
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[bytes]]:
    tmp: Path = tmp_path_factory.mktemp("seeds")
    img = make_envmap(16, seed=3)
    return {"/envmaps": [exr_bytes(img, tmp), hdr_bytes(img, tmp)], "/meshes": [OBJ, gltf_bytes()]}


@pytest.fixture(scope="module")
def fuzz_schema(keyed: Server, seeds: dict[str, list[bytes]]) -> schemathesis.BaseSchema:
    with httpx.Client(base_url=keyed.url, timeout=60) as http:
        assert http.get("/envmaps").status_code == 401  # the key is really required
        resp = http.get("/openapi.json", headers={"X-API-Key": API_KEY})
        assert resp.status_code == 200, resp.text
        raw = resp.json()
    assert add_links(raw) >= 8
    schema = schemathesis.openapi.from_dict(raw)
    schema.config.update(base_url=keyed.url, headers={"X-API-Key": API_KEY}, request_timeout=60)
    bodies = {"/envmaps": mutated(seeds["/envmaps"]), "/meshes": mutated(seeds["/meshes"])}

    @schema.hook
    def flatmap_body(context: schemathesis.HookContext, body: Any) -> st.SearchStrategy[Any]:
        op = context.operation
        assert op is not None
        if (op.method.upper(), op.path) in UPLOADS:
            return bodies[op.path]
        if (op.method.upper(), op.path) == ("POST", "/jobs"):
            return job_bodies()
        return st.just(body)

    return schema


def run_case(case: Any, seen: Counter[tuple[str, str, int]]) -> None:
    response = case.call()
    seen[(case.method.upper(), case.path, response.status_code)] += 1
    case.validate_response(response, checks=CHECKS)


@pytest.mark.timeout(600)
def test_uploads_and_jobs_reach_the_parsers(fuzz_schema: schemathesis.BaseSchema) -> None:
    seen: Counter[tuple[str, str, int]] = Counter()
    fuzzed = fuzz_schema.include(path_regex=r"^/(envmaps|meshes|jobs)$", method=["POST", "PUT"])
    for result in fuzzed.get_all_operations():
        assert isinstance(result, Ok), result
        op = result.ok()
        n = JOB_EXAMPLES if op.path == "/jobs" else UPLOAD_EXAMPLES

        @settings(max_examples=n, deadline=None, database=None, derandomize=True,
                  suppress_health_check=list(HealthCheck))
        @given(case=op.as_strategy())
        def one(case: Any) -> None:
            run_case(case, seen)

        one()
    codes = dict(seen)
    print(sorted(codes.items()))
    # Mutated files reached the decoders: some accepted (201/200), some refused by a parser (422) -- a body stopped
    # at the magic check would be 415 only.
    for method, path in UPLOADS:
        assert any(seen[(method, path, c)] for c in (200, 201)), codes
        assert seen[(method, path, 422)], codes
    assert seen[("POST", "/jobs", 202)] + seen[("POST", "/jobs", 200)] and seen[("POST", "/jobs", 422)], codes


@pytest.mark.timeout(600)
def test_stateful_links(fuzz_schema: schemathesis.BaseSchema, keyed: Server) -> None:
    seen: Counter[tuple[str, str, int]] = Counter()
    server_errors: list[str] = []
    scenarios = [0]
    # Event streams stay open while their job runs (minutes for a fuzzed /dfg?size=1024) and schemathesis reads a
    # stream to its end: its own link inference (Location: /jobs/{id}) reached GET /jobs/{id}/events and held the
    # run for over 15 minutes in CI. The streams have their own tests (tests/service/routes/test_jobs.py,
    # test_jobs_kinds.py); here they are left out, as add_links leaves them out.
    base = fuzz_schema.exclude(path_regex=r"/events$").as_state_machine()

    class Workflow(base):  # type: ignore[misc, valid-type]
        def setup(self) -> None:
            scenarios[0] += 1

        def call(self, case: Any, **kwargs: Any) -> Any:
            try:
                response = case.call(**kwargs)
            except requests.Timeout:  # the server's stacks (threads, asyncio tasks) say what it waits for
                keyed.dump_stacks()
                raise AssertionError(f"{case.method} {case.formatted_path}: no answer within the client's timeout; "
                                     f"server log:\n{keyed.output()[-20000:]}") from None
            seen[(case.method.upper(), case.path, response.status_code)] += 1
            if response.status_code >= 500:  # kept even if hypothesis later calls the failure flaky
                server_errors.append(f"{case.method} {case.formatted_path} -> {response.status_code}: "
                                     f"{case.as_curl_command()} {response.text[:300]}")
            return response

        def validate_response(self, response: Any, case: Any, additional_checks: Any = None, **kwargs: Any) -> None:
            case.validate_response(response, checks=CHECKS)

    # A scenario's rules depend on the server's answers (a known file is 200, not 201; a job may have finished), so
    # hypothesis can meet a prefix that draws differently the second time and stop with FlakyStrategyDefinition;
    # schemathesis' own runner restarts then, and so does this loop, until the budget of scenarios has run.
    for _ in range(200):  # restarts are cheap; a loaded CI run met only 381 scenarios within 10 rounds
        if scenarios[0] >= SCENARIOS:
            break
        try:
            Workflow.run(settings=settings(max_examples=SCENARIOS - scenarios[0], stateful_step_count=STEPS,
                                           deadline=None, database=None, phases=[Phase.generate],
                                           suppress_health_check=list(HealthCheck)))
        except FlakyStrategyDefinition:
            continue
    codes = dict(seen)
    print(scenarios[0], sorted(codes.items()))
    assert not server_errors, server_errors
    assert scenarios[0] >= SCENARIOS
    # Each link was taken to a resource that exists: a 200 on the id-only GET routes of all three kinds.
    for path in ("/envmaps/{envmap_id}", "/meshes/{mesh_id}", "/jobs/{job_id}"):
        assert seen[("GET", path, 200)], (path, codes)
    assert any(seen[("DELETE", "/jobs/{job_id}", c)] for c in (200, 409)), codes
