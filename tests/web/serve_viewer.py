"""Run the relight service *with the viewer* for the browser tests and the benchmark.

``python -m tests.web.serve_viewer --data DIR [--port 0]`` builds the app with ``relight.server.main.create_app``
and, if
the lead has not wired them in yet, adds the render router (``server/api/routes/render.py``, behind the API key
like the other routes) and ``relight.server.viewer.mount_viewer``. It prints ``relight: serving http://host:port`` once
ready (the line ``tests/service/conftest.py`` waits for). Settings come from ``RELIGHT_*`` variables.
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path

import uvicorn
from fastapi import FastAPI

from relight.server.config import Settings


def build_app(settings: Settings, on_ready: object = None) -> FastAPI:
    from relight.server.api.deps import ApiKey
    from relight.server.api.routes import render
    from relight.server.main import create_app
    from relight.server.viewer import mount_viewer

    app = create_app(settings, on_ready=on_ready)  # type: ignore[arg-type]
    paths = {getattr(r, "path", None) for r in app.routes}
    if "/shrms/{shrm_id}/render.{fmt}" not in paths:
        app.include_router(render.router, dependencies=[ApiKey])
    if "/" not in paths:
        mount_viewer(app)
    return app


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args(argv)
    settings = Settings(data_dir=args.data)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((args.host, args.port))
    url = f"http://{args.host}:{sock.getsockname()[1]}"

    def ready(app: FastAPI) -> None:
        print(f"relight: serving {url}", flush=True)

    app = build_app(settings, ready)
    config = uvicorn.Config(app, log_level=settings.log_level.lower(), access_log=False, lifespan="on",
                            timeout_graceful_shutdown=5)
    server = uvicorn.Server(config)
    try:
        server.run(sockets=[sock])
    finally:
        sock.close()
    if not server.started:
        sys.exit(1)


if __name__ == "__main__":
    main()
