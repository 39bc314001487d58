"""``/jobs``: state, progress (also as server-sent events) and cancellation."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from starlette.responses import StreamingResponse

from relight.contract.models import JobList, JobPublic, JobState
from relight.server.api.deps import JobsDep
from relight.server.problems import problem_responses

router = APIRouter(prefix="/jobs", tags=["jobs"])


@router.get("", response_model=JobList, responses=problem_responses(401, 422))
async def list_jobs(jobs: JobsDep, state: JobState | None = None,
                    limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> JobList:
    return await jobs.list(state, limit)


@router.get("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 422))
async def get_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """State, stage, progress, predicted and measured time and error, failure reason."""
    return await jobs.get(job_id)


@router.get("/{job_id}/events", response_class=StreamingResponse,
            responses={200: {"description": "``event: job`` with the job as JSON on every update, then "
                                            "``event: end`` with the final state", "content": {
                "text/event-stream": {"schema": {"type": "string"}}}}, **problem_responses(401, 404, 422)})
async def job_events(job_id: str, jobs: JobsDep) -> StreamingResponse:
    """Server-sent events until the job ends."""
    first = await jobs.get(job_id)
    return StreamingResponse(jobs.events(job_id, first), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


@router.delete("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 409, 422))
async def cancel_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """Cancel a queued or running job (409 if it already finished)."""
    return await jobs.cancel(job_id)
