"""Accuracy–time sweeps as jobs (``POST /tradeoffs``), the analysis-job machinery scenes share, and the calibrated
cost model behind ``/plan``.

* **Analysis jobs.** A tradeoff or a scene is identified by the SHA-256 of its canonical request (with
  ``relight.ALGORITHM_VERSION`` and the kind's result version); its row in the ``analyses`` table is the source of
  truth. Submitting starts one Dask task (:mod:`relight.worker.analysis`) and a watcher that stores the result (small
  JSON) in the row; a lost future is submitted again and failures are classified as for SHRM jobs
  (:mod:`relight.server.services.runner`). Identical requests share the row (200 with the result once it exists). Rows
  left queued or running by a previous server process are submitted again when the service first starts in a
  process (at-least-once).
* **Cost model.** ``/plan`` predicts seconds with ``relight.planning.plan_job``: the calibration cached for this
  machine if one exists, else the built-in constants while a calibration runs once in a worker
  (:func:`start_calibration`).
"""

from __future__ import annotations

import asyncio
import functools
import logging
from abc import ABC, abstractmethod
from collections.abc import Callable
from datetime import datetime
from typing import Any, Final

from fastapi import Request
from sqlalchemy import JSON, DateTime, Integer, String, Text, select, update
from sqlalchemy.orm import Mapped, mapped_column

import relight
from relight.contract.models import JobState, TradeoffCreate, TradeoffPublic
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Base, Database, utcnow
from relight.server.problems import NotFound, TooManyJobs, Unprocessable
from relight.server.services.base import aware, content_id, in_thread, utc
from relight.server.services.brdfs import BrdfService
from relight.server.services.envmaps import EnvmapService
from relight.server.services.runner import failure_of, run_with_resubmits
from relight.worker.blobs import BlobStore

log = logging.getLogger("relight.server")

ACTIVE: Final = (JobState.queued.value, JobState.running.value)
#: Server-side caps of a sweep (each point runs both an SHRM and an angular reference).
MAX_TRADEOFF_ROWS: Final = 256


class Analysis(Base):
    """A tradeoff sweep or a scene run: request, state and (small, JSON) result."""

    __tablename__ = "analyses"

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    kind: Mapped[str] = mapped_column(String(16), index=True)
    state: Mapped[str] = mapped_column(String(16), index=True)
    request: Mapped[dict[str, Any]] = mapped_column(JSON)
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    failure_reason: Mapped[str | None] = mapped_column(Text)
    retryable: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))


class AnalysisService(ABC):
    """Submission, watching and lookup of one kind of analysis job (module docstring)."""

    kind: str = ""
    #: Version of this kind's result format, part of its ids: a result stored in an older format is never served
    #: for a new request (it is computed again under the new id).
    result_version: int = 1

    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster, envmaps: EnvmapService,
                 brdfs: BrdfService) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self.cluster = cluster
        self.envmaps = envmaps
        self.brdfs = brdfs
        self._watchers: dict[str, asyncio.Task[None]] = {}
        Base.metadata.create_all(db.engine, tables=[Analysis.__table__])  # type: ignore[list-item]

    @abstractmethod
    def task(self) -> Callable[..., Any]:
        """The worker function this kind of analysis runs (``relight.worker.analysis``)."""

    def _row(self, job_id: str) -> Analysis | None:
        with self.db.session() as s:
            row = s.get(Analysis, job_id)
            return row if row is not None and row.kind == self.kind else None

    async def row(self, job_id: str) -> Analysis:
        row = await in_thread(self._row, job_id)
        if row is None:
            raise NotFound(f"no {self.kind} with id {job_id!r}")
        return row

    async def submit_request(self, request: dict[str, Any]) -> tuple[Analysis, int]:
        """The row for ``request`` (created, or found) and 202 (work pending) or 200 (finished)."""
        job_id = content_id({"task": self.kind, "algorithm_version": relight.ALGORITHM_VERSION,
                             "result_version": self.result_version, "request": request})
        row = await in_thread(self._row, job_id)
        if row is not None:
            if row.state == JobState.succeeded or (row.state == JobState.failed and not row.retryable):
                return row, 200
            if row.state in ACTIVE:
                self._ensure(job_id)
                return row, 202
        if len(self._watchers) >= self.settings.max_active_jobs:
            raise TooManyJobs(f"{len(self._watchers)} {self.kind} jobs are queued or running; try again later",
                              headers={"Retry-After": "5"})

        def upsert() -> Analysis:
            with self.db.session() as s:
                found = s.get(Analysis, job_id)
                if found is None:
                    found = Analysis(id=job_id, kind=self.kind, state=JobState.queued.value, request=request,
                                     result=None, retryable=0)
                    s.add(found)
                else:  # failed (retryable) or cancelled: run again
                    found.state, found.failure_reason, found.result, found.finished_at = "queued", None, None, None
                return found

        row = await in_thread(upsert)
        self._ensure(job_id)
        return row, 202

    def _ensure(self, job_id: str) -> None:
        if job_id not in self._watchers:
            self._watchers[job_id] = asyncio.create_task(self._watch(job_id), name=f"relight-{self.kind}-{job_id[:12]}")

    def resume(self) -> None:
        """Submit again every job of this kind left queued or running (called once per process)."""
        with self.db.session() as s:
            ids = list(s.scalars(select(Analysis.id).where(Analysis.kind == self.kind, Analysis.state.in_(ACTIVE))))
        for job_id in ids:
            self._ensure(job_id)

    def _set(self, job_id: str, **values: Any) -> None:
        with self.db.session() as s:
            s.execute(update(Analysis).where(Analysis.id == job_id).values(**values))

    async def _watch(self, job_id: str) -> None:
        me = asyncio.current_task()

        async def submit(attempt: int) -> Any:
            row = await in_thread(self._row, job_id)
            if row is None or row.state not in ACTIVE:
                return None
            payload = {**row.request, "max_pixels": self.settings.max_pixels}
            await in_thread(functools.partial(self._set, job_id, state=JobState.running.value))
            return self.cluster.submit(self.task(), str(self.store.root), payload,
                                       key=f"relight-{self.kind}-{job_id}-{attempt}")

        async def wanted() -> bool:
            row = await in_thread(self._row, job_id)
            return row is not None and row.state in ACTIVE

        try:
            try:
                done, result = await run_with_resubmits(submit, wanted, name=f"{self.kind} {job_id}")
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # noqa: BLE001 - every failure is recorded; retryable ones may be resubmitted
                reason, retryable = failure_of(exc)
                log.warning("%s %s failed: %s", self.kind, job_id, reason)
                await in_thread(functools.partial(self._set, job_id, state=JobState.failed.value,
                                                  failure_reason=reason, retryable=int(retryable),
                                                  finished_at=utcnow()))
                return
            if done:
                await in_thread(functools.partial(self._set, job_id, state=JobState.succeeded.value, result=result,
                                                  failure_reason=None, finished_at=utcnow()))
        finally:
            if self._watchers.get(job_id) is me:
                del self._watchers[job_id]


def service_for(request: Request, attr: str, cls: type[AnalysisService]) -> Any:
    """The app's instance of ``cls``, created on first use from the app's services (one per process)."""
    svc = getattr(request.app.state, attr, None)
    if svc is None:
        services = request.app.state.services
        svc = cls(services.settings, services.db, services.store, services.cluster, services.envmaps, services.brdfs)
        setattr(request.app.state, attr, svc)
        svc.resume()
    return svc


class TradeoffService(AnalysisService):
    kind = "tradeoff"
    result_version = 2  # 2: Mitsuba 3 errors (points' mitsuba_error, meta.mitsuba)

    def task(self) -> Callable[..., Any]:
        from relight.worker.analysis import compute_tradeoff

        return compute_tradeoff

    def public(self, row: Analysis) -> TradeoffPublic:
        req = row.request
        result = row.result or {}
        links = {"self": f"/tradeoffs/{row.id}"}
        return TradeoffPublic(
            id=row.id, state=JobState(row.state), failure_reason=row.failure_reason, envmap=req["envmap"],
            brdf=req["brdf_id"], brdf_spec=req["brdf"], params=req["params"], points=result.get("points"),
            meta=result.get("meta"), created_at=utc(row.created_at), finished_at=aware(row.finished_at), links=links,
        )

    async def submit(self, create: TradeoffCreate) -> tuple[TradeoffPublic, int]:
        env = await self.envmaps.get(create.envmap)
        await self.envmaps.input_ok(env.id)
        brdf = await self.brdfs.resolve(create.brdf)
        if create.view is not None:
            n = sum(x * x for x in create.view) ** 0.5
            if n < 1e-12:
                raise Unprocessable("view: must be a non-zero vector")
            view: list[float] | None = [x / n for x in create.view]
        else:
            view = None
        rows = min(create.rows or 64, env.height)
        if create.size is not None and create.size > 4 * rows:
            raise Unprocessable(f"size: {create.size} is above 4 x rows = {4 * rows}")
        params = {"rows": rows, "size": create.size, "view": view,
                  "epsilons": sorted(set(create.epsilons), reverse=True) if create.epsilons else None,
                  "truncations": sorted(set(create.truncations), reverse=True) if create.truncations is not None
                  else None}
        request = {"envmap": env.id, "brdf_id": brdf.id, "brdf": brdf.spec, "params": params}
        row, status = await self.submit_request(request)
        return self.public(row), status

    async def get(self, job_id: str) -> TradeoffPublic:
        return self.public(await self.row(job_id))


async def tradeoff_service(request: Request) -> TradeoffService:
    svc: TradeoffService = service_for(request, "tradeoff_service", TradeoffService)
    return svc


# --------------------------------------------------------------------------------------------- cost model for /plan
_calibrating: dict[str, Any] = {}


def start_calibration(cluster: Cluster) -> None:
    """Calibrate the cost model once in a worker (``relight.worker.analysis.calibrate_costmodel``); call on the event
    loop.

    The worker writes the calibration file that ``relight.planning.plan_job`` reads on later calls.
    """
    if "future" in _calibrating:
        return
    from relight.worker.analysis import calibrate_costmodel

    try:
        _calibrating["future"] = cluster.submit(calibrate_costmodel, key="relight-costmodel-calibration")
    except RuntimeError as exc:  # the cluster is not started
        log.warning("could not start the cost-model calibration: %s", exc)
