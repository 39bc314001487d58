"""Any registered job kind through the generic routes: ``POST /jobs`` (``{"kind": ..., "request": {...}}``),
``GET /jobs/{id}/result`` and ``GET /jobs/{id}/files/{name}`` (:mod:`relight.server.services.kinds`).

The request is validated by the kind's pydantic model, made canonical by the kind's ``prepare`` and submitted
through the one job system (:meth:`relight.server.services.jobs.JobService.submit`): the same id rule, deduplication,
active-job cap (429) and 202/200 answers as the kinds' own routes (``POST /shrms``, ``/tradeoffs``, ``/scenes``,
which submit the same canonical requests, so both paths share one job).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from relight.contract.models import JobPublic, JobState, JobSubmit
from relight.server.problems import Conflict, NotFound
from relight.server.services.jobs import JobService
from relight.server.services.kinds import JobKind, Submission, kind_of, kinds

if TYPE_CHECKING:
    from relight.server.state import Services


def submittable(name: str) -> JobKind:
    """The registered kind ``name`` that takes generic submissions (422 naming the known ones otherwise)."""
    try:
        kind = kind_of(name)
    except KeyError:
        kind = None
    if kind is None or kind.request is None:
        known = [k for k in kinds() if kind_of(k).request is not None]
        raise RequestValidationError([{
            "loc": ("body", "kind"), "msg": f"no job kind {name!r} takes POST /jobs (known: {', '.join(known)})",
            "type": "value_error", "input": name}])
    return kind


async def submit(services: Services, body: JobSubmit) -> tuple[JobPublic, int]:
    """Validate, canonicalise and submit ``body``; the job and 202 (work pending) or 200 (finished)."""
    kind = submittable(body.kind)
    assert kind.request is not None
    try:
        create = kind.request.model_validate(body.request)
    except ValidationError as exc:
        raise RequestValidationError([{**e, "loc": ("body", "request", *e["loc"])} for e in exc.errors()]) from None
    prepared = await kind.prepare(create, services)
    sub = prepared if isinstance(prepared, Submission) else Submission(prepared)
    row, status = await services.jobs.submit(kind, sub.request, job_id=sub.job_id, predicted=sub.predicted,
                                             intact=sub.intact)
    return services.jobs.public(row, cached=status == 200 and row.state == JobState.succeeded), status


async def result(jobs: JobService, job_id: str, kind: str | None = None) -> dict[str, Any]:
    """The stored result of a succeeded job (of ``kind``; 404 otherwise; 409 while it has none)."""
    row = await jobs.row(job_id, kind)
    if row.state != JobState.succeeded:
        raise Conflict(f"{kind or 'job'} {job_id} is {row.state}; it has no result yet", state=row.state)
    return dict(row.result or {})


async def file(jobs: JobService, job_id: str, name: str, kind: str | None = None) -> tuple[Path, str, str]:
    """(verified path, digest, media type) of the file ``name`` that a succeeded job's result lists under
    ``files`` (``{name: {"sha256": ..., "media_type": ...}}``)."""
    info = ((await result(jobs, job_id, kind)).get("files") or {}).get(name)
    if not isinstance(info, dict) or "sha256" not in info:
        raise NotFound(f"{kind or 'job'} {job_id} has no file {name!r}")
    path = await jobs.verified_file(job_id, str(info["sha256"]))  # 503 and recomputed when missing or corrupt
    return path, str(info["sha256"]), str(info.get("media_type", "application/octet-stream"))
