"""``/jobs``: every kind of job (SHRMs, tradeoff sweeps, scenes, ...): generic submission (``POST /jobs``), state,
progress (also as server-sent events), results and cancellation (:mod:`relight.server.services.submissions`)."""

from __future__ import annotations

import inspect
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Query, Request, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent
from starlette.responses import Response as StarletteResponse

from relight.contract.models import JobKindList, JobList, JobPublic, JobState, JobSubmit
from relight.server.api.deps import JobsDep, ServicesDep
from relight.server.api.http import blob_response
from relight.server.problems import problem_responses
from relight.server.services import submissions
from relight.server.services.jobs import JobService
from relight.server.services.kinds import kind_of, kinds

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


@router.post("", status_code=202, response_model=JobPublic,
             responses={200: {"description": "the result exists already (or the job failed for good)",
                              "model": JobPublic}, **problem_responses(400, 401, 404, 422, 429, 503)})
async def submit_job(body: JobSubmit, response: Response, services: ServicesDep) -> JobPublic:
    """Start (or join) a job of any kind: ``request`` is what the kind's own route takes (``GET /jobs/kinds``).
    202 with the job (``Location: /jobs/{id}``), or 200 when its result exists already; 429 beyond the cap."""
    job, status = await submissions.submit(services, body)
    response.status_code = status
    response.headers["Location"] = f"/jobs/{job.id}"
    return job


@router.get("/kinds", response_model=JobKindList, responses=problem_responses(401))
async def job_kinds() -> JobKindList:
    """The job kinds ``POST /jobs`` takes."""
    return JobKindList(items=[k for k in kinds() if kind_of(k).request is not None])


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


@router.get("/{job_id}/result", responses={
    200: {"description": "the succeeded job's result (JSON, as its task returned it)",
          "content": {"application/json": {"schema": {"type": "object"}}}},
    **problem_responses(401, 404, 409, 422)})
async def job_result(job_id: str, jobs: JobsDep) -> dict[str, Any]:
    """The result of a succeeded job of any kind (409 while it is queued, running, failed or cancelled)."""
    return await submissions.result(jobs, job_id)


@router.get("/{job_id}/files/{name}", response_class=StarletteResponse,
            responses={200: {"content": {"application/octet-stream": {"schema": {"type": "string",
                                                                                 "format": "binary"}}}},
                       304: {"description": "not modified"}, **problem_responses(401, 404, 409, 422)})
async def job_file(job_id: str, name: str, request: Request, jobs: JobsDep) -> StarletteResponse:
    """A file that a succeeded job's result lists under ``files`` (verified against its SHA-256)."""
    path, digest, media_type = await submissions.file(jobs, job_id, name)
    return blob_response(request, path, digest, media_type, filename=name)


@router.delete("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 409, 422))
async def cancel_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """Cancel a queued or running job of any kind (409 if it already finished)."""
    return await jobs.cancel(job_id)
