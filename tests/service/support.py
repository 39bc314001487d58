"""Helpers for the service tests: server and worker subprocesses, test images, problem-body assertions.

Servers run as subprocesses in their own process group, so a test can kill one (and its workers) outright.
Every wait is bounded; nothing sleeps longer than a poll interval.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx
import numpy as np
from httpx_sse import connect_sse

from relight.client.sdk import RelightClient

if TYPE_CHECKING:
    from .postgres import Backend

REPO = Path(__file__).resolve().parents[2]
URL_LINE = re.compile(r"relight: serving (http://\S+)")
START_TIMEOUT_S = 90.0

#: Limits of the test servers: small, so "too large" inputs stay small too.
TEST_ENV = {
    "RELIGHT_MAX_UPLOAD_BYTES": str(1 << 20),
    "RELIGHT_MAX_PIXELS": str(512 * 1024),
    "RELIGHT_WORKER_MEMORY_LIMIT": "2GiB",
    "RELIGHT_N_WORKERS": "2",
    "RELIGHT_THREADS": "1",
    "RELIGHT_LOG_LEVEL": "warning",
    # A killed server's jobs are taken over once its claims lapse: 10 s instead of 30 keeps restart tests short,
    # and is still 4 renewals (every 2.5 s) long, so a loaded machine does not lapse a live server's claim.
    "RELIGHT_JOB_LEASE_S": "10",
}


def base_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("RELIGHT_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    env.update(TEST_ENV)
    env.update(extra or {})
    return env


def wait_until(predicate: Callable[[], Any], timeout: float, what: str, interval: float = 0.05) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(interval)


@dataclass
class Proc:
    """A subprocess in its own session (process group), its log file, and how to stop it."""

    args: list[str]
    env: dict[str, str]
    log: Path
    proc: subprocess.Popen[bytes] | None = None
    _fh: Any = field(default=None, repr=False)

    def start(self) -> Proc:
        self._fh = open(self.log, "ab")
        self.proc = subprocess.Popen(self.args, env=self.env, stdout=self._fh, stderr=subprocess.STDOUT,
                                     cwd=REPO, start_new_session=True)
        return self

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def dump_stacks(self) -> None:
        """Ask a running server to write its threads' and asyncio tasks' stacks into its log
        (:mod:`relight.server.run`: SIGUSR1, SIGUSR2), for a test that found it hanging."""
        if not self.alive():
            return
        for sig in (signal.SIGUSR1, signal.SIGUSR2):
            os.kill(self.pid, sig)
            time.sleep(1.0)

    def kill(self) -> None:
        """SIGKILL the whole process group (the server and the worker processes it spawned)."""
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait(timeout=30)
        self._close()

    def stop(self, timeout: float = 20.0) -> None:
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                pass
        try:  # stragglers in the group (worker processes), if any
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait(timeout=30)
        self._close()

    def _close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


@dataclass
class Server(Proc):
    url: str = ""

    def wait_ready(self, timeout: float = START_TIMEOUT_S) -> Server:
        def ready() -> str | None:
            if not self.alive():
                raise AssertionError(f"server exited early:\n{self.output()[-4000:]}")
            m = URL_LINE.search(self.output())
            return m.group(1) if m else None

        self.url = wait_until(ready, timeout, "the server to print its URL", interval=0.1)
        return self

    def client(self, **kw: Any) -> RelightClient:
        return RelightClient(self.url, timeout=60.0, **kw)


def start_server(data_dir: Path, extra_env: dict[str, str] | None = None, log_name: str = "server.log",
                 database: Backend | None = None) -> Server:
    """A server on ``data_dir``; on ``database`` when given (:class:`tests.service.postgres.Backend`: SQLite in the
    data directory, or the PostgreSQL database of this data directory), else SQLite."""
    data_dir.mkdir(parents=True, exist_ok=True)
    args = [sys.executable, "-m", "relight.cli", "serve", "--host", "127.0.0.1", "--port", "0", "--data",
            str(data_dir), "--no-preload"]
    env = {**(database.env_for(data_dir) if database is not None else {}), **(extra_env or {})}
    server = Server(args=args, env=base_env(env), log=data_dir / log_name)
    server.start()
    try:
        return server.wait_ready()
    except BaseException:
        server.stop()
        raise


# ------------------------------------------------------------------------------------------------ test data
def make_envmap(height: int = 64, seed: int = 0) -> np.ndarray:
    """A smooth sky with a small bright sun: (H, 2H, 3) float32, all positive."""
    rng = np.random.default_rng(seed)
    from relight.conventions import latlong_dirs

    d = latlong_dirs(height, 2 * height)
    sun = np.array([0.3, 0.8, 0.52])
    sun /= np.linalg.norm(sun)
    glow = np.exp(40.0 * (d @ sun - 1.0))
    sky = 0.5 + 0.4 * d[..., 1:2]
    img: np.ndarray = np.asarray(sky * np.array([0.6, 0.7, 1.0]) + 50.0 * glow[..., None] + 0.05 * rng.random(d.shape),
                                 dtype=np.float32)
    return img


def exr_bytes(img: np.ndarray, tmp: Path) -> bytes:
    from relight.envmap import write_exr

    p = tmp / f"img-{os.getpid()}-{time.monotonic_ns()}.exr"
    write_exr(p, img)
    data = p.read_bytes()
    p.unlink()
    return data


def hdr_bytes(img: np.ndarray, tmp: Path) -> bytes:
    from relight.envmap import write_hdr

    p = tmp / f"img-{os.getpid()}-{time.monotonic_ns()}.hdr"
    write_hdr(p, img)
    data = p.read_bytes()
    p.unlink()
    return data


def assert_problem(resp: httpx.Response, status: int, *fragments: str) -> dict[str, Any]:
    """An RFC 9457 problem body with this status whose detail mentions every fragment."""
    assert resp.status_code == status, f"expected {status}, got {resp.status_code}: {resp.text[:500]}"
    assert resp.headers["content-type"].startswith("application/problem+json"), resp.headers["content-type"]
    body: dict[str, Any] = resp.json()
    for key in ("type", "title", "status", "detail"):
        assert key in body, f"problem body lacks {key!r}: {body}"
    assert body["status"] == status
    for frag in fragments:
        assert frag.lower() in body["detail"].lower(), f"{frag!r} not in detail {body['detail']!r}"
    return body


def fresh_health(http: httpx.Client, timeout: float = 60.0) -> dict[str, Any]:
    """``/health`` from a probe round that began after this call: the probes run in the background (every
    ``RELIGHT_HEALTH_INTERVAL_S``), so the answer after an event may predate it; two new rounds seen means the second
    started after the first ended, which was after the call."""
    from datetime import UTC, datetime

    start = datetime.now(UTC)
    rounds: set[str] = set()

    def newer() -> dict[str, Any] | None:
        h: dict[str, Any] = http.get("/health").json()
        if datetime.fromisoformat(h["probed_at"]) > start:
            rounds.add(h["probed_at"])
        return h if len(rounds) >= 2 else None

    found: dict[str, Any] = wait_until(newer, timeout, "two health probe rounds", interval=0.1)
    return found


def assert_healthy(http: httpx.Client) -> None:
    r = http.get("/health")
    assert r.status_code == 200, r.text
    assert r.json()["workers"] >= 1


def library_map(exr: bytes, spec: str, **kw: Any) -> np.ndarray:
    """What a direct library call produces for these inputs (float32, as stored)."""
    from relight.brdf.base import RadialLobe
    from relight.brdf.spec import parse_brdf
    from relight.envmap import read_envmap
    from relight.prefilter import prefilter_radial

    lobe = parse_brdf(spec)
    assert isinstance(lobe, RadialLobe)
    return prefilter_radial(read_envmap(exr).pixels, lobe, **kw).map.astype(np.float32)


def read_exr(data: bytes) -> dict[str, np.ndarray]:
    from relight.envmap import read_exr_layers

    layers, _ = read_exr_layers(data)
    return layers


def wait_done(http: httpx.Client, path: str, timeout: float = 180.0) -> dict[str, Any]:
    """Follow the job's event stream to its end, then read the resource."""
    job_id = path.rsplit("/", 1)[1]
    with connect_sse(http, "GET", f"{path}/events", timeout=httpx.Timeout(timeout, connect=10.0)) as source:
        assert source.response.status_code == 200, source.response.read()
        last = [e for e in source.iter_sse()][-1]
    assert last.event == "end" and json.loads(last.data)["id"] == job_id, last
    body: dict[str, Any] = http.get(path).json()
    assert body["state"] == json.loads(last.data)["state"]
    return body
