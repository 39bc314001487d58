"""``/health``'s probes (``relight.server.services.health``, issue 12 item 1): they run in the background, each under
a time limit, and the route only reads their last round. A real SQLite database and blob store directory; the
scheduler is a stand-in whose RPC never answers, the way a lost scheduler behaves, and one database ping is made to
hang. Timing goals (``/health`` within 100 ms under load) are measured by ``bench/load.py``, not asserted here."""

from __future__ import annotations

import asyncio
import dataclasses
import threading
import time
from pathlib import Path

import httpx
import pytest

from relight.server.config import Settings
from relight.server.db import Database
from relight.server.services.health import PROBE_TIMEOUT_S, STALE_FACTOR, HealthMonitor
from relight.worker.blobs import BlobStore

from .support import Server

pytestmark = pytest.mark.timeout(120)


class SilentScheduler:
    """A cluster whose scheduler RPC never returns (a scheduler that is gone without closing the connection)."""

    async def n_workers(self) -> int:
        await asyncio.Event().wait()
        return 0


class TwoWorkers:
    async def n_workers(self) -> int:
        return 2


def monitor(tmp_path: Path, cluster: object, **settings: object) -> HealthMonitor:
    s = Settings(data_dir=tmp_path, **settings)  # type: ignore[arg-type]
    db = Database(f"sqlite:///{tmp_path / 'h.db'}")
    db.create_all()
    return HealthMonitor(s, db, BlobStore(tmp_path / "blobs"), cluster)  # type: ignore[arg-type]


def test_hung_probes_time_out_and_the_answer_never_waits_for_them(tmp_path: Path) -> None:
    async def run() -> None:
        m = monitor(tmp_path, SilentScheduler(), health_interval_s=0.2)
        release = threading.Event()
        m._ping = lambda: release.wait(30)  # type: ignore[method-assign]  # noqa: SLF001 - the database hangs
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        await m.start()  # the first round: both probes time out, neither hangs the start
        assert loop.time() - t0 < 2 * PROBE_TIMEOUT_S  # the probes run at once, each under its limit
        snap, problems = m.current()
        assert snap.workers == 0
        assert "database: not answering (TimeoutError)" in problems
        assert "scheduler: lost (TimeoutError)" in problems
        assert not any(p.startswith("disk:") for p in problems)  # the disk answered (min_free_bytes 256 MiB)
        release.set()
        await m.close()

    asyncio.run(run())


def test_a_stuck_monitor_is_reported_and_a_healthy_one_refreshes(tmp_path: Path) -> None:
    async def run() -> None:
        m = monitor(tmp_path, TwoWorkers(), health_interval_s=0.05, min_free_bytes=0)
        await m.start()
        first, problems = m.current()
        assert (first.workers, problems) == (2, [])
        await asyncio.sleep(0.5)
        later, problems = m.current()
        assert later.probed_at > first.probed_at and problems == []  # refreshed in the background
        await m.close()
        # no round for longer than STALE_FACTOR intervals + the probe limit: the answer says so
        age = STALE_FACTOR * m.interval_s + PROBE_TIMEOUT_S + 1.0
        m.snapshot = dataclasses.replace(later, monotonic=time.monotonic() - age)
        _, problems = m.current()
        assert len(problems) == 1 and problems[0].startswith("health: the probes last finished"), problems

    asyncio.run(run())


def test_health_names_when_it_was_probed(server: Server) -> None:
    with httpx.Client(base_url=server.url, timeout=30) as http:
        first = http.get("/health").json()
        assert first["status"] == "ok" and first["probed_at"]
