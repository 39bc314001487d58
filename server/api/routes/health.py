"""Liveness and metrics (never behind the API key)."""

from __future__ import annotations

from fastapi import APIRouter
from starlette.responses import PlainTextResponse

import relight
from relight.contract.models import Health
from relight.server.api.deps import ServicesDep
from relight.server.services.base import in_thread

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
async def health(services: ServicesDep) -> Health:
    """Service status: the database answers and how many Dask workers are connected."""

    def ping() -> str:
        from sqlalchemy import text

        with services.db.session() as s:
            s.execute(text("SELECT 1"))
        return services.db.dialect

    database = await in_thread(ping)
    workers = await services.cluster.n_workers()
    return Health(status="ok" if workers > 0 else "degraded", version=relight.__version__,
                  algorithm_version=relight.ALGORITHM_VERSION, scheduler=services.cluster.address, workers=workers,
                  database=database)


@router.get("/metrics", response_class=PlainTextResponse,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}}}})
async def metrics(services: ServicesDep) -> PlainTextResponse:
    """Prometheus text format: jobs by state, job durations, cache hits, submissions, runs."""
    counts = await services.jobs.counts()
    text = services.metrics.render(counts, await services.cluster.n_workers())
    return PlainTextResponse(text, media_type="text/plain; version=0.0.4; charset=utf-8")
