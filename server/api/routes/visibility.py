"""``/visibility``: per-vertex SH visibility, diffuse transfer or shadow matrix of a mesh as a job
(``relight.visibility``); the result's manifest and files (float16 vertex textures, float32 NPZ)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Request, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent
from starlette.responses import Response as StarletteResponse

from relight.contract.models import JobPublic, VisibilityCreate
from relight.server.api.deps import JobsDep, VisibilityDep
from relight.server.api.http import bytes_response
from relight.server.api.routes.jobs import EVENTS_RESPONSES, existing, job_stream
from relight.server.problems import problem_responses
from relight.server.services.visibility import VISIBILITY
from relight.worker.results import canonical_json

router = APIRouter(prefix="/visibility", tags=["visibility"])

RESULT_ERRORS = problem_responses(401, 404, 409, 422, 503)


@router.post("", status_code=202, response_model=JobPublic,
             responses={200: {"description": "the result exists already (cached)", "model": JobPublic},
                        **problem_responses(400, 401, 404, 422, 429, 503)})
async def submit(body: VisibilityCreate, response: Response, visibility: VisibilityDep) -> JobPublic:
    """Start (or join) the job: 202 with the job, or 200 when the result is already there."""
    job, status = await visibility.submit(body)
    response.status_code = status
    response.headers["Location"] = f"/jobs/{job.id}"
    if status == 200:
        response.headers["Content-Location"] = f"/visibility/{job.id}"
    return job


@router.get("/{job_id}", response_model=dict[str, Any],
            responses={304: {"description": "not modified"}, **RESULT_ERRORS})
async def manifest(job_id: str, request: Request, visibility: VisibilityDep) -> StarletteResponse:
    """The result's manifest: settings, Monte Carlo errors (RMS over vertices), the texture layout of every file."""
    digest, content = await visibility.manifest(job_id)
    return bytes_response(request, canonical_json(content), digest, "application/json")


@router.get("/{job_id}/files/{name}", response_class=StarletteResponse,
            responses={200: {"content": {"application/octet-stream": {"schema": {"type": "string",
                                                                                  "format": "binary"}}}},
                       304: {"description": "not modified"}, **RESULT_ERRORS})
async def result_file(job_id: str, name: str, request: Request, visibility: VisibilityDep) -> StarletteResponse:
    """``ao.bin``, ``visibility.bin``, ``transfer.bin``, ``shadow_matrix.bin`` (float16 RGBA data textures indexed
    by vertex id) or ``visibility.npz`` (float32); content-addressed (strong ETag, immutable)."""
    data, digest, media_type = await visibility.file(job_id, name)
    return bytes_response(request, data, digest, media_type)


@router.get("/{job_id}/events", response_class=EventSourceResponse, responses=EVENTS_RESPONSES)
async def visibility_events(job_id: Annotated[str, existing(VISIBILITY.name)],
                            jobs: JobsDep) -> AsyncIterator[ServerSentEvent]:
    """The job as server-sent events until it ends (``/jobs/{id}/events``)."""
    async for event in job_stream(jobs, job_id):
        yield event


@router.delete("/{job_id}", response_model=JobPublic, responses=problem_responses(401, 404, 409, 422))
async def cancel(job_id: str, jobs: JobsDep) -> JobPublic:
    """Cancel a queued or running job (409 if it already finished)."""
    return await jobs.cancel(job_id, VISIBILITY.name)
