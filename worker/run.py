"""``relight worker``: a Dask worker (under a nanny that restarts it) for an existing scheduler."""

from __future__ import annotations

import asyncio
import signal
from typing import Any


async def _serve(scheduler: str, *, nthreads: int, name: str | None, memory_limit: str, nanny: bool,
                 host: str | None) -> None:
    from distributed import Nanny, Worker

    cls: Any = Nanny if nanny else Worker
    kwargs: dict[str, Any] = {"nthreads": nthreads, "memory_limit": memory_limit, "dashboard": False,
                              "preload": ["relight.worker.preload"]}
    if name:
        kwargs["name"] = name
    if host:
        kwargs["host"] = host
    node = await cls(scheduler, **kwargs)
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    print(f"relight: worker {node.worker_address if nanny else node.address} connected to {scheduler}", flush=True)
    finished = asyncio.ensure_future(node.finished())
    waiter = asyncio.ensure_future(stop.wait())
    await asyncio.wait({finished, waiter}, return_when=asyncio.FIRST_COMPLETED)
    waiter.cancel()
    if not finished.done():
        await node.close(timeout=10)


def run_worker(scheduler: str, *, nthreads: int = 1, name: str | None = None, memory_limit: str = "auto",
               nanny: bool = True, host: str | None = None) -> None:
    """Connect to ``scheduler`` and run tasks until interrupted (the worker imports the core at start-up)."""
    asyncio.run(_serve(scheduler, nthreads=nthreads, name=name, memory_limit=memory_limit, nanny=nanny, host=host))
