"""Accuracy–time sweeps as jobs (``POST /tradeoffs``, the ``tradeoff`` job kind).

* **Sweeps.** A tradeoff is identified by the SHA-256 of its canonical request (with ``relight.ALGORITHM_VERSION``
  and the kind's result version, :meth:`relight.server.services.kinds.JobKind.job_id`); it runs as a job of the one
  job system (:class:`relight.server.services.jobs.JobService`: progress, SSE, cancel, the cap, recovery) with the
  task :func:`relight.worker.analysis.compute_tradeoff`, whose small JSON result is stored on the job's row.
  Identical requests share the job (200 with the result once it exists).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

from relight.contract.models import TradeoffCreate, TradeoffPublic
from relight.server.db import Job
from relight.server.problems import Unprocessable
from relight.server.services.base import aware, utc
from relight.server.services.brdfs import BrdfService
from relight.server.services.envmaps import EnvmapService
from relight.server.services.jobs import JobService
from relight.server.services.kinds import JobKind, register
from relight.worker.analysis import compute_tradeoff

if TYPE_CHECKING:
    from relight.server.state import Services

#: Server-side caps of a sweep (each point runs both an SHRM and an angular reference).
MAX_TRADEOFF_ROWS: Final = 256


async def _prepare(create: TradeoffCreate, services: Services) -> dict[str, Any]:
    return await services.tradeoffs.canonical(create)


TRADEOFF = register(JobKind(
    "tradeoff", compute_tradeoff, request=TradeoffCreate, prepare=_prepare,
    result_version=2,  # 2: Mitsuba 3 errors (points' mitsuba_error, meta.mitsuba)
    links=lambda job_id, result: {"result": f"/tradeoffs/{job_id}"},
))


class TradeoffService:
    def __init__(self, jobs: JobService, envmaps: EnvmapService, brdfs: BrdfService) -> None:
        self.jobs = jobs
        self.envmaps = envmaps
        self.brdfs = brdfs

    def public(self, row: Job) -> TradeoffPublic:
        req = row.request
        result = row.result or {}
        job = self.jobs.public(row)
        links = {"self": f"/tradeoffs/{row.id}", "job": f"/jobs/{row.id}", "events": f"/jobs/{row.id}/events"}
        return TradeoffPublic(
            id=row.id, state=job.state, stage=job.stage, progress=job.progress, failure_reason=row.failure_reason,
            envmap=req["envmap"], brdf=req["brdf_id"], brdf_spec=req["brdf"], params=req["params"],
            points=result.get("points"), meta=result.get("meta"), created_at=utc(row.created_at),
            finished_at=aware(row.finished_at), links=links,
        )

    async def canonical(self, create: TradeoffCreate) -> dict[str, Any]:
        """The canonical request of ``create`` (the map checked, the BRDF resolved, defaults and orders fixed)."""
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
        return {"envmap": env.id, "brdf_id": brdf.id, "brdf": brdf.spec, "params": params}

    async def submit(self, create: TradeoffCreate) -> tuple[TradeoffPublic, int]:
        row, status = await self.jobs.submit(TRADEOFF, await self.canonical(create))
        return self.public(row), status

    async def get(self, job_id: str) -> TradeoffPublic:
        return self.public(await self.jobs.row(job_id, TRADEOFF.name))
