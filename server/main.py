"""The FastAPI application factory (``uvicorn --factory server.main:create_app``, or ``relight serve``)."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware

import relight
from relight.server import problems
from relight.server.api.router import include_routes
from relight.server.config import Settings, get_settings
from relight.server.limits import BodyLimit
from relight.server.services.health import HealthEndpoint
from relight.server.state import Services
from relight.server.viewer import mount_viewer

DESCRIPTION = """\
Upload HDR environment maps, describe BRDFs, and get them prefiltered in frequency space into reflection maps and
Spherical Harmonic Reflection Maps (Ramamoorthi & Hanrahan 2002). Jobs run on Dask; results are content-addressed.
Errors are RFC 9457 problem details (`application/problem+json`).
"""


def create_app(settings: Settings | None = None, *, on_ready: Callable[[FastAPI], None] | None = None) -> FastAPI:
    settings = settings or get_settings()
    logging.getLogger("relight").setLevel(settings.log_level.upper())

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = await Services.start(settings)
        app.state.services = services
        if on_ready is not None:
            on_ready(app)
        try:
            yield
        finally:
            await services.stop()

    app = FastAPI(title="relight", version=relight.__version__, description=DESCRIPTION, lifespan=lifespan)
    app.state.settings = settings
    problems.install(app)
    app.add_middleware(HealthEndpoint)  # innermost: GET /health from the probes' pre-rendered answer, O(1)
    app.add_middleware(BodyLimit, settings=settings)  # inside CORS: its 401/413 answers carry the CORS headers
    if settings.cors_origins:
        app.add_middleware(
            CORSMiddleware, allow_origins=settings.cors_origins, allow_methods=["GET", "POST", "PUT", "DELETE"],
            allow_headers=["Authorization", "X-API-Key", "Content-Type", "If-None-Match"],
            expose_headers=["ETag", "Location", "Content-Location", "Retry-After"],
        )
    include_routes(app)
    mount_viewer(app)  # after the API routes: static paths never shadow them
    return app
