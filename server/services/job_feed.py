"""How jobs are shown live: the API view of a row, progress events from the workers, and the event streams.

* **Progress.** Workers publish Dask events (:mod:`relight.worker.progress`); every event is fanned out to event
  streams at once (:class:`relight.server.services.events.EventHub`), and stored at most every
  ``progress_interval_s`` (or on a stage change).
* **Snapshots.** The last update published for each active job is kept in memory; the API view of a row
  (:meth:`JobFeed.public`) takes its state, stage and progress from it, since the table lags behind by up to
  ``progress_interval_s``.
* **Submissions.** Only events of a job's current submission count (:attr:`JobFeed.submission`, set by the
  watcher in :class:`relight.server.services.jobs.JobService`): a superseded submission's events are dropped.
* **Other servers' jobs.** A job computed by another server on the same database (its claim,
  :mod:`relight.server.services.job_table`) publishes nothing here: its event streams read the row every
  ``follow_interval_s`` and send what changed (the owner stores progress at least every ``progress_interval_s``
  and at every stage change). Streams of this server's own jobs read it only as a safety net (every
  :data:`LOCAL_RECHECK` intervals).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

from relight.contract.models import ACTIVE_STATES, JobParams, JobPublic, JobState, Measurement, Prediction
from relight.server.config import Settings
from relight.server.db import Job
from relight.server.services.base import aware, utc
from relight.server.services.envmaps import EnvmapService
from relight.server.services.events import CLOSED, EventHub
from relight.server.services.job_table import ACTIVE, JobTable
from relight.server.services.kinds import links_of
from relight.server.services.metrics import Metrics

log = logging.getLogger("relight.server")

#: A stream of a job this server computes re-reads its row after this many ``follow_interval_s`` without an update.
LOCAL_RECHECK = 10


class JobFeed:
    def __init__(self, settings: Settings, table: JobTable, hub: EventHub, metrics: Metrics,
                 envmaps: EnvmapService) -> None:
        self.settings = settings
        self.table = table
        self.hub = hub
        self.metrics = metrics
        self.envmaps = envmaps
        #: job id -> the submission whose events count (set by the job's watcher)
        self.submission: dict[str, int] = {}
        self._snapshots: dict[str, JobPublic] = {}
        self._last_store: dict[str, tuple[float, str | None]] = {}
        self._events: asyncio.Queue[Any] = asyncio.Queue()
        self._consumer: asyncio.Task[None] | None = None
        #: Whether this server computes the job (a watcher of its own runs it); set by the job service.
        self.local: Callable[[str], bool] = lambda job_id: False

    # ------------------------------------------------------------------------------------------------ view
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

    def publish(self, pub: JobPublic) -> None:
        if pub.state in ACTIVE_STATES:
            self._snapshots[pub.id] = pub
        else:
            self._snapshots.pop(pub.id, None)
        self.hub.publish(pub.id, pub.model_dump(mode="json"))

    def publish_final(self, row: Job) -> None:
        """Publish a row that has just left the active states (succeeded, failed)."""
        self._snapshots.pop(row.id, None)
        self.publish(self.public(row))

    async def republish(self, job_id: str) -> JobPublic | None:
        row = await self.table.find(job_id)
        if row is None:
            return None
        if row.state not in ACTIVE:
            self._snapshots.pop(job_id, None)
        pub = self.public(row)
        self.publish(pub)
        return pub

    def forget(self, job_id: str) -> None:
        """The job's watcher has ended: its submission's events no longer count."""
        self.submission.pop(job_id, None)
        self._last_store.pop(job_id, None)

    # ------------------------------------------------------------------------------------------------ events
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

    def stop(self) -> asyncio.Task[None] | None:
        """Cancel the event consumer; the task to await (``None`` when it never started)."""
        if self._consumer is not None:
            self._consumer.cancel()
        return self._consumer

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
        if msg.get("submission") != self.submission.get(job_id):
            return  # a superseded submission, or a job this process does not watch
        snap = self._snapshots.get(job_id)
        if snap is None or snap.state not in ACTIVE_STATES:
            return
        if kind == "started":
            worker = msg.get("worker")
            await self.table.mark_running(job_id, worker)  # stored before shown: "running" means in the table
            self.metrics.inc("job_runs_total")
            snap = self._snapshots.get(job_id)
            if snap is not None and snap.state in ACTIVE_STATES:
                self.publish(snap.model_copy(update={"state": JobState.running, "worker": worker,
                                                     "runs": snap.runs + 1}))
        elif kind == "progress":
            stage, fraction = str(msg.get("stage")), float(msg.get("fraction", 0.0))
            snap = snap.model_copy(update={"stage": stage, "progress": fraction})
            self.publish(snap)
            now = time.monotonic()
            last_t, last_stage = self._last_store.get(job_id, (0.0, None))
            if stage != last_stage or now - last_t >= self.settings.progress_interval_s:
                self._last_store[job_id] = (now, stage)
                await self.table.store_progress(job_id, stage, fraction)

    async def events(self, job_id: str) -> AsyncIterator[tuple[str, JobPublic]]:
        """The job's updates as ``(event, job)``: ``job`` with the current state, one per update, then ``end`` with
        the final state (the route sends them as server-sent events)."""
        q = self.hub.subscribe(job_id)
        try:
            current = self.public(await self.table.row(job_id))  # subscribed first: nothing is missed between
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
            last = _seen(current)
            while True:
                interval = self.settings.follow_interval_s * (LOCAL_RECHECK if self.local(job_id) else 1)
                try:
                    payload = await asyncio.wait_for(q.get(), interval)
                except TimeoutError:  # computed elsewhere (or an update was lost): the row says where it is
                    row = await self.table.find(job_id)
                    if row is None:
                        return
                    pub = self.public(row)
                    if _seen(pub) == last:
                        continue
                else:
                    if payload is CLOSED:  # the server is stopping: the stream ends without an "end" event
                        return
                    pub = JobPublic.model_validate(payload)
                last = _seen(pub)
                yield "job", pub
                if pub.state.terminal:
                    yield "end", pub
                    return
        finally:
            self.hub.unsubscribe(job_id, q)


def _seen(pub: JobPublic) -> tuple[Any, ...]:
    """What a stream has shown of a job (an update that changes none of it is not sent again)."""
    return pub.state, pub.stage, pub.progress, pub.runs, pub.submissions, pub.worker


__all__ = ["JobFeed"]
