"""Issue 12, item 7 (security), against a real server on loopback with an API key.

* The embedded Dask cluster: its address is not in ``/health``; every port the server and its workers listen on,
  but the API's, refuses a Dask client that has no certificate (plain TCP and TLS alike) and answers no HTTP
  (Dask starts HTTP servers even with dashboards off: they are stopped).
* Every route of the OpenAPI document, every method, without a key and with a wrong one: 401 (``/health`` and
  ``/metrics`` excepted, as documented).
* Error bodies carry no server path and no exception text: a store made unwritable gives a problem with an
  incident reference, the path and the exception only in the server's log.
"""

from __future__ import annotations

import hashlib
import re
import socket
from collections.abc import Iterator
from pathlib import Path

import httpx
import psutil
import pytest
from distributed import Client
from distributed.security import Security

from .postgres import Backend
from .support import Server, exr_bytes, make_envmap, start_server

pytestmark = pytest.mark.timeout(240)

API_KEY = "security-key-0b7d"
PUBLIC = {"/health", "/metrics"}


@pytest.fixture(scope="module")
def keyed(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp("keyed"),
                       {"RELIGHT_API_KEY_HASHES": hashlib.sha256(API_KEY.encode()).hexdigest()}, database=database)
    yield srv
    srv.stop()


def listening_ports(server: Server) -> set[int]:
    procs = [psutil.Process(server.pid), *psutil.Process(server.pid).children(recursive=True)]
    ports = set()
    for p in procs:
        for c in p.net_connections(kind="inet"):
            if c.status == psutil.CONN_LISTEN:
                ports.add(c.laddr.port)
    return ports


def http_answer(port: int) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(b"GET /health HTTP/1.0\r\nHost: x\r\n\r\n")
        s.settimeout(5)
        try:
            return s.recv(64)
        except (TimeoutError, ConnectionResetError):
            return b""


def test_dask_is_unreachable_and_unpublished(keyed: Server) -> None:
    api_port = int(keyed.url.rsplit(":", 1)[1])
    health = httpx.get(f"{keyed.url}/health", timeout=30).json()
    ports = listening_ports(keyed) - {api_port}
    assert len(ports) >= 3  # scheduler + one per worker at least
    assert health["scheduler"] == "embedded"
    text = str(health)
    assert "tcp://" not in text and "tls://" not in text and not any(str(p) in text for p in ports)
    assert http_answer(api_port).startswith(b"HTTP/1.")
    for port in sorted(ports):
        assert not http_answer(port).startswith(b"HTTP/"), f"port {port} answers HTTP"
        with pytest.raises((OSError, TimeoutError)):  # plain TCP: the TLS server hangs up
            Client(f"tcp://127.0.0.1:{port}", timeout=3, set_as_default=False).close()
        with pytest.raises((OSError, TimeoutError)):  # TLS with a certificate of the attacker's own CA
            Client(f"tls://127.0.0.1:{port}", timeout=3, set_as_default=False,
                   security=Security.temporary()).close()


def _concrete(path: str) -> str:
    return re.sub(r"\{[^}]+\}", "a" * 64, path)


def test_every_openapi_route_needs_the_key(keyed: Server) -> None:
    with httpx.Client(base_url=keyed.url, timeout=30.0) as http:
        doc = http.get("/openapi.json").json()
        probed = 0
        for path, item in doc["paths"].items():
            for method in item:
                if method not in ("get", "post", "put", "delete", "patch"):
                    continue
                url = _concrete(path)
                for headers in ({}, {"X-API-Key": "wrong"}, {"Authorization": "Bearer wrong"}):
                    r = http.request(method.upper(), url, headers=headers, content=b"{}" if method != "get" else None)
                    if path in PUBLIC:
                        assert r.status_code == 200, (method, path, r.status_code)
                        continue
                    assert r.status_code == 401, (method, path, headers, r.status_code, r.text[:200])
                    assert r.headers["content-type"].startswith("application/problem+json")
                    probed += 1
        assert probed >= 3 * 20  # every route of the document, three ways
        ok = http.get("/jobs", headers={"X-API-Key": API_KEY})
        assert ok.status_code == 200


def test_error_bodies_hold_no_paths_or_exception_text(keyed: Server, tmp_path: Path) -> None:
    """The store's temporary directory replaced by a file: the upload fails inside the server (NotADirectoryError
    with the full path). The client sees a problem with an incident reference; the log has the rest."""
    data = Path(keyed.args[keyed.args.index("--data") + 1])
    tmp_dir = data / "blobs" / "tmp"
    assert tmp_dir.is_dir()
    moved = tmp_dir.with_name("tmp.moved")
    tmp_dir.rename(moved)
    tmp_dir.write_bytes(b"not a directory")
    try:
        r = httpx.post(f"{keyed.url}/envmaps", content=exr_bytes(make_envmap(16, seed=2), tmp_path),
                       headers={"X-API-Key": API_KEY}, timeout=60)
    finally:
        tmp_dir.unlink()
        moved.rename(tmp_dir)
    assert r.status_code >= 500, r.text
    body = r.json()
    assert r.headers["content-type"].startswith("application/problem+json")
    text = r.text
    assert str(data) not in text and "/tmp" not in text and "Traceback" not in text, text
    assert "NotADirectory" not in text and "Errno" not in text and "Error" not in body["detail"], text
    assert re.fullmatch(r"[0-9a-f]{12}", body["incident"])
    assert body["incident"] in keyed.output()  # the log line the reference points to
    ok = httpx.post(f"{keyed.url}/envmaps", content=exr_bytes(make_envmap(16, seed=2), tmp_path),
                    headers={"X-API-Key": API_KEY}, timeout=60)
    assert ok.status_code in (200, 201), ok.text
