"""``/scenes``: store a scene, plan it and run the plan as a job (``relight.planning``)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import APIRouter, Request, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent
from starlette.responses import Response as StarletteResponse

from relight.contract.models import SceneCreate, ScenePublic
from relight.server.api.deps import JobsDep, ScenesDep
from relight.server.api.http import blob_response
from relight.server.api.routes.jobs import EVENTS_RESPONSES, existing, job_stream
from relight.server.problems import problem_responses
from relight.server.services.scenes import SCENE

router = APIRouter(prefix="/scenes", tags=["scenes"])
BINARY = {"schema": {"type": "string", "format": "binary"}}


@router.post("", status_code=202, response_model=ScenePublic,
             responses={200: {"description": "the scene has run already", "model": ScenePublic},
                        **problem_responses(400, 401, 404, 422, 429, 503)})
async def submit(body: SceneCreate, response: Response, scenes: ScenesDep) -> ScenePublic:
    """Store the scene and run its plan: 202 with the scene's id, or 200 when it has run already."""
    pub, status = await scenes.submit(body)
    response.status_code = status
    response.headers["Location"] = f"/scenes/{pub.id}"
    return pub


@router.get("/{scene_id}", response_model=ScenePublic, responses=problem_responses(401, 404, 422))
async def get_scene(scene_id: str, scenes: ScenesDep) -> ScenePublic:
    """The scene, its state and, once done, the plan (what is simulated, what is skipped and why) and the result."""
    return await scenes.get(scene_id)


@router.get("/{scene_id}/files/{name}", response_class=StarletteResponse,
            responses={200: {"content": {"image/x-exr": BINARY, "image/png": BINARY, "application/json": BINARY}},
                       304: {"description": "not modified"}, **problem_responses(401, 404, 409, 422)})
async def scene_file(scene_id: str, name: str, request: Request, scenes: ScenesDep) -> StarletteResponse:
    """One output file of a finished scene (verified against its SHA-256)."""
    path, digest, media_type = await scenes.file(scene_id, name)
    return blob_response(request, path, digest, media_type, filename=name)


@router.get("/{scene_id}/events", response_class=EventSourceResponse, responses=EVENTS_RESPONSES)
async def scene_events(scene_id: Annotated[str, existing(SCENE.name, "scene_id")],
                       jobs: JobsDep) -> AsyncIterator[ServerSentEvent]:
    """The scene's job as server-sent events until it ends (``/jobs/{id}/events``)."""
    async for event in job_stream(jobs, scene_id):
        yield event


@router.delete("/{scene_id}", response_model=ScenePublic, responses=problem_responses(401, 404, 409, 422))
async def cancel_scene(scene_id: str, jobs: JobsDep, scenes: ScenesDep) -> ScenePublic:
    """Cancel a queued or running scene (409 if it already finished)."""
    await jobs.cancel(scene_id, SCENE.name)
    return await scenes.get(scene_id)
