"""Running one task on the Dask cluster for a stored job: what SHRM jobs (:mod:`relight.server.services.jobs`) and
analysis
jobs (:mod:`relight.server.services.tradeoffs`: sweeps, scenes) share.

* :func:`run_with_resubmits` — submit, await, and submit again when the future is lost (the scheduler connection
  dropped, or the cluster restarted) while the job is still wanted, with a capped exponential back-off; after
  :data:`MAX_RESUBMITS` losses the job fails (retryable).
* :func:`failure_of` — the reason stored on a failed job and whether submitting it again may succeed: bad input
  never does; a worker that died repeatedly (memory), a cancellation or any other error may.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import re
from collections.abc import Awaitable, Callable
from typing import Any, Final

from distributed.client import FutureCancelledError
from distributed.scheduler import KilledWorker

from relight.errors import InputError
from relight.worker.progress import JobCancelled

log = logging.getLogger("relight.server")

#: How a full disk reads in errors that are not an ``OSError``: OpenEXR's writer raises ``RuntimeError("Failed to
#: write pixel data to image file \"<path>\". No space left on device.")`` (found by the real full-disk test).
DISK_FULL_TEXTS: Final = ("No space left on device", "Disk quota exceeded")
#: Absolute paths in an error's text (a server's store, its temporary files): never shown to a client (issue 12).
PATH_RE: Final = re.compile(r"(?<![\w.:/])/(?:[\w.@+-]+/)+[\w.@+-]*")
#: Resubmissions after the scheduler connection was lost, before the job is marked failed (retryable).
MAX_RESUBMITS: Final = 5


class SchedulerLost(RuntimeError):
    """The task's future was lost more than :data:`MAX_RESUBMITS` times."""


async def run_with_resubmits(
    submit: Callable[[int], Awaitable[Any | None]], wanted: Callable[[], Awaitable[bool]], *, name: str
) -> tuple[bool, Any]:
    """Run a task to its end: ``(True, result)``, or ``(False, None)`` when the job stopped being wanted.

    ``submit(attempt)`` submits the task (and records the submission) and returns its future, or None when the job
    is no longer to be run. A lost future (``FutureCancelledError``) is submitted again while ``wanted()`` says the
    job is still active (a user's cancellation makes it not). The task's own exception propagates;
    :class:`SchedulerLost` after too many losses.
    """
    for attempt in range(MAX_RESUBMITS + 1):
        fut = await submit(attempt)
        if fut is None:
            return False, None
        try:
            return True, await fut
        except FutureCancelledError as exc:
            if not await wanted():
                return False, None
            log.warning("%s: Dask future lost (%s); resubmitting (attempt %d)", name, exc.reason, attempt + 1)
            await asyncio.sleep(min(2.0**attempt, 10.0))
    raise SchedulerLost(f"lost the Dask scheduler {MAX_RESUBMITS + 1} times")


def failure_of(exc: BaseException) -> tuple[str, bool]:
    """(reason, retryable) of a failed task (module docstring)."""
    if isinstance(exc, InputError):
        return str(exc), False
    if isinstance(exc, KilledWorker):
        return (f"the worker process running the job died repeatedly ({exc}); the job may exceed the worker memory "
                "limit"), True
    if isinstance(exc, JobCancelled | SchedulerLost):
        return str(exc), True
    if (isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)) \
            or any(text in str(exc) for text in DISK_FULL_TEXTS):
        return "the blob store is full (no space left on its device); resubmit once space is freed", True
    return PATH_RE.sub("<path>", f"{type(exc).__name__}: {exc}"), True
