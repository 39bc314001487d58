"""Liveness and metrics (never behind the API key)."""

from __future__ import annotations

import asyncio
import shutil
from concurrent.futures import ThreadPoolExecutor

from fastapi import APIRouter
from starlette.responses import PlainTextResponse

import relight
from relight.contract.models import Health
from relight.server.api.deps import ServicesDep

router = APIRouter(tags=["health"])


#: Seconds each health probe (database, scheduler) may take before it counts as failed.
PROBE_TIMEOUT_S = 2.0
#: The database probe's own thread: a flood of requests holding the shared thread pool cannot delay /health.
_PROBE_THREAD = ThreadPoolExecutor(1, thread_name_prefix="relight-health")


@router.get("/health", response_model=Health)
async def health(services: ServicesDep) -> Health:
    """Service status: ``ok``, or ``degraded`` with the reasons in ``problems`` (no workers, the scheduler lost,
    the database not answering, the blob store's disk full). The scheduler's address is not published: whoever
    reaches a Dask scheduler can run code in the cluster."""

    def ping() -> str:
        from sqlalchemy import text

        with services.db.session() as s:
            s.execute(text("SELECT 1"))
        return services.db.dialect

    problems: list[str] = []
    loop = asyncio.get_running_loop()
    database = services.db.dialect
    try:
        await asyncio.wait_for(loop.run_in_executor(_PROBE_THREAD, ping), PROBE_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - any failure of the probe is a degraded database
        problems.append(f"database: not answering ({type(exc).__name__})")
    workers = 0
    try:
        workers = await asyncio.wait_for(services.cluster.n_workers(), PROBE_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - any failure of the probe means the scheduler is unreachable
        problems.append(f"scheduler: lost ({type(exc).__name__})")
    else:
        if workers == 0:
            problems.append("workers: none connected")
    free = shutil.disk_usage(services.store.root).free
    if free < services.settings.min_free_bytes:
        problems.append(f"disk: {free} bytes free in the blob store, below {services.settings.min_free_bytes}")
    return Health(status="degraded" if problems else "ok", version=relight.__version__,
                  algorithm_version=relight.ALGORITHM_VERSION,
                  scheduler="external" if services.settings.scheduler else "embedded", workers=workers,
                  database=database, problems=problems)


@router.get("/metrics", response_class=PlainTextResponse,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}}}})
async def metrics(services: ServicesDep) -> PlainTextResponse:
    """Prometheus text format: jobs by state, job durations, cache hits, submissions, runs."""
    counts = await services.jobs.counts()
    text = services.metrics.render(counts, await services.cluster.n_workers())
    return PlainTextResponse(text, media_type="text/plain; version=0.0.4; charset=utf-8")
