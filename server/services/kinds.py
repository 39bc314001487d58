"""The registry of job kinds: what the one job system (:mod:`relight.server.services.jobs`) needs to know about a kind.

A kind is a task function in ``worker/`` (``task(ctx, request) -> result``, :data:`relight.worker.progress.Task`)
plus a :class:`JobKind` registered here. Everything else is shared by every kind: submission through
``POST /jobs`` (``{"kind": ..., "request": {...}}``: the request validated by the kind's pydantic model
:attr:`JobKind.request`, made canonical by :attr:`JobKind.prepare`), the row in the job table, the id (the SHA-256
of the canonical request, :meth:`JobKind.job_id`), submission to Dask through :func:`relight.worker.progress.run_job`,
progress, ``GET /jobs/{id}``, ``GET /jobs/{id}/events`` (SSE), ``GET /jobs/{id}/result`` and
``GET /jobs/{id}/files/{name}``, ``DELETE /jobs/{id}``, the active-job cap and recovery at start-up.
``server/README.md`` shows a registration.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel

import relight
from relight.contract.models import Measurement
from relight.server.db import Job, utcnow
from relight.server.services.base import aware, content_id
from relight.worker.progress import Task

if TYPE_CHECKING:
    from relight.server.state import Services

#: ``links(job_id, result)``: result links of a succeeded job, added to its ``links``.
Links = Callable[[str, dict[str, Any] | None], dict[str, str]]
#: ``store_result(row, result)``: put the task's result on the (still active) row, in the writer's transaction.
StoreResult = Callable[[Job, dict[str, Any]], None]


@dataclass(frozen=True)
class Submission:
    """What :attr:`JobKind.prepare` may return instead of a plain canonical request.

    ``job_id`` overrides the kind's id rule; ``predicted`` (JSON) is stored on a new row; ``intact(row)`` says
    whether a succeeded job's stored result is still usable (else the job is computed again).
    """

    request: dict[str, Any]
    job_id: str | None = None
    predicted: dict[str, Any] | None = None
    intact: Callable[[Job], Awaitable[bool]] | None = None


#: ``prepare(create, services)``: the validated request model -> the canonical request (or a :class:`Submission`).
#: Resolve references here (an envmap id that must exist, a BRDF written three ways): 4xx problems raised here
#: reach the client as they are.
Prepare = Callable[[Any, "Services"], Awaitable["dict[str, Any] | Submission"]]


def measurement(row: Job, result: dict[str, Any]) -> dict[str, Any]:
    """The row's ``measured`` record from a task's timings: the wall time since the first submission, and the
    result's ``task_seconds``, ``compute_seconds`` and ``stage_seconds`` (name -> seconds) where it has them.
    Timings live here and in the row's result, never in a stored file: a file computed again is byte-identical."""
    submitted = aware(row.submitted_at) or utcnow()
    stages = result.get("stage_seconds")

    def seconds(key: str) -> float | None:
        value = result.get(key)
        return float(value) if isinstance(value, int | float) else None

    return Measurement(
        seconds=(utcnow() - submitted).total_seconds(), task_seconds=seconds("task_seconds"),
        compute_seconds=seconds("compute_seconds"),
        stage_seconds={str(k): float(v) for k, v in stages.items() if isinstance(v, int | float)}
        if isinstance(stages, dict) else None,
    ).model_dump(mode="json")


def keep_result(row: Job, result: dict[str, Any]) -> None:
    """The default: the task's (small, JSON) result is the row's ``result``; its timings are also the row's
    ``measured`` record (:func:`measurement`)."""
    row.result = result
    row.measured = measurement(row, result)


def job_links(job_id: str, result: dict[str, Any] | None) -> dict[str, str]:
    """The default links of a succeeded job: its result, and each file a result lists under ``files``
    (``{name: {"sha256": ..., "media_type": ...}}``, served verified by ``GET /jobs/{id}/files/{name}``)."""
    links = {"result": f"/jobs/{job_id}/result"}
    for name in ((result or {}).get("files") or {}):
        links[name] = f"/jobs/{job_id}/files/{name}"
    return links


async def dump_request(create: BaseModel, services: Services) -> dict[str, Any]:
    """The default :attr:`JobKind.prepare`: the validated model as JSON (defaults filled in, so that two ways of
    writing one request share one id)."""
    return create.model_dump(mode="json")


@dataclass(frozen=True)
class JobKind:
    """One kind of job (module docstring)."""

    name: str
    task: Task
    #: The pydantic model ``POST /jobs`` validates the kind's ``request`` with (None: no generic submission; the
    #: kind is submitted by its own service).
    request: type[BaseModel] | None = None
    prepare: Prepare = field(default=dump_request)
    #: Version of this kind's result format, part of its ids: a result stored in an older format is never served
    #: for a new request (it is computed again under the new id).
    result_version: int = 1
    links: Links = field(default=job_links)
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


def links_of(name: str) -> Links:
    """The links rule of the kind ``name``; the default one for a kind this process does not know (a row written by
    a server that loaded a plugin this one does not: it is still listed)."""
    known = _REGISTRY.get(name)
    return known.links if known is not None else job_links
