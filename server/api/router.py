"""All routes; everything but health and metrics sits behind the (optional) API key."""

from __future__ import annotations

from fastapi import FastAPI

from relight.server.api.deps import ApiKey
from relight.server.api.routes import (
    brdfs,
    envmaps,
    gaussian,
    health,
    ibl,
    jobs,
    meshes,
    plan,
    render,
    scenes,
    shrms,
    tradeoffs,
    visibility,
)


def include_routes(app: FastAPI) -> None:
    """One level of routers (nesting routers costs a matching pass per level on every request)."""
    app.include_router(health.router)
    for r in (envmaps.router, brdfs.router, plan.router, shrms.router, jobs.router, tradeoffs.router, scenes.router,
              render.router, meshes.router, visibility.router, ibl.router, gaussian.router):
        app.include_router(r, dependencies=[ApiKey])
