"""``/scenes``: store a scene, plan it and run the plan as a job (``relight.planning``)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response
from starlette.responses import Response as StarletteResponse

from relight.contract.models import SceneCreate, ScenePublic
from relight.server.api.http import blob_response
from relight.server.problems import problem_responses
from relight.server.services.scenes import SceneService, scene_service

router = APIRouter(prefix="/scenes", tags=["scenes"])

ScenesDep = Annotated[SceneService, Depends(scene_service)]
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
