"""Liveness and metrics (never behind the API key)."""

from __future__ import annotations

from fastapi import APIRouter
from starlette.responses import PlainTextResponse

from relight.contract.models import Health
from relight.server.api.deps import ServicesDep

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
async def health(services: ServicesDep) -> Health:
    """Service status: ``ok``, or ``degraded`` with the reasons in ``problems`` (no workers, the scheduler lost,
    the database not answering, the blob store's disk full or not answering, the probes themselves stuck). Answered
    from the background probes' last round (``probed_at``; :mod:`relight.server.services.health`), so it does no
    work under load. The scheduler's address is not published: whoever reaches a Dask scheduler can run code in
    the cluster."""
    return services.health.health()  # the app's HealthEndpoint answers first with the same JSON, pre-rendered


@router.get("/metrics", response_class=PlainTextResponse,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}}}})
async def metrics(services: ServicesDep) -> PlainTextResponse:
    """Prometheus text format: jobs by state, job durations, cache hits, submissions, runs."""
    counts = await services.jobs.counts()
    text = services.metrics.render(counts, await services.cluster.n_workers())
    return PlainTextResponse(text, media_type="text/plain; version=0.0.4; charset=utf-8")
