"""TEST ONLY fault-injection points (issue 12, item 5): a job can be held at the points where a crash matters, so
a test kills a worker, the server or the scheduler exactly there instead of racing a sleep.

Off in production: without ``RELIGHT_TEST_FAULT_DIR`` every call here returns at once. The points, in the order a
job passes them:

* ``compute`` — in the worker, inside the job's computation: the result is in memory, nothing is written yet
  (:func:`relight.worker.tasks.compute_shrm`);
* ``blobs_written`` — in the worker, after the result's blobs are stored and before the ref naming them is recorded
  (:func:`relight.worker.results.write_result`);
* ``before_commit`` — in the server, after the worker's result has arrived and before the job row is updated
  (:class:`relight.server.services.jobs.JobService`).

The file ``<dir>/armed`` names the one point armed (a test re-arms without restarting anything). A process
reaching it writes ``<dir>/<point>.reached`` (the job id and its pid, so a test knows whom to kill) and waits until
``<dir>/<point>.release`` exists (at most :data:`MAX_WAIT_S`); with the release file present the point is passed
without waiting, so the run after a kill goes through. Worker processes read the same variable (the embedded
cluster's inherit the server's environment).
"""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Final

POINTS: Final = ("compute", "blobs_written", "before_commit")
DIR_ENV: Final = "RELIGHT_TEST_FAULT_DIR"
#: A held job is let go after this long even without a release (a test that died must not hang a worker for ever).
MAX_WAIT_S: Final = 300.0
POLL_S: Final = 0.05


def _armed(point: str) -> tuple[Path, Path] | None:
    """(reached marker, release marker) when ``point`` is armed and not released yet, else None."""
    if point not in POINTS:
        raise ValueError(f"unknown fault point {point!r} (one of {', '.join(POINTS)})")
    folder = os.environ.get(DIR_ENV)
    if not folder:
        return None
    try:
        if (Path(folder) / "armed").read_text().strip() != point:
            return None
    except FileNotFoundError:
        return None
    release = Path(folder) / f"{point}.release"
    if release.exists():
        return None
    return Path(folder) / f"{point}.reached", release


def _mark(reached: Path, job_id: str) -> None:
    tmp = reached.with_name(f"{reached.name}.{os.getpid()}.tmp")
    tmp.write_text(f"{job_id} {os.getpid()}\n")
    os.replace(tmp, reached)  # a test polling for the marker never reads half of it


def pause(point: str, job_id: str, check: Callable[[], None] | None = None) -> None:
    """Hold here while ``point`` is armed (module docstring); ``check()`` runs every poll (it may raise, e.g. on a
    cancellation)."""
    armed = _armed(point)
    if armed is None:
        return
    reached, release = armed
    _mark(reached, job_id)
    deadline = time.monotonic() + MAX_WAIT_S
    while not release.exists() and time.monotonic() < deadline:
        if check is not None:
            check()
        time.sleep(POLL_S)


async def apause(point: str, job_id: str) -> None:
    """:func:`pause` for the server's event loop (never blocks it)."""
    armed = _armed(point)
    if armed is None:
        return
    reached, release = armed
    _mark(reached, job_id)
    deadline = time.monotonic() + MAX_WAIT_S
    while not release.exists() and time.monotonic() < deadline:
        await asyncio.sleep(POLL_S)


__all__ = ["POINTS", "apause", "pause"]
