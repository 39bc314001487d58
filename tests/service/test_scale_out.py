"""Scale-out: a separately started ``relight scheduler``, two ``relight worker`` processes, and a server pointed at
them with ``RELIGHT_SCHEDULER``, all on mutual TLS with a certificate from ``relight tls init``
(:mod:`relight.worker.tls`); the end-to-end path is the same. This server also has API keys and CORS on.

Issue 12, item 7 for the scale-out cluster: every port the scheduler, the workers and their nannies listen on
speaks only TLS with the cluster's certificate (a plain TCP client and a client with a foreign certificate are
refused; so is a worker with a foreign certificate), and none answers HTTP.
"""

from __future__ import annotations

import hashlib
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import psutil
import pytest
from distributed import Client

from relight.client.errors import ApiError
from relight.contract.models import JobState

from .postgres import Backend
from .support import Proc, Server, assert_problem, base_env, library_map, read_exr, start_server, wait_until
from .test_reliability_security import http_answer

pytestmark = pytest.mark.timeout(240)
API_KEY = "test-key-7f3a9c"
ORIGIN = "https://viewer.example"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def tls_init(directory: Path) -> dict[str, str]:
    """``relight tls init DIR`` as an operator runs it; the three RELIGHT_TLS_* variables it prints."""
    out = subprocess.run([sys.executable, "-m", "relight.cli", "tls", "init", str(directory)], env=base_env(),
                         capture_output=True, text=True, timeout=120, check=True).stdout
    return dict(line.split("=", 1) for line in out.splitlines() if line.startswith("RELIGHT_TLS_"))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[tuple[Server, list[Proc]]]:
    tmp = tmp_path_factory.mktemp("scale-out")
    port = free_port()
    address = f"tls://127.0.0.1:{port}"
    tls = tls_init(tmp / "certs")  # the workers take the files from the environment, the scheduler from flags
    procs: list[Proc] = []
    try:
        sched = Proc([sys.executable, "-m", "relight.cli", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                      "--tls-ca-file", tls["RELIGHT_TLS_CA_FILE"], "--tls-cert", tls["RELIGHT_TLS_CERT"],
                      "--tls-key", tls["RELIGHT_TLS_KEY"]], base_env(), tmp / "scheduler.log").start()
        procs.append(sched)
        wait_until(lambda: f"relight: scheduler at {address}" in sched.output(), 60, "the scheduler to start")
        for i in range(2):
            procs.append(Proc([sys.executable, "-m", "relight.cli", "worker", "--scheduler", address, "--name",
                               f"relight-w{i}", "--host", "127.0.0.1", "--memory-limit", "2GiB"], base_env(tls),
                              tmp / f"worker{i}.log").start())
        server = start_server(tmp / "server", {
            **tls,
            "RELIGHT_SCHEDULER": address,
            "RELIGHT_API_KEY_HASHES": hashlib.sha256(API_KEY.encode()).hexdigest(),
            "RELIGHT_CORS_ORIGINS": ORIGIN,
            "RELIGHT_MAX_UPLOAD_BYTES": str(64 << 20),  # room for a MERL file (35 MB)
        }, database=database)
        procs.append(server)
        with server.client(api_key=API_KEY) as c:
            wait_until(lambda: c.health().workers == 2, 60, "both workers to join the scheduler", interval=0.2)
        yield server, procs
    finally:
        for p in reversed(procs):
            p.stop()


def test_end_to_end_on_external_cluster(cluster: tuple[Server, list[Proc]], sample_exr: bytes) -> None:
    server, _ = cluster
    with server.client(api_key=API_KEY) as c:
        assert c.health().scheduler == "external"  # the address is never published
        env = c.upload_envmap(sample_exr)
        plan = c.plan(env.id, {"kind": "phong", "s": 32}, epsilon=0.01)
        job = c.submit(env.id, {"kind": "phong", "s": 32}, epsilon=0.01)
        assert job.id == plan.job_id
        stages = [u.stage for u in c.events(job.id, timeout=60)]
        final = c.get_job(job.id)
        assert final.state == JobState.succeeded, final
        assert final.worker is not None and final.worker.startswith("tls://127.0.0.1:")
        assert "done" in stages
        got = read_exr(c.download(job.id))[""]
        expected = library_map(sample_exr, "phong:s=32", epsilon=0.01)
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))


def test_api_keys_and_cors(cluster: tuple[Server, list[Proc]]) -> None:
    server, _ = cluster
    with httpx.Client(base_url=server.url, timeout=30) as http:
        assert http.get("/health").status_code == 200  # health and metrics stay open
        r = http.get("/jobs")
        assert_problem(r, 401, "API key")
        assert r.headers["www-authenticate"].startswith("Bearer")
        assert_problem(http.get("/jobs", headers={"Authorization": "Bearer wrong"}), 401, "not valid")
        assert http.get("/jobs", headers={"X-API-Key": API_KEY}).status_code == 200
        pre = http.options("/jobs", headers={"Origin": ORIGIN, "Access-Control-Request-Method": "GET"})
        assert pre.headers.get("access-control-allow-origin") == ORIGIN
        other = http.options("/jobs", headers={"Origin": "https://evil.example",
                                               "Access-Control-Request-Method": "GET"})
        assert "access-control-allow-origin" not in other.headers
    with server.client(api_key="wrong") as c, pytest.raises(ApiError) as info:
        c.list_jobs()
    assert info.value.status == 401


def test_measured_merl_brdf(cluster: tuple[Server, list[Proc]], sample_exr: bytes, tmp_path: Path) -> None:
    """A MERL file uploaded to the service becomes a BRDF id usable in jobs; no server path leaks out."""
    from relight.brdf.measured import MERL_DIMS, write_merl

    merl = tmp_path / "grey.binary"
    write_merl(merl, np.full((*MERL_DIMS, 3), 0.5 / np.pi))  # a Lambertian-like measured BRDF
    server, _ = cluster
    with server.client(api_key=API_KEY) as c:
        brdf = c.upload_measured_brdf(merl)
        assert brdf.measured and brdf.kind == "merl" and set(brdf.spec) == {"kind", "sha256"}
        assert c.upload_measured_brdf(merl).id == brdf.id
        env = c.upload_envmap(sample_exr)
        plan = c.plan(env.id, brdf.id, order=4, p_order=1, size=16)
        assert plan.representation == "shrm"
        job = c.wait(c.submit(env.id, brdf.id, order=4, p_order=1, size=16).id, timeout=180)
        assert job.state == JobState.succeeded
        manifest = c.get_shrm(job.id).model_dump_json()
        assert str(server.args[server.args.index("--data") + 1]) not in manifest and '"path"' not in manifest


def test_cors_on_real_responses(cluster: tuple[Server, list[Proc]], sample_exr: bytes) -> None:
    """CORS headers on real answers, not only on preflights: a 200 with its ETag exposed, a 201 with Location, the
    401 and 404 problems (the browser must be able to read why), and never for another origin."""
    server, _ = cluster
    key = {"X-API-Key": API_KEY}
    with httpx.Client(base_url=server.url, timeout=60) as http:
        up = http.post("/envmaps", content=sample_exr, headers={**key, "Origin": ORIGIN})
        assert up.status_code in (200, 201) and up.headers["access-control-allow-origin"] == ORIGIN
        env_id = up.json()["id"]
        got = http.get(f"/envmaps/{env_id}/preview.png", headers={**key, "Origin": ORIGIN})
        assert got.status_code == 200 and got.headers.get("etag")
        exposed = {h.strip().lower() for h in got.headers["access-control-expose-headers"].split(",")}
        assert {"etag", "location", "retry-after"} <= exposed
        for resp in (http.get("/jobs", headers={"Origin": ORIGIN}),  # no key: 401
                     http.get(f"/jobs/{'0' * 64}", headers={**key, "Origin": ORIGIN})):  # 404
            assert resp.status_code in (401, 404) and resp.headers["access-control-allow-origin"] == ORIGIN
        other = http.get("/jobs", headers={**key, "Origin": "https://evil.example"})
        assert other.status_code == 200 and "access-control-allow-origin" not in other.headers


def test_the_external_cluster_speaks_only_tls_and_no_http(cluster: tuple[Server, list[Proc]],
                                                          tmp_path: Path) -> None:
    """Every port of the scheduler, the workers and their nannies: no HTTP answer, a plain TCP client and a client
    with a foreign certificate refused (the server's client, with the cluster's certificate, is what the other
    tests use); a worker with a foreign certificate never joins."""
    server, procs = cluster
    sched, workers = procs[0], procs[1:3]
    ports: set[int] = set()
    for proc in (sched, *workers):
        for p in (psutil.Process(proc.pid), *psutil.Process(proc.pid).children(recursive=True)):
            ports |= {c.laddr.port for c in p.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN}
    assert len(ports) == 5, ports  # the scheduler, and a nanny and a worker each: no HTTP server left listening
    foreign = tls_init(tmp_path / "foreign")  # another self-signed cluster certificate: another CA
    from relight.worker.tls import TlsFiles

    bad = TlsFiles.of(*foreign.values())
    assert bad is not None
    for port in sorted(ports):
        assert not http_answer(port).startswith(b"HTTP/"), f"port {port} answers HTTP"
        with pytest.raises((OSError, TimeoutError)):  # plain TCP: the TLS server hangs up
            Client(f"tcp://127.0.0.1:{port}", timeout=3, set_as_default=False).close()
    with pytest.raises((OSError, TimeoutError)):  # TLS with a certificate the cluster's CA did not sign
        Client(sched_address(sched), timeout=3, set_as_default=False, security=bad.security()).close()
    intruder = Proc([sys.executable, "-m", "relight.cli", "worker", "--scheduler", sched_address(sched), "--name",
                     "intruder", "--host", "127.0.0.1", "--no-nanny"], base_env(foreign),
                    tmp_path / "intruder.log").start()
    handshakes = "TLS handshake failed with remote"
    failed_before = sched.output().count(handshakes)
    try:  # the scheduler refuses each of its attempts (unknown CA); it keeps retrying, never connected
        wait_until(lambda: sched.output().count(handshakes) >= failed_before + 3, 60,
                   "the scheduler to refuse the intruder's handshakes")
        assert "UNKNOWN_CA" in sched.output().split(handshakes, failed_before + 1)[-1]
        with server.client(api_key=API_KEY) as c:
            assert c.health().workers == 2
        assert "connected to" not in intruder.output()
    finally:
        intruder.stop()


def sched_address(sched: Proc) -> str:
    line = next(ln for ln in sched.output().splitlines() if "relight: scheduler at" in ln)
    return line.rsplit(" ", 1)[1]
