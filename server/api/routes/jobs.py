"""``/jobs``: every kind of job (SHRMs, tradeoff sweeps, scenes, ...): state, progress (also as server-sent
events) and cancellation."""

from __future__ import annotations

import inspect
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Query
from fastapi.sse import EventSourceResponse, ServerSentEvent

from relight.contract.models import JobList, JobPublic, JobState
from relight.server.api.deps import JobsDep
from relight.server.problems import problem_responses
from relight.server.services.jobs import JobService

router = APIRouter(prefix="/jobs", tags=["jobs"])

#: OpenAPI description of a job's event stream (every ``events`` route).
EVENTS_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {"description": "``event: job`` with the job (``JobPublic``) as JSON: its current state, then one on every "
                         "update; then ``event: end`` with the final state. Comments keep an idle stream alive."},
    **problem_responses(401, 404, 422),
}


async def job_stream(jobs: JobService, job_id: str) -> AsyncIterator[ServerSentEvent]:
    """A job's updates as server-sent events (numbered, so a client can tell what it has seen)."""
    seq = 0
    async for event, pub in jobs.events(job_id):
        seq += 1
        yield ServerSentEvent(raw_data=pub.model_dump_json(), event=event, id=str(seq))


@router.get("", response_model=JobList, responses=problem_responses(401, 422))
async def list_jobs(jobs: JobsDep, state: JobState | None = None,
                    kind: Annotated[str | None, Query(max_length=32, description="only jobs of this kind")] = None,
                    limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> JobList:
    return await jobs.list(state, limit, kind)


@router.get("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 422))
async def get_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """Kind, state, stage, progress, predicted and measured time and error, failure reason."""
    return await jobs.get(job_id)


def existing(kind: str | None, name: str = "job_id") -> Any:
    """A dependency: the path parameter ``name`` after checking that such a job (of ``kind``) exists, so that an
    unknown id is a 404 problem before an event stream starts."""

    async def check(job_id: str, jobs: JobService) -> str:
        await jobs.row(job_id, kind)
        return job_id

    # the signature names the path parameter (built here: a string annotation could not see ``name``)
    param = inspect.Parameter.POSITIONAL_OR_KEYWORD
    check.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [inspect.Parameter("job_id", param, annotation=Annotated[str, Path(alias=name)]),
         inspect.Parameter("jobs", param, annotation=JobsDep)], return_annotation=str)
    return Depends(check)


@router.get("/{job_id}/events", response_class=EventSourceResponse, responses=EVENTS_RESPONSES)
async def job_events(job_id: Annotated[str, existing(None)], jobs: JobsDep) -> AsyncIterator[ServerSentEvent]:
    """Server-sent events until the job ends (any kind of job)."""
    async for event in job_stream(jobs, job_id):
        yield event


@router.delete("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 409, 422))
async def cancel_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """Cancel a queued or running job of any kind (409 if it already finished)."""
    return await jobs.cancel(job_id)
