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
* **Progress.** Workers publish Dask events; :class:`relight.server.services.job_feed.JobFeed` fans them out to
  event streams and stores them at most every ``progress_interval_s``.
* **Cancellation.** ``DELETE`` marks the row ``cancelled`` and cancels the Dask future; the task stops at its next
  progress report, and a result that arrives anyway is not stored (only active rows take results).
* **Recovery.** At start-up jobs of every kind left ``queued`` or ``running`` are submitted again (at-least-once).
* **Integrity.** A succeeded job is only reused when every file its result lists under ``files`` is present and
  intact (:meth:`JobService.files_intact`, plus a kind's own ``intact`` check); otherwise resubmitting computes it
  again. A file found missing or corrupt when it is served queues the job again and answers 503 with
  ``Retry-After`` (:meth:`JobService.recompute`): a lost result is never served and never "succeeded" for good.
* **Several servers, one database.** A job is computed only by the server that holds its claim
  (:class:`relight.server.services.job_table.JobTable`: ``owner`` and ``lease_until``); the creating server
  claims it with the insert, the others asked for it find it claimed and leave it (their event streams read its
  row: :meth:`relight.server.services.job_feed.JobFeed.events`). A lease loop renews this server's claims every
  quarter of ``job_lease_s``, cancels the task of a job cancelled (or taken over) elsewhere, and claims jobs whose
  lease lapsed (their server died). A clean shutdown releases the claims, so the next server resumes at once.

Job-table writes go through a single writer thread, so they apply in the order they were issued
(:class:`relight.server.services.job_table.JobTable`, which holds every query of the table).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any, NoReturn

from relight.contract.models import JobList, JobPublic, JobState
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database, Job
from relight.server.problems import Conflict, Unavailable
from relight.server.services.base import in_thread
from relight.server.services.envmaps import EnvmapService
from relight.server.services.events import EventHub
from relight.server.services.job_feed import JobFeed
from relight.server.services.job_table import ACTIVE, JobTable
from relight.server.services.kinds import JobKind, kind_of
from relight.server.services.metrics import Metrics
from relight.server.services.runner import failure_of, run_with_resubmits
from relight.worker import faults
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore
from relight.worker.progress import run_job

log = logging.getLogger("relight.server")

#: Claim-and-run passes of one watcher: a second pass runs a job queued again while its previous run was finishing.
WATCH_PASSES = 3


class JobService(JobTable):
    """Submit, watch, cancel and resume jobs of every kind; the table's reads and writes are inherited
    (:class:`JobTable`), the live view and the progress events are :attr:`feed`'s."""

    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster, hub: EventHub,
                 metrics: Metrics, envmaps: EnvmapService) -> None:
        super().__init__(settings, db)
        self.store = store
        self.cluster = cluster
        self.metrics = metrics
        self.feed = JobFeed(settings, self, hub, metrics, envmaps)
        self._watchers: dict[str, asyncio.Task[None]] = {}
        self._futures: dict[str, Any] = {}  # job id -> distributed.Future
        self._lease_loop: asyncio.Task[None] | None = None
        #: Awaited with the job id when a finished job is queued again (the kinds drop what they cached of it).
        self.on_requeue: list[Callable[[str], Awaitable[None]]] = []

    # ------------------------------------------------------------------------------------------------ views
    def public(self, row: Job, *, cached: bool = False) -> JobPublic:
        return self.feed.public(row, cached=cached)

    async def get(self, job_id: str) -> JobPublic:
        return self.public(await self.row(job_id))

    async def list(self, state: JobState | None, limit: int, kind: str | None = None) -> JobList:
        return JobList(items=[self.public(r) for r in await self.rows(state, limit, kind)])

    def on_event(self, event: Any) -> None:
        """Dask topic handler for the workers' progress events (:meth:`JobFeed.on_event`)."""
        self.feed.on_event(event)

    def start(self) -> None:
        self.feed.start()
        self.feed.local = self._watchers.__contains__
        self._lease_loop = asyncio.create_task(self._leases(), name="relight-job-leases")

    async def _leases(self) -> None:
        """Every quarter of ``job_lease_s``: renew this server's claims, cancel the tasks of jobs that are no longer
        its own (cancelled through another server, or claimed by one after a lapse), claim the unclaimed."""
        while True:
            await asyncio.sleep(self.settings.job_lease_s / 4)
            try:
                mine = await self.renew(list(self._watchers))
                for job_id, fut in list(self._futures.items()):
                    if job_id not in mine and not fut.done():
                        log.warning("job %s is no longer this server's (cancelled or taken over): cancelling its "
                                    "task", job_id)
                        await self.cluster.cancel(fut)
                for job_id in await self.claimable():
                    self._ensure(job_id)
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # noqa: BLE001 - a database hiccup must not end the loop
                log.warning("renewing job claims: %s", exc)

    def events(self, job_id: str) -> AsyncIterator[tuple[str, JobPublic]]:
        """The job's updates as server-sent events (:meth:`JobFeed.events`)."""
        return self.feed.events(job_id)

    # ------------------------------------------------------------------------------------------------ submit
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
                      request=request, predicted=predicted, runs=0, submissions=0, retryable=0,
                      owner=self.instance, lease_until=self.lease())
            row, created = await self.insert(new)
            if created:
                self.metrics.inc("jobs_created_total")
                self._ensure(job_id)
                return row, 202
        else:
            row = found
        if row.state == JobState.succeeded:
            if await self.files_intact(row) and (intact is None or await intact(row)):
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

    async def requeue(self, job_id: str, stage: str, *, from_states: tuple[str, ...], capped: bool) -> bool:
        """Queue a finished job again (a cancelled or retryable one: under the cap; a lost result: always)."""
        queued = await self.requeue_row(job_id, stage, from_states=from_states, capped=capped)
        if queued:
            for hook in self.on_requeue:
                await hook(job_id)
            await self.feed.republish(job_id)
        self._ensure(job_id)
        return queued

    # ------------------------------------------------------------------------------------------------ integrity
    def _verify_files(self, row: Job) -> None:
        for info in ((row.result or {}).get("files") or {}).values():
            if isinstance(info, dict) and "sha256" in info:
                self.store.verified_path(str(info["sha256"]))

    async def files_intact(self, row: Job) -> bool:
        """Whether every file the job's result lists under ``files`` is present and hashes to its name (a corrupt
        one is removed by the check)."""
        try:
            await in_thread(self._verify_files, row)
        except (BlobMissing, BlobCorrupt, ValueError):
            return False
        return True

    async def require_files(self, row: Job) -> None:
        """Return when every file of the succeeded job ``row`` is intact; else queue it again and answer 503."""
        try:
            await in_thread(self._verify_files, row)
        except (BlobMissing, BlobCorrupt, ValueError) as exc:
            await self.recompute(row.id, exc)

    async def verified_file(self, job_id: str, digest: str) -> Path:
        """The verified path of the blob ``digest`` of job ``job_id``'s result; 503 and the job queued again when it
        is missing or corrupt."""
        try:
            return await in_thread(self.store.verified_path, digest)
        except (BlobMissing, BlobCorrupt) as exc:
            await self.recompute(job_id, exc)

    async def recompute(self, job_id: str, exc: BaseException) -> NoReturn:
        """A stored result of ``job_id`` was found missing or corrupt: queue the job again (outside the cap: the
        result existed) and answer 503 with ``Retry-After``."""
        log.warning("result of job %s unusable (%s): recomputing", job_id, exc)
        self.metrics.inc("results_recomputed_total")
        await self.requeue(job_id, "recomputing: the stored result was missing or corrupt",
                           from_states=(JobState.succeeded.value,), capped=False)
        raise Unavailable(f"the stored result of job {job_id} was missing or corrupt; it is being recomputed",
                          headers={"Retry-After": "2"}, job=f"/jobs/{job_id}")

    def _ensure(self, job_id: str) -> None:
        """Start the job's watcher unless one runs (runs on the event loop only: no two watchers per job)."""
        if job_id not in self._watchers:
            self._watchers[job_id] = asyncio.create_task(self._watch(job_id), name=f"relight-job-{job_id[:12]}")

    async def _watch(self, job_id: str) -> None:
        """Claim the job and run it while it is active and this server's; leave it to its owner otherwise."""
        me = asyncio.current_task()
        try:
            for _ in range(WATCH_PASSES):
                row = await self.claim(job_id)
                if row is None or row.state not in ACTIVE or row.owner != self.instance:
                    return
                await self._run(job_id)
        finally:
            if self._watchers.get(job_id) is me:
                del self._watchers[job_id]

    async def _run(self, job_id: str) -> None:
        """Submit the claimed job (again while its future is lost) and store its outcome."""

        async def submit(attempt: int) -> Any:
            row = await self.mark_submitted(job_id)
            if row is None:
                return None
            kind = kind_of(row.kind)
            self.feed.submission[job_id] = row.submissions
            self.feed.publish(self.public(row))
            payload = {"job_id": job_id, "submission": row.submissions, "request": row.request,
                       "max_pixels": self.settings.max_pixels, "test_delay_s": self.settings.test_job_delay_s}
            fut = self.cluster.submit(run_job, kind.task, str(self.store.root), payload,
                                      key=f"relight-{kind.name}-{job_id}-{row.submissions}", job=True)
            self._futures[job_id] = fut
            self.metrics.inc("job_submissions_total")
            return fut

        async def wanted() -> bool:  # not cancelled by a user (or taken over by another server) meanwhile
            current = await self.find(job_id)
            return current is not None and current.state in ACTIVE and current.owner == self.instance

        try:
            try:
                done, result = await run_with_resubmits(submit, wanted, name=f"job {job_id}")
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # noqa: BLE001 - every task failure is recorded on the job
                await self._fail(job_id, self.feed.submission.get(job_id, 0), exc)
                return
            # the result is in hand: let Dask forget the task now. A held future would make Dask recompute the
            # task if its worker died while the result is being committed (tests/service/test_faults.py).
            self._futures.pop(job_id, None)
            if done:
                await self._succeed(job_id, self.feed.submission[job_id], result)
        finally:
            self._futures.pop(job_id, None)
            self.feed.forget(job_id)

    async def _succeed(self, job_id: str, submission: int, result: dict[str, Any]) -> None:
        await faults.apause("before_commit", job_id)  # TEST ONLY: off unless RELIGHT_TEST_FAULT_DIR is set
        row = await self.store_success(job_id, submission, result)
        if row is None:
            return
        self.metrics.inc("jobs_succeeded_total")
        if row.measured:
            self.metrics.job_seconds.observe(float(row.measured.get("seconds") or 0.0))
            self.metrics.compute_seconds.observe(float(row.measured.get("compute_seconds") or 0.0))
        self.feed.publish_final(row)

    async def _fail(self, job_id: str, submission: int, exc: BaseException) -> None:
        reason, retryable = failure_of(exc)
        log.warning("job %s failed: %s", job_id, reason)
        row = await self.store_failure(job_id, submission, reason, retryable)
        if row is not None:
            self.metrics.inc("jobs_failed_total")
            self.feed.publish_final(row)

    # ------------------------------------------------------------------------------------------------ cancel
    async def cancel(self, job_id: str, kind: str | None = None) -> JobPublic:
        """Cancel a queued or running job of any kind (409 when it has finished already)."""
        row = await self.row(job_id, kind)
        if row.state in (JobState.succeeded, JobState.failed):
            raise Conflict(f"job {job_id} has already {row.state}; there is nothing to cancel", state=row.state)
        if row.state in ACTIVE:
            if await self.mark_cancelled(job_id):
                self.metrics.inc("jobs_cancelled_total")
            fut = self._futures.get(job_id)
            if fut is not None:
                await self.cluster.cancel(fut)
        pub = await self.feed.republish(job_id)
        assert pub is not None
        return pub

    # ------------------------------------------------------------------------------------------------ recovery
    async def resume(self) -> int:
        """Submit again every job, of every kind, left queued or running by a previous server process."""
        ids = await self.requeue_active()
        for job_id in ids:
            self._ensure(job_id)
        if ids:
            log.info("resubmitted %d unfinished jobs", len(ids))
        return len(ids)

    async def close(self) -> None:
        watchers = list(self._watchers.values())
        consumer = self.feed.stop()
        if consumer is not None:
            watchers.append(consumer)
        if self._lease_loop is not None:
            watchers.append(self._lease_loop)
        for t in watchers:
            t.cancel()
        await asyncio.gather(*watchers, return_exceptions=True)
        try:
            released = await self.release()  # the next server (or another one) resumes them at once
            if released:
                log.info("released the claims on %d unfinished jobs", released)
        except Exception as exc:  # noqa: BLE001 - the database may be what failed; the leases lapse anyway
            log.warning("releasing job claims: %s", exc)
        self.close_writer()


__all__ = ["JobService"]
