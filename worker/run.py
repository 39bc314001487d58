"""``relight worker`` (a Dask worker under a nanny that restarts it) and ``relight scheduler`` (a Dask scheduler) for
a scaled-out cluster.

With TLS files (:mod:`relight.worker.tls`) both speak only TLS and accept only peers with a certificate of the
cluster's CA; without them, plain TCP (for a trusted network only: whoever reaches a Dask scheduler runs code).
Neither keeps an HTTP endpoint: Dask starts an HTTP server on every scheduler and worker even without a dashboard
(metrics, call stacks, a health page); it is bound to loopback on a random port and stopped once the node is up
(the worker's by its preload, :mod:`relight.worker.preload`).
"""

from __future__ import annotations

import asyncio
import signal
from typing import Any

from relight.worker.tls import TlsFiles

#: Where Dask's HTTP server listens until it is stopped (loopback, any free port).
HTTP_UNTIL_STOPPED = "127.0.0.1:0"


async def _until_stopped(node: Any) -> None:
    """Wait for SIGINT/SIGTERM or for the node to finish on its own, then close it."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    finished = asyncio.ensure_future(node.finished())
    waiter = asyncio.ensure_future(stop.wait())
    await asyncio.wait({finished, waiter}, return_when=asyncio.FIRST_COMPLETED)
    waiter.cancel()
    if not finished.done():
        await node.close(timeout=10)


def _tls_scheme(address: str, tls: TlsFiles | None) -> None:
    if tls is not None and not address.startswith("tls://"):
        raise SystemExit(f"relight: with TLS files the scheduler address must be tls://..., not {address!r}")


async def _serve(scheduler: str, *, nthreads: int, name: str | None, memory_limit: str, nanny: bool,
                 host: str | None, tls: TlsFiles | None) -> None:
    from distributed import Nanny, Worker

    from relight.worker.slots import worker_options

    _tls_scheme(scheduler, tls)
    cls: Any = Nanny if nanny else Worker
    kwargs: dict[str, Any] = {**worker_options(nthreads), "memory_limit": memory_limit, "dashboard": False,
                              "dashboard_address": HTTP_UNTIL_STOPPED, "preload": ["relight.worker.preload"]}
    if name:
        kwargs["name"] = name
    if host:
        kwargs["host"] = host
    if tls is not None:
        kwargs |= {"security": tls.security(), "protocol": "tls"}
    node = await cls(scheduler, **kwargs)
    print(f"relight: worker {node.worker_address if nanny else node.address} connected to {scheduler}", flush=True)
    await _until_stopped(node)


def run_worker(scheduler: str, *, nthreads: int = 1, name: str | None = None, memory_limit: str = "auto",
               nanny: bool = True, host: str | None = None, tls: TlsFiles | None = None) -> None:
    """Connect to ``scheduler`` and run tasks until interrupted (the worker imports the core at start-up)."""
    asyncio.run(_serve(scheduler, nthreads=nthreads, name=name, memory_limit=memory_limit, nanny=nanny, host=host,
                       tls=tls))


async def _schedule(host: str, port: int, tls: TlsFiles | None) -> None:
    import dask
    from distributed import Scheduler

    from relight.worker.slots import SCHEDULER_CONFIG

    kwargs: dict[str, Any] = {"host": host, "port": port, "dashboard": False,
                              "dashboard_address": HTTP_UNTIL_STOPPED}
    if tls is not None:
        kwargs |= {"security": tls.security(), "protocol": "tls"}
    sched: Any = Scheduler
    with dask.config.set(SCHEDULER_CONFIG):  # read when the scheduler is made
        node = await sched(**kwargs)
    http = getattr(node, "http_server", None)
    if http is not None:
        http.stop()
    print(f"relight: scheduler at {node.address}", flush=True)
    await _until_stopped(node)


def run_scheduler(host: str = "0.0.0.0", port: int = 8786, tls: TlsFiles | None = None) -> None:  # noqa: S104
    """Run a Dask scheduler (TLS when ``tls`` is given, no HTTP endpoint) until interrupted."""
    asyncio.run(_schedule(host, port, tls))
