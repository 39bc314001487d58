"""Dask preload module (``preload=["relight.worker.preload"]``): imports the numerical core when a worker process
starts,
so the first job does not pay for it."""

from __future__ import annotations

from typing import Any

from relight.worker.tasks import warmup


def dask_setup(worker: Any) -> None:
    warmup()
