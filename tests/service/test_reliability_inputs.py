"""Issue 12, item 2 (every input bounded), tried as an attacker would against a real server on loopback: a server
with an API key and small limits, raw sockets where an HTTP client would refuse to send the request.

Each test sends the attack and checks the answer *and* that the server did not do the work: a 413/401 arrives
while the body has not been sent at all, nothing is stored after a rejection, the server stays healthy.
"""

from __future__ import annotations

import hashlib
import json
import socket
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from .postgres import Backend
from .support import Server, assert_healthy, assert_problem, exr_bytes, make_envmap, start_server, wait_done

pytestmark = pytest.mark.timeout(180)

API_KEY = "reliability-key-51c2"
AUTH = {"X-API-Key": API_KEY}
#: Small limits so "too large" stays small: JSON bodies of 64 KiB, results of 4 MiB, uploads of 40 MB (a MERL file
#: is 35 MB and must fit).
JSON_LIMIT = 64 * 1024
OUTPUT_LIMIT = 4 << 20
UPLOAD_LIMIT = 40_000_000


@pytest.fixture(scope="module")
def guarded(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp("guarded"), {
        "RELIGHT_API_KEY_HASHES": hashlib.sha256(API_KEY.encode()).hexdigest(),
        "RELIGHT_MAX_JSON_BYTES": str(JSON_LIMIT), "RELIGHT_MAX_OUTPUT_BYTES": str(OUTPUT_LIMIT),
        "RELIGHT_MAX_UPLOAD_BYTES": str(UPLOAD_LIMIT)}, database=database)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def gh(guarded: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=guarded.url, timeout=60.0, headers=AUTH) as c:
        yield c


@pytest.fixture(scope="module")
def envmap_id(gh: httpx.Client, tmp_path_factory: pytest.TempPathFactory) -> str:
    r = gh.post("/envmaps", content=exr_bytes(make_envmap(32, seed=7), tmp_path_factory.mktemp("img")))
    assert r.status_code in (200, 201), r.text
    return str(r.json()["id"])


def raw_request(server: Server, head: bytes, body: bytes = b"", *, timeout: float = 30.0) -> tuple[int, dict[str, str],
                                                                                                     bytes]:
    """Send ``head`` (and ``body``) on a fresh socket and read the whole answer (the server closes or sends its
    Content-Length). Returns status, headers (lower-case names) and body."""
    host, port = server.url.removeprefix("http://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=timeout) as sock:
        sock.sendall(head + body)
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = sock.recv(65536)
            if not chunk:
                break
            data += chunk
        head_bytes, _, rest = data.partition(b"\r\n\r\n")
        lines = head_bytes.decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])}
        length = int(headers.get("content-length", "0"))
        while len(rest) < length:
            chunk = sock.recv(65536)
            if not chunk:
                break
            rest += chunk
    return status, headers, rest


def post_head(path: str, length: int, *, key: str | None = API_KEY, ctype: str = "application/json") -> bytes:
    lines = [f"POST {path} HTTP/1.1", "Host: localhost", f"Content-Type: {ctype}", f"Content-Length: {length}"]
    if key is not None:
        lines.append(f"X-API-Key: {key}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def blob_files(server: Server) -> set[str]:
    root = Path(server.args[server.args.index("--data") + 1]) / "blobs"
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


# ------------------------------------------------------------------------------------------------ body and header
@pytest.mark.parametrize("path", ["/plan", "/shrms", "/brdfs", "/scenes", "/tradeoffs", "/envmaps", "/brdfs/measured"])
def test_declared_oversize_body_is_413_unread(guarded: Server, path: str) -> None:
    """A 50 MB Content-Length with no body sent at all: the 413 can only come before reading."""
    status, headers, body = raw_request(guarded, post_head(path, 50_000_000))
    assert status == 413, body
    assert headers["content-type"].startswith("application/problem+json")
    assert "50000000" in json.loads(body)["detail"]


@pytest.mark.parametrize("key", [None, "wrong-key"])
@pytest.mark.parametrize("path", ["/plan", "/envmaps", "/brdfs/measured"])
def test_api_key_checked_before_the_body(guarded: Server, path: str, key: str | None) -> None:
    """Without or with a wrong key, a small declared body that is never sent still gets its 401: the key is
    checked before the body is read (a read would wait for the missing bytes until the socket times out)."""
    status, headers, body = raw_request(guarded, post_head(path, 1000, key=key), timeout=20.0)
    assert status == 401, body
    assert "api key" in json.loads(body)["detail"].lower()
    assert "bearer" in headers["www-authenticate"].lower()


def test_chunked_json_over_the_limit_is_413(gh: httpx.Client) -> None:
    """No Content-Length (chunked): the bytes are counted while reading, the 413 comes at the limit."""
    def chunks() -> Iterator[bytes]:
        yield b'{"envmap": "' + b"a" * 64 + b'", "brdf": "phong:s=' + b"1" * (2 * JSON_LIMIT)
        yield b'"}'

    assert_problem(gh.post("/plan", content=chunks(), headers={"Content-Type": "application/json"}), 413,
                   str(JSON_LIMIT))
    assert_healthy(gh)


def test_chunked_upload_over_the_limit_is_413_and_nothing_stored(guarded: Server, gh: httpx.Client,
                                                                 tmp_path: Path) -> None:
    valid = exr_bytes(make_envmap(16, seed=3), tmp_path)
    before = blob_files(guarded)

    def chunks() -> Iterator[bytes]:
        yield valid
        for _ in range(UPLOAD_LIMIT // (1 << 20) + 2):
            yield bytes(1 << 20)

    assert_problem(gh.post("/envmaps", content=chunks()), 413, str(UPLOAD_LIMIT))
    assert blob_files(guarded) == before
    assert_healthy(gh)


@pytest.mark.parametrize(("method", "url"), [("GET", "/envmaps/ab%00cd"), ("GET", "/jobs/ab%00cd"),
                                           ("POST", "/meshes?name=a%00b.obj"), ("GET", "/jobs?state=queued%00")])
def test_a_nul_in_the_url_is_422_and_nothing_stored(guarded: Server, gh: httpx.Client, method: str, url: str
                                                    ) -> None:
    """A NUL character in an id or a name: on PostgreSQL these were 500s (psycopg refuses a string literal with a
    NUL; SQLite answered 404 and stored a mesh named ``a\\x00b.obj``); now 422 on both (documented on every route with a
    parameter, as FastAPI's own parameter errors), before the route runs."""
    before = blob_files(guarded)
    body = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" if method == "POST" else None
    assert_problem(gh.request(method, url, content=body), 422, "NUL")
    assert blob_files(guarded) == before  # the mesh upload's body was never read, let alone stored
    assert_healthy(gh)


def test_header_over_64_kib_is_431(guarded: Server, gh: httpx.Client) -> None:
    """1 MB of header (the issue's attack used 100 MB; the server reads at most one socket read past 64 KiB)."""
    head = (b"GET /health HTTP/1.1\r\nHost: localhost\r\nX-Pad: " + b"x" * (1 << 20) + b"\r\n\r\n")
    status, headers, body = raw_request(guarded, head)
    assert status == 431, body
    assert json.loads(body)["status"] == 431
    many = b"GET /health HTTP/1.1\r\nHost: localhost\r\n" + b"".join(b"X-H%d: %s\r\n" % (i, b"y" * 100)
                                                                    for i in range(2000)) + b"\r\n"
    assert raw_request(guarded, many)[0] == 431
    ok = b"GET /health HTTP/1.1\r\nHost: localhost\r\nX-Pad: " + b"x" * 8000 + b"\r\n\r\n"
    assert raw_request(guarded, ok)[0] == 200
    assert_healthy(gh)


# ------------------------------------------------------------------------------------------------ BRDF strings
def test_sum_string_has_the_object_forms_term_limit(gh: httpx.Client, envmap_id: str) -> None:
    """The issue's attack: ``lambert+lambert+...`` of 80 KB. Nine terms are refused (the object form takes 8)
    before parsing; eight are planned."""
    r = gh.post("/plan", json={"envmap": envmap_id, "brdf": "+".join(["lambert"] * 9), "order": 2})
    assert_problem(r, 422, "9 terms", "at most 8")
    r = gh.post("/plan", json={"envmap": envmap_id, "brdf": "+".join(["lambert"] * 8), "order": 2})
    assert r.status_code == 200, r.text
    r = gh.post("/plan", json={"envmap": envmap_id, "brdf": "+".join(["lambert"] * 8000), "order": 2})
    assert_problem(r, 422, "characters")


@pytest.mark.parametrize(("brdf", "field"), [
    ("torrance-sparrow:alpha=1e-300", "torrance-sparrow.alpha"),
    ({"kind": "torrance-sparrow", "alpha": 1e-300}, "alpha"),
    ("ggx:alpha=1e-300", "ggx.alpha"),
    ("microfacet:sigma=1e-300", "microfacet.sigma"),
    ("ward:rho_d=0.5,rho_s=0.1,alpha=1e-300", "ward.alpha"),
    ("phong:s=1e308", "s"),
    ("lambert+blinn-phong:s=1e308", "s"),
    ("lambert+ggx:alpha=1e-300", "alpha"),
    ("ggx-ld:roughness=1e-300", "roughness"),
])
def test_parameter_ranges_hold_whatever_the_form(gh: httpx.Client, envmap_id: str, brdf: Any, field: str) -> None:
    """Strings, objects and sums alike: 422 naming the field, never "order 0, error 0"; no job is created."""
    for route in ("/plan", "/shrms"):
        assert_problem(gh.post(route, json={"envmap": envmap_id, "brdf": brdf}), 422, field)
    jobs = gh.get("/jobs").json()["items"]
    assert all("1e-300" not in json.dumps(j) and "1e+308" not in json.dumps(j) for j in jobs)


# ------------------------------------------------------------------------------------------------ output size
def test_output_size_is_checked_in_plan_and_at_submit(gh: httpx.Client, envmap_id: str) -> None:
    """An SHRM of order 40, P = 8 at S = 512: 81 layers of 512 x 1024 float32 RGB = 10 GiB... here any output over
    the test server's 4 MiB. /plan and /shrms both say so and name the bytes; no job row is created."""
    body = {"envmap": envmap_id, "brdf": "torrance-sparrow:alpha=0.3", "order": 8, "p_order": 4, "size": 256}
    expected = 25 * 256 * 512 * 3 * 4  # (P + 1)^2 layers of S x 2S float32 RGB
    assert expected > OUTPUT_LIMIT
    r = gh.post("/plan", json=body)
    assert_problem(r, 422, "bytes", str(OUTPUT_LIMIT))
    assert r.json()["output_bytes"] >= expected
    before = {j["id"] for j in gh.get("/jobs").json()["items"]}
    assert_problem(gh.post("/shrms", json=body), 422, str(OUTPUT_LIMIT))
    assert {j["id"] for j in gh.get("/jobs").json()["items"]} == before
    small = {**body, "size": 16}
    assert gh.post("/plan", json=small).status_code == 200


# ------------------------------------------------------------------------------------------------ non-finite results
def test_non_finite_result_fails_the_job_with_a_reason(gh: httpx.Client, envmap_id: str) -> None:
    """A MERL file whose samples are all 1e308 (finite, so the file is valid) overflows while prefiltering: the
    job fails and says why, it is never "succeeded" with +Inf texels."""
    merl = struct.pack("<3i", 90, 90, 180) + np.full(3 * 90 * 90 * 180, 1e308, dtype="<f8").tobytes()
    r = gh.post("/brdfs/measured", content=merl)
    assert r.status_code in (200, 201), r.text
    brdf_id = r.json()["id"]
    r = gh.post("/shrms", json={"envmap": envmap_id, "brdf": brdf_id, "order": 2, "p_order": 1, "size": 8})
    assert r.status_code in (200, 202), r.text
    job = wait_done(gh, f"/jobs/{r.json()['id']}")
    assert job["state"] == "failed", job
    assert "non-finite" in job["failure_reason"], job
    assert_problem(gh.get(f"/shrms/{job['id']}/coefficients.exr"), 409)
