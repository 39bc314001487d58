"""Dask preload module (``preload=["relight.worker.preload"]``): imports the numerical core when a worker process
starts,
so the first job does not pay for it, and stops the worker's HTTP server (nothing but the scheduler talks to a
worker)."""

from __future__ import annotations

from typing import Any

from relight.worker.tasks import warmup


def dask_setup(worker: Any) -> None:
    """Stop the worker's HTTP server (Dask starts one even without a dashboard: metrics, call stacks), then warm
    up."""
    http = getattr(worker, "http_server", None)
    if http is not None:
        http.stop()
    warmup()
