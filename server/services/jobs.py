"""Jobs: identity, the job table (source of truth), submission to Dask, progress, cancellation and recovery.

* **Identity.** A job's id is the SHA-256 of (input digests, canonical parameters, ``relight.ALGORITHM_VERSION``):
  identical requests share one job and one result.
* **Submission.** One watcher task per active job submits ``relight.worker.tasks.compute_shrm`` and awaits it; a dict of
  watchers (mutated only on the event loop) guarantees one submission per job in this process, the primary
  key guarantees one row. A lost worker is Dask's business: it reschedules the task (``runs`` counts starts).
* **Progress.** Workers publish Dask events (:mod:`relight.worker.progress`); every event is fanned out to event streams
  at once, and stored at most every ``progress_interval_s`` (or on a stage change).
* **Recovery.** At start-up jobs left ``queued`` or ``running`` are submitted again (at-least-once). The worker
  finds a finished result through its ref instead of recomputing, and results are content-addressed, so a
  repeated run never duplicates a result.
* **Integrity.** Result files are verified by hash when served; a missing or corrupt one sends the job back to
  ``queued`` (recomputed, 503 meanwhile), never served.

Job-table writes go through a single writer thread, so they apply in the order they were issued.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TypeVar

from sqlalchemy import func, select, update

from relight.contract.models import (
    ACTIVE_STATES,
    JobList,
    JobParams,
    JobPublic,
    JobState,
    Measurement,
    Orders,
    Prediction,
    ShrmCreate,
    parse_view,
)
from relight.errors import InputError
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database, Job, Render, utcnow
from relight.server.problems import Conflict, NotFound, TooManyJobs, Unavailable, Unprocessable
from relight.server.services.base import aware, content_id, in_thread, utc
from relight.server.services.envmaps import EnvmapService
from relight.server.services.events import EventHub
from relight.server.services.metrics import Metrics
from relight.server.services.plans import PlanService, Prepared
from relight.server.services.runner import failure_of, run_with_resubmits
from relight.worker import tasks
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore
from relight.worker.results import job_ref, load_manifest

log = logging.getLogger("relight.server")
T = TypeVar("T")

ACTIVE: Final = tuple(s.value for s in ACTIVE_STATES)
HEARTBEAT_S: Final = 15.0
RENDER_TIMEOUT_S: Final = 300.0


@dataclass(frozen=True)
class ResultFile:
    """A verified result file: its bytes, digest, media type and where the store keeps it."""

    content: bytes
    sha256: str
    media_type: str
    path: Path


class JobService:
    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster, hub: EventHub,
                 metrics: Metrics, envmaps: EnvmapService, plans: PlanService) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self.cluster = cluster
        self.hub = hub
        self.metrics = metrics
        self.envmaps = envmaps
        self.plans = plans
        self._watchers: dict[str, asyncio.Task[None]] = {}
        self._futures: dict[str, Any] = {}  # job id -> distributed.Future
        self._submission: dict[str, int] = {}
        self._snapshots: dict[str, JobPublic] = {}
        self._last_store: dict[str, tuple[float, str | None]] = {}
        self._manifests: dict[str, tuple[str, dict[str, Any]]] = {}
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="relight-db-writer")
        self._events: asyncio.Queue[Any] = asyncio.Queue()
        self._consumer: asyncio.Task[None] | None = None

    # ------------------------------------------------------------------------------------------------ plumbing
    async def _write(self, fn: Callable[..., T], *args: Any) -> T:
        return await asyncio.get_running_loop().run_in_executor(self._writer, fn, *args)

    def _row(self, job_id: str) -> Job | None:
        with self.db.session() as s:
            return s.get(Job, job_id)

    def _public(self, row: Job, *, cached: bool = False) -> JobPublic:
        links = {"self": f"/jobs/{row.id}", "events": f"/jobs/{row.id}/events"}
        if row.state == JobState.succeeded:
            links |= {"result": f"/shrms/{row.id}", "coefficients.exr": f"/shrms/{row.id}/coefficients.exr",
                      "coefficients.bin": f"/shrms/{row.id}/coefficients.bin"}
        pub = JobPublic(
            id=row.id, state=JobState(row.state), stage=row.stage, progress=row.progress, envmap=row.envmap_id,
            brdf=row.brdf_id, brdf_spec=row.brdf_spec, params=JobParams(**row.params),
            predicted=Prediction(**row.predicted) if row.predicted else None,
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
        row = await in_thread(self._row, job_id)
        if row is None:
            raise NotFound(f"no job with id {job_id!r}")
        return self._public(row)

    async def list(self, state: JobState | None, limit: int) -> JobList:
        def q() -> list[Job]:
            with self.db.session() as s:
                stmt = select(Job).order_by(Job.created_at.desc()).limit(limit)
                if state is not None:
                    stmt = stmt.where(Job.state == state.value)
                return list(s.scalars(stmt))

        return JobList(items=[self._public(r) for r in await in_thread(q)])

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
        pub = self._public(row)
        self._publish(pub)
        return pub

    # ------------------------------------------------------------------------------------------------ submit
    async def submit(self, create: ShrmCreate) -> tuple[JobPublic, int]:
        """Create (or find) the job for ``create``; returns the job and 202 (work pending) or 200 (finished)."""
        prep = await self.plans.prepare(create)
        await self.envmaps.input_ok(prep.envmap.id)
        row = await in_thread(self._row, prep.job_id)
        if row is not None:
            return await self._existing(row)
        if len(self._watchers) >= self.settings.max_active_jobs:
            raise TooManyJobs(f"{len(self._watchers)} jobs are queued or running (limit "
                              f"{self.settings.max_active_jobs}); try again later", headers={"Retry-After": "5"})
        plan = await self.plans.plan_prepared(prep)
        predicted = Prediction(seconds=plan.predicted_seconds, rms_error=plan.predicted_error.rms_min_of_errors,
                               orders=plan.orders, representation=plan.representation)
        new = Job(id=prep.job_id, state=JobState.queued.value, stage="queued", progress=0.0,
                  envmap_id=prep.envmap.id, brdf_id=prep.brdf.id, brdf_spec=prep.brdf.spec, params=prep.params,
                  predicted=predicted.model_dump(mode="json"), runs=0, submissions=0, retryable=0)
        stored, created = await self._write(self._insert, new)
        if not created:
            return await self._existing(stored)
        self.metrics.inc("jobs_created_total")
        self._ensure(stored.id)
        return self._public(stored), 202

    def _insert(self, new: Job) -> tuple[Job, bool]:
        from sqlalchemy.exc import IntegrityError

        try:
            with self.db.session() as s:
                found = s.get(Job, new.id)
                if found is not None:
                    return found, False
                s.add(new)
            return new, True
        except IntegrityError:  # another server process inserted it first
            row = self._row(new.id)
            if row is None:
                raise
            return row, False

    async def _existing(self, row: Job) -> tuple[JobPublic, int]:
        if row.state == JobState.succeeded:
            if await self._result_intact(row):
                self.metrics.inc("cache_hits_total")
                return self._public(row, cached=True), 200
            await self._requeue(row.id, "recomputing: the stored result is missing or corrupt",
                                from_states=(JobState.succeeded.value,))
        elif row.state in ACTIVE:
            self._ensure(row.id)
        elif row.state == JobState.cancelled or row.retryable:
            await self._requeue(row.id, "resubmitted", from_states=(row.state,))
        else:  # failed for a reason that resubmitting cannot fix (invalid input)
            return self._public(row), 200
        fresh = await in_thread(self._row, row.id)
        return self._public(fresh or row), 202

    async def _result_intact(self, row: Job) -> bool:
        if row.result_sha256 is None:
            return False
        try:
            manifest = await in_thread(load_manifest, self.store, row.result_sha256)
            for info in manifest["files"].values():
                await in_thread(self.store.verified_path, info["sha256"])
        except (BlobMissing, BlobCorrupt, KeyError, ValueError):
            return False
        self._manifests[row.id] = (row.result_sha256, manifest)
        return True

    async def _requeue(self, job_id: str, stage: str, *, from_states: tuple[str, ...]) -> None:
        def do() -> int:
            with self.db.session() as s:
                res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(from_states)).values(
                    state=JobState.queued.value, stage=stage, progress=0.0, failure_reason=None, retryable=0,
                    result_sha256=None, finished_at=None, worker=None))
                return int(getattr(res, "rowcount", 0) or 0)

        if await self._write(do):
            self._manifests.pop(job_id, None)
            await in_thread(self.store.delete_ref, job_ref(job_id))
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
            row = await self._write(self._mark_submitted, job_id)
            if row is None:
                return None
            self._submission[job_id] = row.submissions
            self._publish(self._public(row))
            payload = {
                "job_id": job_id, "submission": row.submissions, "envmap": row.envmap_id, "brdf": row.brdf_spec,
                "params": row.params, "max_pixels": self.settings.max_pixels,
                "test_delay_s": self.settings.test_job_delay_s,
            }
            fut = self.cluster.submit(tasks.compute_shrm, str(self.store.root), payload,
                                      key=f"relight-job-{job_id}-{row.submissions}")
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
            if self._watchers.get(job_id) is me:
                del self._watchers[job_id]

    async def _succeed(self, job_id: str, submission: int, result: dict[str, Any]) -> None:
        manifest: dict[str, Any] = result["manifest"]
        orders = manifest.get("orders") or {}

        def do() -> Job | None:
            with self.db.session() as s:
                row = s.get(Job, job_id)
                if row is None or row.state not in ACTIVE or row.submissions != submission:
                    return None
                now = utcnow()
                submitted = aware(row.submitted_at) or now
                row.measured = Measurement(
                    seconds=(now - submitted).total_seconds(), task_seconds=result.get("task_seconds"),
                    compute_seconds=result.get("compute_seconds"), stage_seconds=result.get("timings"),
                    rms_error=orders.get("rms_min_of_errors"),
                    rms_bound=orders.get("rms_appendix_b"),
                    orders=Orders(F_L=orders.get("F_L"), F_rho=orders.get("F_rho"), F_B=orders.get("F_B", 0),
                                  P_B=orders.get("P_B", 0)) if orders else None,
                    reused=bool(result.get("reused")),
                ).model_dump(mode="json")
                row.state, row.stage, row.progress = JobState.succeeded.value, "done", 1.0
                row.result_sha256 = result["manifest_sha256"]
                row.finished_at = now
                row.runs = max(row.runs, 1)
                row.failure_reason = None
                return row

        row = await self._write(do)
        if row is None:
            return
        self._manifests[job_id] = (result["manifest_sha256"], manifest)
        self.metrics.inc("jobs_succeeded_total")
        if row.measured:
            self.metrics.job_seconds.observe(float(row.measured.get("seconds") or 0.0))
            self.metrics.compute_seconds.observe(float(row.measured.get("compute_seconds") or 0.0))
        self._snapshots.pop(job_id, None)
        self._publish(self._public(row))

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

        row = await self._write(do)
        if row is not None:
            self.metrics.inc("jobs_failed_total")
            self._snapshots.pop(job_id, None)
            self._publish(self._public(row))

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

            await self._write(do)  # stored before it is shown: "running" in the API means it is in the table
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

                await self._write(store_progress)

    async def events(self, job_id: str, first: JobPublic) -> AsyncIterator[str]:
        """Server-sent events: the current state, every update, then ``end`` with the final state."""
        q = self.hub.subscribe(job_id)
        seq = 0

        def sse(event: str, data: str) -> str:
            nonlocal seq
            seq += 1
            return f"id: {seq}\nevent: {event}\ndata: {data}\n\n"

        try:
            current = await self.get(job_id)  # subscribed first: nothing is missed between the two
            yield sse("job", current.model_dump_json())
            if current.state.terminal:
                yield sse("end", current.model_dump_json())
                return
            while True:
                try:
                    payload = await asyncio.wait_for(q.get(), HEARTBEAT_S)
                except TimeoutError:
                    yield ": keep-alive\n\n"
                    continue
                pub = JobPublic.model_validate(payload)
                yield sse("job", pub.model_dump_json())
                if pub.state.terminal:
                    yield sse("end", pub.model_dump_json())
                    return
        finally:
            self.hub.unsubscribe(job_id, q)

    # ------------------------------------------------------------------------------------------------ cancel
    async def cancel(self, job_id: str) -> JobPublic:
        row = await in_thread(self._row, job_id)
        if row is None:
            raise NotFound(f"no job with id {job_id!r}")
        if row.state in (JobState.succeeded, JobState.failed):
            raise Conflict(f"job {job_id} has already {row.state}; there is nothing to cancel", state=row.state)
        if row.state in ACTIVE:
            def do() -> int:
                with self.db.session() as s:
                    res = s.execute(update(Job).where(Job.id == job_id, Job.state.in_(ACTIVE)).values(
                        state=JobState.cancelled.value, stage="cancelled", finished_at=utcnow(),
                        failure_reason="cancelled by request"))
                    return int(getattr(res, "rowcount", 0) or 0)

            if await self._write(do):
                self.metrics.inc("jobs_cancelled_total")
            fut = self._futures.get(job_id)
            if fut is not None:
                await self.cluster.cancel(fut)
        pub = await self._republish(job_id)
        assert pub is not None
        return pub

    # ------------------------------------------------------------------------------------------------ recovery
    async def resume(self) -> int:
        """Submit again every job left queued or running by a previous server process."""

        def do() -> list[str]:
            with self.db.session() as s:
                ids = list(s.scalars(select(Job.id).where(Job.state.in_(ACTIVE))))
                if ids:
                    s.execute(update(Job).where(Job.id.in_(ids)).values(
                        state=JobState.queued.value, stage="resubmitted after a restart", worker=None))
                return ids

        ids = await self._write(do)
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

    # ------------------------------------------------------------------------------------------------ results
    async def manifest(self, job_id: str) -> tuple[str, dict[str, Any]]:
        cached = self._manifests.get(job_id)
        if cached is not None:
            return cached
        row = await in_thread(self._row, job_id)
        if row is None:
            raise NotFound(f"no result with id {job_id!r}")
        if row.state != JobState.succeeded or row.result_sha256 is None:
            raise Conflict(f"job {job_id} is {row.state}; it has no result yet", state=row.state)
        try:
            manifest = await in_thread(load_manifest, self.store, row.result_sha256)
        except (BlobMissing, BlobCorrupt) as exc:
            await self._recompute(job_id, exc)
            raise AssertionError("unreachable") from exc
        self._manifests[job_id] = (row.result_sha256, manifest)
        return row.result_sha256, manifest

    async def _recompute(self, job_id: str, exc: BaseException) -> None:
        log.warning("result of job %s unusable (%s): recomputing", job_id, exc)
        self._manifests.pop(job_id, None)
        self.metrics.inc("results_recomputed_total")
        await self._requeue(job_id, "recomputing: the stored result was missing or corrupt",
                            from_states=(JobState.succeeded.value,))
        raise Unavailable(f"the stored result of job {job_id} was missing or corrupt ({exc}); it is being "
                          "recomputed", headers={"Retry-After": "2"}, job=f"/jobs/{job_id}")

    async def result_file(self, job_id: str, name: str) -> ResultFile:
        """A result file's verified bytes (held in memory after the first read: one ``stat`` per request)."""
        _, manifest = await self.manifest(job_id)
        info = manifest["files"][name]
        digest = info["sha256"]
        data = self.store.cached_bytes(digest)
        if data is None:
            try:
                data = await in_thread(self.store.load, digest)
            except (BlobMissing, BlobCorrupt) as exc:
                await self._recompute(job_id, exc)
                raise AssertionError("unreachable") from exc
        return ResultFile(data, digest, info.get("media_type", "application/octet-stream"), self.store.path(digest))

    async def reflection(self, job_id: str, view_text: str) -> ResultFile:
        try:
            view = parse_view(view_text)
        except ValueError as exc:
            raise Unprocessable(str(exc)) from None
        manifest_digest, _ = await self.manifest(job_id)
        canon = [round(v, 9) + 0.0 for v in view]
        key = content_id({"manifest": manifest_digest, "view": canon})

        def lookup() -> str | None:
            with self.db.session() as s:
                r = s.get(Render, key)
                return r.sha256 if r else None

        digest = await in_thread(lookup)
        if digest is not None:
            try:
                return ResultFile(await in_thread(self.store.load, digest), digest, "image/x-exr",
                                  self.store.path(digest))
            except (BlobMissing, BlobCorrupt):
                digest = None
        fut = self.cluster.submit(tasks.render_reflection, str(self.store.root), manifest_digest, canon,
                                  key=f"relight-render-{key}")
        try:
            digest = str(await asyncio.wait_for(fut, RENDER_TIMEOUT_S))
        except InputError as exc:
            raise Unprocessable(str(exc)) from None

        def save() -> None:
            with self.db.session() as s:
                if s.get(Render, key) is None:
                    s.add(Render(key=key, job_id=job_id, view=",".join(f"{v:.9g}" for v in canon), sha256=digest))

        await self._write(save)
        return ResultFile(await in_thread(self.store.load, digest), digest, "image/x-exr", self.store.path(digest))


__all__ = ["JobService", "Prepared", "ResultFile"]
