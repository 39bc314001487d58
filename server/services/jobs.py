"""The one job system: every kind of job (:mod:`relight.server.services.kinds`) is submitted, watched, cancelled
and resumed here, on one table and under one active-job cap.

* **Identity.** A job's id is the SHA-256 of its kind's canonical request (with ``relight.ALGORITHM_VERSION``):
  identical requests share one job and one result.
* **Cap.** At most ``max_active_jobs`` jobs of all kinds together are queued or running. The count and the insert
  (or the re-queue of a cancelled or failed job) happen in one transaction on the single writer thread, so
  concurrent submissions cannot overshoot it; beyond it the answer is 429 with ``Retry-After``.
* **Submission.** One watcher task per active job submits ``relight.worker.progress.run_job`` with the kind's task
  and awaits it (:func:`relight.server.services.runner.run_with_resubmits`); a dict of watchers (mutated only on the
  event loop) guarantees one submission per job in this process, the primary key guarantees one row. A lost
  worker is Dask's business: it reschedules the task (``runs`` counts starts).
* **Progress.** Workers publish Dask events (:mod:`relight.worker.progress`); every event is fanned out to event
  streams at once, and stored at most every ``progress_interval_s`` (or on a stage change).
* **Cancellation.** ``DELETE`` marks the row ``cancelled`` and cancels the Dask future; the task stops at its next
  progress report, and a result that arrives anyway is not stored (only active rows take results).
* **Recovery.** At start-up jobs of every kind left ``queued`` or ``running`` are submitted again (at-least-once).

Job-table writes go through a single writer thread, so they apply in the order they were issued.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Final, TypeVar

from sqlalchemy import func, select, update

from relight.contract.models import ACTIVE_STATES, JobList, JobParams, JobPublic, JobState, Measurement, Prediction
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database, Job, utcnow
from relight.server.problems import Conflict, NotFound, TooManyJobs
from relight.server.services.base import aware, in_thread, utc
from relight.server.services.envmaps import EnvmapService
from relight.server.services.events import EventHub
from relight.server.services.kinds import JobKind, kind_of, links_of
from relight.server.services.metrics import Metrics
from relight.server.services.runner import failure_of, run_with_resubmits
from relight.worker.blobs import BlobStore
from relight.worker.progress import run_job

log = logging.getLogger("relight.server")
T = TypeVar("T")

ACTIVE: Final = tuple(s.value for s in ACTIVE_STATES)
#: Seconds a client is asked to wait after a 429 (the shortest jobs take about this long).
RETRY_AFTER_S: Final = 5


class JobService:
    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster, hub: EventHub,
                 metrics: Metrics, envmaps: EnvmapService) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self.cluster = cluster
        self.hub = hub
        self.metrics = metrics
        self.envmaps = envmaps
        self._watchers: dict[str, asyncio.Task[None]] = {}
        self._futures: dict[str, Any] = {}  # job id -> distributed.Future
        self._submission: dict[str, int] = {}
        self._snapshots: dict[str, JobPublic] = {}
        self._last_store: dict[str, tuple[float, str | None]] = {}
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="relight-db-writer")
        self._events: asyncio.Queue[Any] = asyncio.Queue()
        self._consumer: asyncio.Task[None] | None = None
        #: Awaited with the job id when a finished job is queued again (the kinds drop what they cached of it).
        self.on_requeue: list[Callable[[str], Awaitable[None]]] = []

    # ------------------------------------------------------------------------------------------------ plumbing
    async def write(self, fn: Callable[..., T], *args: Any) -> T:
        """Run ``fn`` on the single writer thread (every job-table write goes through here)."""
        return await asyncio.get_running_loop().run_in_executor(self._writer, fn, *args)

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

    def public(self, row: Job, *, cached: bool = False) -> JobPublic:
        req = row.request or {}
        links = {"self": f"/jobs/{row.id}", "events": f"/jobs/{row.id}/events"}
        if row.state == JobState.succeeded:
            links |= links_of(row.kind)(row.id, row.result)
        shrm = row.kind == "shrm"
        envmap = req.get("envmap") or (req.get("scene") or {}).get("environment")
        pub = JobPublic(
            id=row.id, kind=row.kind, state=JobState(row.state), stage=row.stage, progress=row.progress,
            envmap=envmap, brdf=req.get("brdf") if shrm else req.get("brdf_id"),
            brdf_spec=req.get("brdf_spec") if shrm else None,
            params=JobParams(**req["params"]) if shrm and req.get("params") is not None else None,
            request=req, predicted=Prediction(**row.predicted) if row.predicted else None,
            measured=Measurement(**row.measured) if row.measured else None,
            failure_reason=row.failure_reason, runs=row.runs, submissions=row.submissions, worker=row.worker,
            cached=cached, created_at=utc(row.created_at), started_at=aware(row.started_at),
            finished_at=aware(row.finished_at), links=links,
        )
        live = self._snapshots.get(row.id)
        if live is not None and pub.state in ACTIVE_STATES and live.state in ACTIVE_STATES:
            # the table is written at most every progress_interval_s; the live snapshot is newer
            pub = pub.model_copy(update={"state": live.state, "stage": live.stage, "progress": live.progress,
                                         "worker": live.worker or pub.worker, "runs": max(pub.runs, live.runs)})
        return pub

    async def get(self, job_id: str) -> JobPublic:
        return self.public(await self.row(job_id))

    async def list(self, state: JobState | None, limit: int, kind: str | None = None) -> JobList:
        def q() -> list[Job]:
            with self.db.session() as s:
                stmt = select(Job).order_by(Job.created_at.desc()).limit(limit)
                if state is not None:
                    stmt = stmt.where(Job.state == state.value)
                if kind is not None:
                    stmt = stmt.where(Job.kind == kind)
                return list(s.scalars(stmt))

        return JobList(items=[self.public(r) for r in await in_thread(q)])

    async def counts(self) -> dict[str, int]:
        def q() -> dict[str, int]:
            with self.db.session() as s:
                return {st: n for st, n in s.execute(select(Job.state, func.count()).group_by(Job.state))}

        return await in_thread(q)

    def _publish(self, pub: JobPublic) -> None:
        if pub.state in ACTIVE_STATES:
            self._snapshots[pub.id] = pub
        else:
            self._snapshots.pop(pub.id, None)
        self.hub.publish(pub.id, pub.model_dump(mode="json"))

    async def _republish(self, job_id: str) -> JobPublic | None:
        row = await in_thread(self._row, job_id)
        if row is None:
            return None
        if row.state not in ACTIVE:
            self._snapshots.pop(job_id, None)
        pub = self.public(row)
        self._publish(pub)
        return pub

    # ------------------------------------------------------------------------------------------------ submit
    def _too_many(self, s: Any) -> None:
        """Raise 429 when the active-job cap is reached (inside the writer's transaction: atomic with the insert)."""
        active = s.scalar(select(func.count()).select_from(Job).where(Job.state.in_(ACTIVE))) or 0
        cap = self.settings.max_active_jobs
        if active >= cap:
            raise TooManyJobs(f"{active} jobs are queued or running (limit {cap}); try again later",
                              headers={"Retry-After": str(RETRY_AFTER_S)})

    async def submit(self, kind: JobKind, request: dict[str, Any], *, job_id: str | None = None,
                     predicted: dict[str, Any] | None = None,
                     intact: Callable[[Job], Any] | None = None) -> tuple[Job, int]:
        """The job of ``kind`` for the canonical ``request`` (created, found, or queued again) and 202 (work pending)
        or 200 (finished).

        ``job_id`` overrides the kind's id rule (SHRM ids predate it); ``predicted`` is stored on a new row;
        ``intact(row)`` (awaitable) says whether a succeeded job's stored result is still usable (else it is
        recomputed). Raises 429 beyond the active-job cap.
        """
        job_id = job_id or kind.job_id(request)
        found = await self.find(job_id)
        if found is None:
            new = Job(id=job_id, kind=kind.name, state=JobState.queued.value, stage="queued", progress=0.0,
                      request=request, predicted=predicted, runs=0, submissions=0, retryable=0)
            row, created = await self.write(self._insert, new)
            if created:
                self.metrics.inc("jobs_created_total")
                self._ensure(job_id)
                return row, 202
        else:
            row = found
        if row.state == JobState.succeeded:
            if intact is None or await intact(row):
                self.metrics.inc("cache_hits_total")
                return row, 200
            await self.requeue(job_id, "recomputing: the stored result is missing or corrupt",
                               from_states=(JobState.succeeded.value,), capped=False)
        elif row.state in ACTIVE:
            self._ensure(job_id)
        elif row.state == JobState.cancelled or row.retryable:
            await self.requeue(job_id, "resubmitted", from_states=(row.state,), capped=True)
        else:  # failed for a reason that resubmitting cannot fix (invalid input)
            return row, 200
        return (await self.find(job_id)) or row, 202

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

    async def requeue(self, job_id: str, stage: str, *, from_states: tuple[str, ...], capped: bool) -> None:
        """Queue a finished job again (a cancelled or retryable one: under the cap; a lost result: always)."""

        def do() -> int:
            with self.db.session() as s:
                if capped:
                    self._too_many(s)
                res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(from_states)).values(
                    state=JobState.queued.value, stage=stage, progress=0.0, failure_reason=None, retryable=0,
                    result=None, result_sha256=None, finished_at=None, worker=None))
                return int(getattr(res, "rowcount", 0) or 0)

        if await self.write(do):
            for hook in self.on_requeue:
                await hook(job_id)
            await self._republish(job_id)
        self._ensure(job_id)

    def _ensure(self, job_id: str) -> None:
        """Start the job's watcher unless one runs (runs on the event loop only: no two watchers per job)."""
        if job_id not in self._watchers:
            self._watchers[job_id] = asyncio.create_task(self._watch(job_id), name=f"relight-job-{job_id[:12]}")

    def _mark_submitted(self, job_id: str) -> Job | None:
        with self.db.session() as s:
            row = s.get(Job, job_id)
            if row is None or row.state not in ACTIVE:
                return None
            row.submissions += 1
            row.state = JobState.queued.value
            row.submitted_at = utcnow()
            return row

    async def _watch(self, job_id: str) -> None:
        me = asyncio.current_task()

        async def submit(attempt: int) -> Any:
            row = await self.write(self._mark_submitted, job_id)
            if row is None:
                return None
            kind = kind_of(row.kind)
            self._submission[job_id] = row.submissions
            self._publish(self.public(row))
            payload = {"job_id": job_id, "submission": row.submissions, "request": row.request,
                       "max_pixels": self.settings.max_pixels, "test_delay_s": self.settings.test_job_delay_s}
            fut = self.cluster.submit(run_job, kind.task, str(self.store.root), payload,
                                      key=f"relight-{kind.name}-{job_id}-{row.submissions}")
            self._futures[job_id] = fut
            self.metrics.inc("job_submissions_total")
            return fut

        async def wanted() -> bool:  # not cancelled by a user meanwhile
            current = await in_thread(self._row, job_id)
            return current is not None and current.state in ACTIVE

        try:
            try:
                done, result = await run_with_resubmits(submit, wanted, name=f"job {job_id}")
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # noqa: BLE001 - every task failure is recorded on the job
                await self._fail(job_id, self._submission.get(job_id, 0), exc)
                return
            if done:
                await self._succeed(job_id, self._submission[job_id], result)
        finally:
            self._futures.pop(job_id, None)
            self._submission.pop(job_id, None)
            self._last_store.pop(job_id, None)
            if self._watchers.get(job_id) is me:
                del self._watchers[job_id]

    async def _succeed(self, job_id: str, submission: int, result: dict[str, Any]) -> None:
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

        row = await self.write(do)
        if row is None:
            return
        self.metrics.inc("jobs_succeeded_total")
        if row.measured:
            self.metrics.job_seconds.observe(float(row.measured.get("seconds") or 0.0))
            self.metrics.compute_seconds.observe(float(row.measured.get("compute_seconds") or 0.0))
        self._snapshots.pop(job_id, None)
        self._publish(self.public(row))

    async def _fail(self, job_id: str, submission: int, exc: BaseException) -> None:
        reason, retryable = failure_of(exc)
        log.warning("job %s failed: %s", job_id, reason)

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

        row = await self.write(do)
        if row is not None:
            self.metrics.inc("jobs_failed_total")
            self._snapshots.pop(job_id, None)
            self._publish(self.public(row))

    # ------------------------------------------------------------------------------------------------ progress
    def on_event(self, event: Any) -> None:
        """Dask topic handler: ``event`` is ``(timestamp, message)`` from :class:`relight.worker.progress.Reporter`.

        Dask awaits handlers inside its message loop (task completions wait behind them), so events are only
        queued here and handled, in order, by :meth:`_consume_events`.
        """
        self._events.put_nowait(event)

    async def _consume_events(self) -> None:
        while True:
            event = await self._events.get()
            try:
                await self._handle_event(event)
            except Exception:  # noqa: BLE001 - one bad event must not stop progress reporting
                log.exception("handling progress event %r", event)

    def start(self) -> None:
        self._consumer = asyncio.create_task(self._consume_events(), name="relight-progress-events")

    async def _handle_event(self, event: Any) -> None:
        try:
            _, msg = event
            job_id = str(msg["job"])
            kind = msg["event"]
        except (TypeError, ValueError, KeyError):
            log.warning("ignoring malformed progress event %r", event)
            return
        if job_id.startswith("envmap-"):
            if kind == "started" and msg.get("worker"):
                self.envmaps.analysing_on[job_id] = str(msg["worker"])
            return
        if msg.get("submission") != self._submission.get(job_id):
            return  # a superseded submission, or a job this process does not watch
        snap = self._snapshots.get(job_id)
        if snap is None or snap.state not in ACTIVE_STATES:
            return
        if kind == "started":
            worker = msg.get("worker")

            def do() -> None:
                with self.db.session() as s:
                    s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                        state=JobState.running.value, stage="started", worker=worker, runs=Job.runs + 1,
                        started_at=utcnow()))

            await self.write(do)  # stored before it is shown: "running" in the API means it is in the table
            self.metrics.inc("job_runs_total")
            snap = self._snapshots.get(job_id)
            if snap is not None and snap.state in ACTIVE_STATES:
                self._publish(snap.model_copy(update={"state": JobState.running, "worker": worker,
                                                      "runs": snap.runs + 1}))
        elif kind == "progress":
            stage, fraction = str(msg.get("stage")), float(msg.get("fraction", 0.0))
            snap = snap.model_copy(update={"stage": stage, "progress": fraction})
            self._publish(snap)
            now = time.monotonic()
            last_t, last_stage = self._last_store.get(job_id, (0.0, None))
            if stage != last_stage or now - last_t >= self.settings.progress_interval_s:
                self._last_store[job_id] = (now, stage)

                def store_progress() -> None:
                    with self.db.session() as s:
                        s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                            stage=stage, progress=fraction))

                await self.write(store_progress)

    async def events(self, job_id: str) -> AsyncIterator[tuple[str, JobPublic]]:
        """The job's updates as ``(event, job)``: ``job`` with the current state, one per update, then ``end`` with
        the final state (the route sends them as server-sent events)."""
        q = self.hub.subscribe(job_id)
        try:
            current = await self.get(job_id)  # subscribed first: nothing is missed between the two
            live = self._snapshots.get(job_id)
            if live is not None and live.state in ACTIVE_STATES:
                # the last update published: what was queued meanwhile is older (progress never goes back)
                current = live
                while not q.empty():
                    q.get_nowait()
            yield "job", current
            if current.state.terminal:
                yield "end", current
                return
            while True:
                pub = JobPublic.model_validate(await q.get())
                yield "job", pub
                if pub.state.terminal:
                    yield "end", pub
                    return
        finally:
            self.hub.unsubscribe(job_id, q)

    # ------------------------------------------------------------------------------------------------ cancel
    async def cancel(self, job_id: str, kind: str | None = None) -> JobPublic:
        """Cancel a queued or running job of any kind (409 when it has finished already)."""
        row = await self.row(job_id, kind)
        if row.state in (JobState.succeeded, JobState.failed):
            raise Conflict(f"job {job_id} has already {row.state}; there is nothing to cancel", state=row.state)
        if row.state in ACTIVE:
            def do() -> int:
                with self.db.session() as s:
                    res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                        state=JobState.cancelled.value, stage="cancelled", finished_at=utcnow(),
                        failure_reason="cancelled by request"))
                    return int(getattr(res, "rowcount", 0) or 0)

            if await self.write(do):
                self.metrics.inc("jobs_cancelled_total")
            fut = self._futures.get(job_id)
            if fut is not None:
                await self.cluster.cancel(fut)
        pub = await self._republish(job_id)
        assert pub is not None
        return pub

    # ------------------------------------------------------------------------------------------------ recovery
    async def resume(self) -> int:
        """Submit again every job, of every kind, left queued or running by a previous server process."""

        def do() -> list[str]:
            with self.db.session() as s:
                ids = list(s.scalars(select(Job.id).where(Job.state.in_(ACTIVE))))
                if ids:
                    s.execute(update(Job).where(Job.id.in_(ids)).values(
                        state=JobState.queued.value, stage="resubmitted after a restart", worker=None))
                return ids

        ids = await self.write(do)
        for job_id in ids:
            self._ensure(job_id)
        if ids:
            log.info("resubmitted %d unfinished jobs", len(ids))
        return len(ids)

    async def close(self) -> None:
        watchers = list(self._watchers.values())
        if self._consumer is not None:
            watchers.append(self._consumer)
        for t in watchers:
            t.cancel()
        await asyncio.gather(*watchers, return_exceptions=True)
        self._writer.shutdown(wait=True)


__all__ = ["JobService"]
