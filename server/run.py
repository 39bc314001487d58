"""Run the server with uvicorn on a socket bound here (so ``--port 0`` works and the URL is known).

For an operator looking at a server that hangs: ``kill -USR1 PID`` writes every thread's stack to stderr
(:mod:`faulthandler`), ``kill -USR2 PID`` every pending asyncio task's stack (what each request is awaiting).
"""

from __future__ import annotations

import asyncio
import faulthandler
import gc
import signal
import socket
import sys
from types import FrameType
from typing import Any

import uvicorn
from fastapi import FastAPI

from relight.server.config import Settings
from relight.server.limits import BoundedHttpToolsProtocol
from relight.server.main import create_app
from relight.server.services.metrics import GcPauses


class RelightServer(uvicorn.Server):
    """uvicorn's server that also ends every open event stream when asked to stop (SIGTERM, SIGINT): a stream
    would otherwise hold the graceful shutdown for its whole timeout and then be cancelled with a traceback
    (:meth:`relight.server.services.events.EventHub.close`)."""

    def __init__(self, config: uvicorn.Config) -> None:
        super().__init__(config)
        self.on_exit: list[Any] = []  # (loop, callback) pairs registered once the app has started

    def handle_exit(self, sig: int, frame: FrameType | None) -> None:
        super().handle_exit(sig, frame)
        for loop, callback in self.on_exit:
            loop.call_soon_threadsafe(callback)  # a signal handler runs between bytecodes: hand it to the loop


def _awaiting(coro: Any) -> list[str]:
    """Where a suspended coroutine waits: the chain of coroutines it awaits, innermost last."""
    where: list[str] = []
    while coro is not None and len(where) < 40:
        frame = getattr(coro, "cr_frame", None) or getattr(coro, "gi_frame", None)
        if frame is not None:
            where.append(f"  {frame.f_code.co_filename}:{frame.f_lineno} in {frame.f_code.co_name}")
        coro = getattr(coro, "cr_await", None) or getattr(coro, "gi_yieldfrom", None)
    return where


def dump_tasks(cluster: Any = None) -> None:
    """Every pending asyncio task of the running loop and the chain of awaits it is suspended in, then the embedded
    Dask scheduler's workers and unfinished tasks, to stderr."""
    tasks = asyncio.all_tasks()
    lines = [f"relight: {len(tasks)} asyncio tasks"]
    for task in tasks:
        lines.append(f"task {task.get_name()}:")
        lines += _awaiting(task.get_coro())
    if cluster is not None:
        lines += ["relight: Dask scheduler", *cluster.describe()]
    print("\n".join(lines), file=sys.stderr, flush=True)


def settle_heap(pauses: GcPauses, freeze: bool = True) -> None:
    """Move every object alive once the server has started (modules, the app, the Dask scheduler, the database
    engine: about 150 000 objects) out of the cyclic garbage collector's reach (:func:`gc.freeze`), so that its
    full collections scan only what requests create. Without it each full collection held the GIL, and with it the
    event loop, for 20-150 ms under load (15 in a 40 s ``bench/health.py`` run): the slow tail of ``/health``.
    The collector's pauses from then on are ``relight_gc_pause_seconds`` in ``/metrics``."""
    if freeze:
        gc.collect()
        gc.freeze()
    pauses.start()


def serve(settings: Settings, host: str = "127.0.0.1", port: int = 8000) -> None:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
    bound_port = sock.getsockname()[1]
    shown = f"[{host}]" if family == socket.AF_INET6 else host
    url = f"http://{shown}:{bound_port}"

    def ready(app: FastAPI) -> None:
        services = app.state.services
        loop = asyncio.get_running_loop()
        server.on_exit.append((loop, services.hub.close))
        loop.add_signal_handler(signal.SIGUSR2, dump_tasks, services.cluster)
        settle_heap(services.metrics.gc, settings.gc_freeze)
        print(f"relight: serving {url} (data {settings.data_dir.resolve()}, Dask {services.cluster.address})",
              flush=True)

    faulthandler.register(signal.SIGUSR1, all_threads=True)
    app = create_app(settings, on_ready=ready)
    config = uvicorn.Config(app, log_level=settings.log_level.lower() if settings.log_level else "info",
                            access_log=False, lifespan="on", timeout_graceful_shutdown=5,
                            http=BoundedHttpToolsProtocol)
    server = RelightServer(config)
    try:
        server.run(sockets=[sock])
    finally:
        sock.close()
    if not server.started:
        sys.exit(1)
