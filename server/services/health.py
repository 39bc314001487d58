"""The health probes behind ``GET /health``, run in the background so that the route itself does no work.

``/health`` must answer within 100 ms under any load (issue 12, item 1). Probing on the request's path could not:
the database ping waits for a thread, the scheduler probe is an RPC whose answer is handled by the same event loop
that is busy with the load (the embedded scheduler lives on it), and ``statvfs`` on a stalled disk blocks. So a
background task (:class:`HealthMonitor`) probes every ``interval_s`` seconds, the three probes at once, each under a
time limit and off the event loop (the database ping and the disk probe each on a thread of its own), and the route
answers from the last snapshot. A snapshot older than :data:`STALE_FACTOR` intervals (the monitor itself stuck) is
reported as a problem, so a hung probe still shows as ``degraded``.

The answer itself is rendered once per probe round (:meth:`HealthMonitor.body`: the ``Health`` JSON as bytes) and
served by :class:`HealthEndpoint`, a pure ASGI middleware that answers ``GET /health`` before FastAPI's routing,
dependency injection and response-model validation: on the request path there is one clock read and one
comparison (O(1), no database, cluster or disk round trip, no pydantic work). ``bench/health.py`` measures it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import shutil
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Final, TypeVar

import relight
from relight.contract.models import Health
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database
from relight.worker.blobs import BlobStore

log = logging.getLogger("relight.server")
T = TypeVar("T")

#: Seconds each probe (database, scheduler, disk) may take before it counts as failed.
PROBE_TIMEOUT_S: Final = 2.0
#: A snapshot older than this many intervals plus the probe time limit means the monitor is stuck.
STALE_FACTOR: Final = 5


#: Header lines of every ``/health`` answer (the body is the ``Health`` JSON; it changes every probe round).
_HEADERS: Final = [(b"content-type", b"application/json"), (b"cache-control", b"no-store")]


@dataclass(frozen=True)
class Snapshot:
    """The result of one round of probes."""

    workers: int
    problems: tuple[str, ...]
    probed_at: datetime
    monotonic: float = field(repr=False)


class HealthMonitor:
    """Probes the database, the scheduler and the blob store's disk every ``interval_s`` seconds (module docstring)."""

    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self.cluster = cluster
        self.interval_s = settings.health_interval_s
        #: The probes' own threads (one each: a hung database cannot hold up the disk probe, and a flood of
        #: requests holding the shared thread pool cannot delay either).
        self._db_thread = ThreadPoolExecutor(1, thread_name_prefix="relight-health-db")
        self._disk_thread = ThreadPoolExecutor(1, thread_name_prefix="relight-health-disk")
        self._task: asyncio.Task[None] | None = None
        self.snapshot: Snapshot | None = None
        #: (snapshot, stale, rendered body) of the last :meth:`body`; rendered again only when either changes.
        self._rendered: tuple[Snapshot | None, bool, bytes] | None = None

    async def start(self) -> None:
        """Probe once (the first answer is never empty), then keep probing in the background."""
        self.snapshot = await self.probe()
        self._task = asyncio.create_task(self._loop(), name="relight-health")

    async def _loop(self) -> None:
        while True:
            await asyncio.sleep(self.interval_s)
            try:
                self.snapshot = await self.probe()
            except asyncio.CancelledError:
                raise
            except Exception:  # noqa: BLE001 - a probe round must never end the monitor
                log.exception("health probe round failed")

    def _ping(self) -> None:
        from sqlalchemy import text

        with self.db.session() as s:
            s.execute(text("SELECT 1"))

    def _free_bytes(self) -> int:
        return shutil.disk_usage(self.store.root).free

    @staticmethod
    async def _in_thread(pool: ThreadPoolExecutor, fn: Callable[[], T]) -> T:
        loop = asyncio.get_running_loop()
        return await asyncio.wait_for(loop.run_in_executor(pool, fn), PROBE_TIMEOUT_S)

    async def _database(self) -> list[str]:
        try:
            await self._in_thread(self._db_thread, self._ping)
        except Exception as exc:  # noqa: BLE001 - any failure of the probe is a degraded database
            return [f"database: not answering ({type(exc).__name__})"]
        return []

    async def _scheduler(self) -> tuple[int, list[str]]:
        try:
            workers = await asyncio.wait_for(self.cluster.n_workers(), PROBE_TIMEOUT_S)
        except Exception as exc:  # noqa: BLE001 - any failure of the probe means the scheduler is unreachable
            return 0, [f"scheduler: lost ({type(exc).__name__})"]
        return workers, [] if workers else ["workers: none connected"]

    async def _disk(self) -> list[str]:
        try:
            free = await self._in_thread(self._disk_thread, self._free_bytes)
        except Exception as exc:  # noqa: BLE001 - a disk that cannot be asked is a degraded disk
            return [f"disk: the blob store's disk does not answer ({type(exc).__name__})"]
        if free < self.settings.min_free_bytes:
            return [f"disk: {free} bytes free in the blob store, below {self.settings.min_free_bytes}"]
        return []

    async def probe(self) -> Snapshot:
        """One round of the three probes, run at once, each under :data:`PROBE_TIMEOUT_S`."""
        database, (workers, scheduler), disk = await asyncio.gather(self._database(), self._scheduler(),
                                                                    self._disk())
        return Snapshot(workers, (*database, *scheduler, *disk), datetime.now(UTC), time.monotonic())

    def health(self) -> Health:
        """The ``GET /health`` answer from the last snapshot (no probing)."""
        snap, problems = self.current()
        return Health(status="degraded" if problems else "ok", version=relight.__version__,
                      algorithm_version=relight.ALGORITHM_VERSION,
                      scheduler="external" if self.settings.scheduler else "embedded", workers=snap.workers,
                      database=self.db.dialect, problems=problems, probed_at=snap.probed_at)

    def body(self) -> bytes:
        """:meth:`health` as JSON bytes, rendered once per snapshot (and once more when it turns stale)."""
        snap = self.snapshot
        stale = snap is None or time.monotonic() - snap.monotonic > STALE_FACTOR * self.interval_s + PROBE_TIMEOUT_S
        rendered = self._rendered
        if rendered is None or rendered[0] is not snap or rendered[1] != stale or snap is None:
            rendered = (snap, stale, self.health().model_dump_json().encode())
            self._rendered = rendered
        return rendered[2]

    def current(self) -> tuple[Snapshot, list[str]]:
        """The last snapshot and its problems, plus one when it is stale (no work: called on the event loop)."""
        snap = self.snapshot
        if snap is None:
            return Snapshot(0, (), datetime.now(UTC), time.monotonic()), ["health: not probed yet"]
        problems = list(snap.problems)
        age = time.monotonic() - snap.monotonic
        if age > STALE_FACTOR * self.interval_s + PROBE_TIMEOUT_S:
            problems.append(f"health: the probes last finished {age:.0f} s ago")
        return snap, problems

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        self._db_thread.shutdown(wait=False)
        self._disk_thread.shutdown(wait=False)


class HealthEndpoint:
    """Pure ASGI middleware: ``GET``/``HEAD /health`` answered with :meth:`HealthMonitor.body` of the running
    services (``app.state.services.health``), everything else passed on (module docstring). Added inside CORS, so
    its answers carry the CORS headers as any route's."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope["path"] != "/health" or scope["method"] not in ("GET", "HEAD"):
            await self.app(scope, receive, send)
            return
        services = getattr(scope["app"].state, "services", None)
        if services is None:  # not started (or stopped): the route answers
            await self.app(scope, receive, send)
            return
        body = services.health.body()
        await send({"type": "http.response.start", "status": 200,
                    "headers": [*_HEADERS, (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": b"" if scope["method"] == "HEAD" else body})


__all__ = ["HealthEndpoint", "HealthMonitor", "Snapshot"]
