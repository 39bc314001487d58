"""The Dask side of the server: an embedded ``LocalCluster`` or a connection to an existing scheduler.

Embedded (no ``RELIGHT_SCHEDULER``): worker *processes* bound to 127.0.0.1, no dashboards, each with a memory
limit; the scheduler lives in the server process. Whoever can talk to a Dask scheduler can run code in the cluster,
so the embedded one speaks TLS with temporary certificates that exist only in the server's memory and its workers'
(``security=True``: Dask's ``Security.temporary``); its address is not published (``/health``), and the HTTP
servers Dask starts even with dashboards off are stopped (the scheduler's here, the workers' in
:mod:`relight.worker.preload`). Scale-out: ``RELIGHT_SCHEDULER=tls://host:8786`` connects to
a running scheduler (``relight scheduler``) whose workers were started with ``relight worker --scheduler ...``,
with the cluster's certificate (``RELIGHT_TLS_CA_FILE``, ``RELIGHT_TLS_CERT``, ``RELIGHT_TLS_KEY``:
:mod:`relight.worker.tls`); ``tcp://`` without them, for a trusted network only.

Every function submitted is a task function of ``relight.worker`` (:meth:`Cluster.submit` refuses anything else):
the workers' entry points live in ``worker/``, thin wrappers over the core where needed.

The client is asynchronous and shares the server's event loop. Dask's classes are untyped; they are held as
``Any`` here, the one module that talks to Dask directly.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

import dask
from distributed import Client, LocalCluster

from relight.server.config import Settings
from relight.worker.slots import SCHEDULER_CONFIG, task_options, worker_options

log = logging.getLogger("relight.server")

#: Worker deaths a task survives before Dask gives up on it (KilledWorker). One death is rescheduled (a lost
#: worker must not fail a job); a second points at the task itself (e.g. an input that crashes the decoder).
ALLOWED_FAILURES = 1
START_TIMEOUT_S = 60.0
#: The package whose functions the server may submit (the worker's entry points).
WORKER_PACKAGE = "relight.worker"


class Cluster:
    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.local: Any = None  # distributed.LocalCluster
        self._client: Any = None  # distributed.Client (asynchronous)

    @property
    def client(self) -> Any:
        if self._client is None:
            raise RuntimeError("the Dask client is not started")
        return self._client

    @property
    def address(self) -> str:
        return self.settings.scheduler or (self.local.scheduler_address if self.local else "not started")

    async def start(self) -> None:
        s = self.settings
        if s.scheduler:
            from relight.worker.tls import TlsFiles

            tls = TlsFiles.of(s.tls_ca_file, s.tls_cert, s.tls_key)
            if tls is not None and not s.scheduler.startswith("tls://"):
                raise ValueError(f"RELIGHT_SCHEDULER must be tls://... with RELIGHT_TLS_* set, not {s.scheduler!r}")
            client: Any = Client
            self._client = await asyncio.wait_for(
                client(s.scheduler, asynchronous=True, timeout=START_TIMEOUT_S,
                       security=tls.security() if tls is not None else None), START_TIMEOUT_S
            )
        else:
            local: Any = LocalCluster
            slots = worker_options(s.threads_per_worker)
            with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES, **SCHEDULER_CONFIG}):
                self.local = await local(
                    n_workers=s.n_workers,
                    # job slots + one thread for interactive tasks (LocalCluster's name for nthreads is
                    # threads_per_worker: an nthreads keyword would be overwritten)
                    threads_per_worker=slots["nthreads"],
                    resources=slots["resources"],
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                    worker_dashboard_address=None,
                    memory_limit=s.worker_memory_limit,
                    preload=["relight.worker.preload"],
                    security=True,  # temporary TLS certificates, in memory: no other process can join or submit
                    asynchronous=True,
                )
            self.local.scheduler.http_server.stop()  # Dask starts it even without a dashboard
            client = Client
            self._client = await client(self.local, asynchronous=True)
        log.info("Dask scheduler %s", self.address)

    def subscribe(self, topic: str, handler: Callable[[Any], None]) -> None:
        self.client.subscribe_topic(topic, handler)

    def submit(self, fn: Callable[..., Any], *args: Any, key: str, job: bool = False, **kwargs: Any) -> Any:
        """A ``distributed.Future`` (awaitable) for ``fn(*args, **kwargs)`` under ``key``; ``fn`` must be defined in
        ``relight.worker`` (TypeError otherwise). ``job``: a job task, which takes one of a worker's job slots;
        otherwise an interactive one, which runs ahead of queued jobs on the thread kept free of them
        (:mod:`relight.worker.slots`)."""
        module = getattr(fn, "__module__", None) or ""
        if module != WORKER_PACKAGE and not module.startswith(WORKER_PACKAGE + "."):
            raise TypeError(f"{getattr(fn, '__qualname__', fn)!r} of {module or 'no module'!r} is not a task of "
                            f"{WORKER_PACKAGE}: Dask callables live in worker/ (wrap the core function there)")
        return self.client.submit(fn, *args, key=key, pure=False, retries=0, **task_options(job=job), **kwargs)

    async def cancel(self, future: Any) -> None:
        await self.client.cancel([future], force=True)

    async def n_workers(self) -> int:
        info = await self.client.scheduler.identity(n_workers=-1)
        return len(info.get("workers", {}))

    async def restart_worker(self, address: str) -> None:
        try:
            await self.client.restart_workers([address], timeout=30, raise_for_error=False)
        except (OSError, TimeoutError, ValueError) as exc:
            log.warning("could not restart worker %s: %s", address, exc)

    def describe(self) -> list[str]:
        """The embedded scheduler's workers (status, threads, resources, tasks processing) and every task not yet in
        memory (state, where it runs or waits), for an operator's dump (:func:`relight.server.run.dump_tasks`);
        nothing for an external scheduler (ask it with ``dask`` tools)."""
        if self.local is None:
            return []
        sched = self.local.scheduler
        lines = [f"worker {ws.address} status={ws.status.name} nthreads={ws.nthreads} used={dict(ws.used_resources)}"
                 f" processing={sorted(t.key for t in ws.processing)} memory={ws.memory.process >> 20} MiB"
                 for ws in sched.workers.values()]
        lines += [f"task {ts.key} state={ts.state} priority={ts.priority} "
                  f"on={getattr(ts.processing_on, 'address', None)} resources={ts.resource_restrictions}"
                  for ts in sched.tasks.values()
                  if ts.state not in ("memory", "forgotten", "released", "erred")]
        return lines

    async def close(self) -> None:
        if self._client is not None:
            try:
                await asyncio.wait_for(self._client.close(), 10)
            except (TimeoutError, OSError) as exc:
                log.warning("closing the Dask client: %s", exc)
            self._client = None
        if self.local is not None:
            try:
                await asyncio.wait_for(self.local.close(), 20)
            except (TimeoutError, OSError) as exc:
                log.warning("closing the embedded cluster: %s", exc)
            self.local = None
