"""The registry of job kinds: what the one job system (:mod:`relight.server.services.jobs`) needs to know about a kind.

A kind is a task function in ``worker/`` (``task(ctx, request) -> result``, :data:`relight.worker.progress.Task`)
plus a :class:`JobKind` registered here. Everything else is shared by every kind: the row in the job table, the id
(the SHA-256 of the canonical request, :meth:`JobKind.job_id`), submission to Dask through
:func:`relight.worker.progress.run_job`, progress, ``GET /jobs/{id}``, ``GET /jobs/{id}/events`` (SSE),
``DELETE /jobs/{id}``, the active-job cap and recovery at start-up. ``server/README.md`` shows a registration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import relight
from relight.server.db import Job
from relight.server.services.base import content_id
from relight.worker.progress import Task

#: ``links(job_id, result)``: result links of a succeeded job, added to its ``links``.
Links = Callable[[str, dict[str, Any] | None], dict[str, str]]
#: ``store_result(row, result)``: put the task's result on the (still active) row, in the writer's transaction.
StoreResult = Callable[[Job, dict[str, Any]], None]


def keep_result(row: Job, result: dict[str, Any]) -> None:
    """The default: the task's (small, JSON) result is the row's ``result``."""
    row.result = result


def no_links(job_id: str, result: dict[str, Any] | None) -> dict[str, str]:
    return {}


@dataclass(frozen=True)
class JobKind:
    """One kind of job (module docstring)."""

    name: str
    task: Task
    #: Version of this kind's result format, part of its ids: a result stored in an older format is never served
    #: for a new request (it is computed again under the new id).
    result_version: int = 1
    links: Links = field(default=no_links)
    store_result: StoreResult = field(default=keep_result)

    def job_id(self, request: dict[str, Any]) -> str:
        """SHA-256 of (kind, algorithm version, result version, canonical request): identical requests share a job."""
        return content_id({"task": self.name, "algorithm_version": relight.ALGORITHM_VERSION,
                           "result_version": self.result_version, "request": request})


_REGISTRY: dict[str, JobKind] = {}


def register(kind: JobKind) -> JobKind:
    """Add ``kind`` (once per name; registering the same definition again is harmless)."""
    known = _REGISTRY.get(kind.name)
    if known is not None and known != kind:
        raise ValueError(f"a different job kind named {kind.name!r} is registered already")
    _REGISTRY[kind.name] = kind
    return kind


def kind_of(name: str) -> JobKind:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"no job kind {name!r} is registered (known: {', '.join(sorted(_REGISTRY))})") from None


def kinds() -> list[str]:
    return sorted(_REGISTRY)
