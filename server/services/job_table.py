"""The job table: every read and write of the one ``jobs`` table (:class:`relight.server.db.Job`) for
:class:`relight.server.services.jobs.JobService`.

Writes go through a single writer thread (:meth:`JobTable.write`), so they apply in the order they were issued;
the active-job cap is checked inside the writer's transaction, atomic with the insert or re-queue it guards.
Every state change only touches an *active* row (``queued`` or ``running``): a cancelled job never takes a result,
and a superseded submission never overwrites its successor's.

**Claims.** Several server processes may share one database (scale-out). A job is computed by the one process that
holds its claim: ``owner`` (:attr:`JobTable.instance`) and ``lease_until``. The claim is taken by one conditional
``UPDATE`` (:meth:`JobTable.claim`: the row must be active and unclaimed, claimed by this process, or its lease
lapsed); both SQLite (one writer at a time) and PostgreSQL (the ``UPDATE`` re-checks its condition on the row it
waited for) let exactly one of two concurrent claims match. The owner renews its leases every quarter of
``job_lease_s``; a process that finds a lapsed lease (its owner died) claims the job and submits it again. Only the
owner may count a submission (:meth:`JobTable.mark_submitted`), so a job is submitted once however many servers
are asked for it. The servers' clocks must agree to well within ``job_lease_s``.
"""

from __future__ import annotations

import asyncio
import os
import socket
import uuid
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime, timedelta
from typing import Any, Final, TypeVar

from sqlalchemy import ColumnElement, func, or_, select, update

from relight.contract.models import ACTIVE_STATES, JobState
from relight.server.config import Settings
from relight.server.db import Database, Job, utcnow
from relight.server.problems import NotFound, TooManyJobs
from relight.server.services.base import in_thread
from relight.server.services.kinds import kind_of

T = TypeVar("T")

ACTIVE: Final = tuple(s.value for s in ACTIVE_STATES)
#: Seconds a client is asked to wait after a 429 (the shortest jobs take about this long).
RETRY_AFTER_S: Final = 5


class JobTable:
    def __init__(self, settings: Settings, db: Database) -> None:
        self.settings = settings
        self.db = db
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="relight-db-writer")
        #: This server process's name in the ``owner`` column (host, pid and a random part: pids are reused).
        self.instance = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"

    async def write(self, fn: Callable[..., T], *args: Any) -> T:
        """Run ``fn`` on the single writer thread (every job-table write goes through here)."""
        return await asyncio.get_running_loop().run_in_executor(self._writer, fn, *args)

    def close_writer(self) -> None:
        self._writer.shutdown(wait=True)

    # ------------------------------------------------------------------------------------------------ reads
    def _row(self, job_id: str) -> Job | None:
        with self.db.session() as s:
            return s.get(Job, job_id)

    async def find(self, job_id: str) -> Job | None:
        return await in_thread(self._row, job_id)

    async def row(self, job_id: str, kind: str | None = None) -> Job:
        """The job's row (404 when there is none, or when it is of another kind than ``kind``)."""
        row = await in_thread(self._row, job_id)
        if row is None or (kind is not None and row.kind != kind):
            raise NotFound(f"no {kind or 'job'} with id {job_id!r}")
        return row

    async def rows(self, state: JobState | None, limit: int, kind: str | None = None) -> list[Job]:
        """The newest ``limit`` rows, of one state and one kind when given."""

        def q() -> list[Job]:
            with self.db.session() as s:
                stmt = select(Job).order_by(Job.created_at.desc()).limit(limit)
                if state is not None:
                    stmt = stmt.where(Job.state == state.value)
                if kind is not None:
                    stmt = stmt.where(Job.kind == kind)
                return list(s.scalars(stmt))

        return await in_thread(q)

    async def counts(self) -> dict[str, int]:
        def q() -> dict[str, int]:
            with self.db.session() as s:
                return {st: n for st, n in s.execute(select(Job.state, func.count()).group_by(Job.state))}

        return await in_thread(q)

    # ------------------------------------------------------------------------------------------------ claims
    def lease(self) -> datetime:
        """Until when a claim taken or renewed now holds."""
        return utcnow() + timedelta(seconds=self.settings.job_lease_s)

    def _claimable(self) -> ColumnElement[bool]:
        """Active, and unclaimed, claimed by this process, or with its lease lapsed."""
        return Job.state.in_(ACTIVE) & or_(Job.owner.is_(None), Job.owner == self.instance, Job.lease_until.is_(None),
                                           Job.lease_until < utcnow())

    async def claim(self, job_id: str) -> Job | None:
        """Claim the job for this process when it is claimable (module docstring); the row afterwards (``None``: no
        such job). Claimed when ``row.owner == self.instance`` and the row is active."""

        def do() -> Job | None:
            with self.db.session() as s:
                s.execute(update(Job).where(Job.id == job_id, self._claimable()).values(
                    owner=self.instance, lease_until=self.lease()))
                return s.get(Job, job_id)

        return await self.write(do)

    def _renew(self, job_ids: list[str]) -> set[str]:
        with self.db.session() as s:
            s.execute(update(Job).where(Job.id.in_(job_ids), Job.owner == self.instance, Job.state.in_(ACTIVE))
                      .values(lease_until=self.lease()))
            return set(s.scalars(select(Job.id).where(Job.id.in_(job_ids), Job.owner == self.instance,
                                                      Job.state.in_(ACTIVE))))

    async def renew(self, job_ids: list[str]) -> set[str]:
        """Renew this process's claims on ``job_ids``; those still active and claimed by it (the others were
        cancelled, finished, or taken over by another server after a lapse)."""
        if not job_ids:
            return set()
        return await in_thread(self._renew, job_ids)  # not the writer: a long write queue must not lapse a lease

    async def claimable(self) -> list[str]:
        """Active jobs nobody holds a live claim on (their server died, or released them when stopping)."""

        def q() -> list[str]:
            with self.db.session() as s:
                return list(s.scalars(select(Job.id).where(self._claimable())))

        return await in_thread(q)

    async def release(self) -> int:
        """Give up every claim of this process (a clean shutdown: another server resumes the jobs at once)."""

        def do() -> int:
            with self.db.session() as s:
                res = s.execute(update(Job).where(Job.owner == self.instance, Job.state.in_(ACTIVE)).values(
                    owner=None, lease_until=None))
                return int(getattr(res, "rowcount", 0) or 0)

        return await self.write(do)

    # ------------------------------------------------------------------------------------------------ submit
    def _too_many(self, s: Any) -> None:
        """Raise 429 when the active-job cap is reached (inside the writer's transaction: atomic with the insert)."""
        active = s.scalar(select(func.count()).select_from(Job).where(Job.state.in_(ACTIVE))) or 0
        cap = self.settings.max_active_jobs
        if active >= cap:
            raise TooManyJobs(f"{active} jobs are queued or running (limit {cap}); try again later",
                              headers={"Retry-After": str(RETRY_AFTER_S)})

    def _insert(self, new: Job) -> tuple[Job, bool]:
        from sqlalchemy.exc import IntegrityError

        try:
            with self.db.session() as s:
                found = s.get(Job, new.id)
                if found is not None:
                    return found, False
                self._too_many(s)
                s.add(new)
            return new, True
        except IntegrityError:  # another server process inserted it first
            row = self._row(new.id)
            if row is None:
                raise
            return row, False

    async def insert(self, new: Job) -> tuple[Job, bool]:
        """Insert ``new`` under the cap; ``(row, created)``, the existing row when one has its id."""
        return await self.write(self._insert, new)

    async def requeue_row(self, job_id: str, stage: str, *, from_states: tuple[str, ...], capped: bool) -> bool:
        """Queue a finished job in one of ``from_states`` again (under the cap when ``capped``); whether it was."""

        def do() -> int:
            with self.db.session() as s:
                if capped:
                    self._too_many(s)
                res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(from_states)).values(
                    state=JobState.queued.value, stage=stage, progress=0.0, failure_reason=None, retryable=0,
                    result=None, result_sha256=None, finished_at=None, worker=None, owner=self.instance,
                    lease_until=self.lease()))
                return int(getattr(res, "rowcount", 0) or 0)

        return bool(await self.write(do))

    async def mark_submitted(self, job_id: str) -> Job | None:
        """Count one more submission of an active job claimed by this process (``None`` when it is no longer
        active or no longer this process's)."""

        def do() -> Job | None:
            with self.db.session() as s:
                row = s.get(Job, job_id)
                if row is None or row.state not in ACTIVE or row.owner != self.instance:
                    return None
                row.submissions += 1
                row.state = JobState.queued.value
                row.submitted_at = utcnow()
                return row

        return await self.write(do)

    # ------------------------------------------------------------------------------------------------ outcomes
    async def store_success(self, job_id: str, submission: int, result: dict[str, Any]) -> Job | None:
        """Store the kind's result of submission ``submission`` (``None``: cancelled or superseded meanwhile)."""

        def do() -> Job | None:
            with self.db.session() as s:
                row = s.get(Job, job_id)
                if row is None or row.state not in ACTIVE or row.submissions != submission:
                    return None  # cancelled (or superseded) meanwhile: the result is not stored
                kind_of(row.kind).store_result(row, result)
                row.state, row.stage, row.progress = JobState.succeeded.value, "done", 1.0
                row.finished_at = utcnow()
                row.runs = max(row.runs, 1)
                row.failure_reason = None
                return row

        return await self.write(do)

    async def store_failure(self, job_id: str, submission: int, reason: str, retryable: bool) -> Job | None:
        def do() -> Job | None:
            with self.db.session() as s:
                row = s.get(Job, job_id)
                if row is None or row.state not in ACTIVE or row.submissions != submission:
                    return None
                row.state, row.stage = JobState.failed.value, "failed"
                row.failure_reason = reason
                row.retryable = int(retryable)
                row.finished_at = utcnow()
                return row

        return await self.write(do)

    async def mark_cancelled(self, job_id: str) -> bool:
        """Mark an active job cancelled; whether it was active."""

        def do() -> int:
            with self.db.session() as s:
                res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                    state=JobState.cancelled.value, stage="cancelled", finished_at=utcnow(),
                    failure_reason="cancelled by request"))
                return int(getattr(res, "rowcount", 0) or 0)

        return bool(await self.write(do))

    # ------------------------------------------------------------------------------------------------ progress
    async def mark_running(self, job_id: str, worker: Any) -> None:
        def do() -> None:
            with self.db.session() as s:
                s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                    state=JobState.running.value, stage="started", worker=worker, runs=Job.runs + 1,
                    started_at=utcnow()))

        await self.write(do)

    async def store_progress(self, job_id: str, stage: str, fraction: float) -> None:
        def do() -> None:
            with self.db.session() as s:
                s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                    stage=stage, progress=fraction))

        await self.write(do)

    # ------------------------------------------------------------------------------------------------ recovery
    async def requeue_active(self) -> list[str]:
        """Every job left queued or running by a server process that holds no live claim on it any more (this
        one's predecessor, stopped or killed), queued again; their ids. Jobs another live server computes are left
        to it."""

        def do() -> list[str]:
            with self.db.session() as s:
                ids = list(s.scalars(select(Job.id).where(self._claimable())))
                if ids:
                    s.execute(update(Job).where(Job.id.in_(ids), self._claimable()).values(
                        state=JobState.queued.value, stage="resubmitted after a restart", worker=None))
                return ids

        return await self.write(do)


__all__ = ["ACTIVE", "RETRY_AFTER_S", "JobTable"]
