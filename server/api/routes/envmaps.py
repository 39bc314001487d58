"""``/envmaps``: upload (streamed, capped, sniffed, header-checked, decoded in a worker), list, get, preview."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from starlette.responses import Response as StarletteResponse

from relight.contract.models import EnvmapList, EnvmapPublic
from relight.server.api.deps import EnvmapsDep
from relight.server.api.http import blob_response
from relight.server.problems import problem_responses

router = APIRouter(prefix="/envmaps", tags=["envmaps"])

UPLOAD_BODY = {
    "requestBody": {
        "required": True,
        "description": "The image file itself as the body: OpenEXR, Radiance RGBE (.hdr), PNG or JPEG; a lat-long "
                       "map (width = 2 x height) or a cube map (strip or cross).",
        "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}
UPLOAD_ERRORS = problem_responses(400, 401, 413, 415, 422, 503)


async def _upload(request: Request, response: Response, envmaps: EnvmapsDep, name: str | None) -> EnvmapPublic:
    env, created = await envmaps.ingest_stream(request.stream(), request.headers.get("content-length"), name)
    response.status_code = 201 if created else 200
    response.headers["Location"] = f"/envmaps/{env.id}"
    return env


@router.post("", status_code=201, response_model=EnvmapPublic, openapi_extra=UPLOAD_BODY,
             responses={200: {"description": "already uploaded", "model": EnvmapPublic}, **UPLOAD_ERRORS})
async def upload_envmap(request: Request, response: Response, envmaps: EnvmapsDep,
                        name: Annotated[str | None, Query(max_length=255)] = None) -> EnvmapPublic:
    """Upload an environment map; its id is the SHA-256 of the bytes (201 new, 200 known)."""
    return await _upload(request, response, envmaps, name)


@router.put("", status_code=201, response_model=EnvmapPublic, openapi_extra=UPLOAD_BODY,
            responses={200: {"description": "already uploaded", "model": EnvmapPublic}, **UPLOAD_ERRORS})
async def put_envmap(request: Request, response: Response, envmaps: EnvmapsDep,
                     name: Annotated[str | None, Query(max_length=255)] = None) -> EnvmapPublic:
    """Same as POST (idempotent: the id is the content hash)."""
    return await _upload(request, response, envmaps, name)


@router.get("", response_model=EnvmapList, responses=problem_responses(401, 422))
async def list_envmaps(envmaps: EnvmapsDep, limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> EnvmapList:
    return EnvmapList(items=await envmaps.list(limit))


@router.get("/{envmap_id}", response_model=EnvmapPublic, responses=problem_responses(401, 404, 422))
async def get_envmap(envmap_id: str, envmaps: EnvmapsDep) -> EnvmapPublic:
    """Metadata: size, range, negative texels clamped, SH power spectrum."""
    return await envmaps.get(envmap_id)


@router.get("/{envmap_id}/preview.png", response_class=StarletteResponse,
            responses={200: {"content": {"image/png": {"schema": {"type": "string", "format": "binary"}}}},
                       304: {"description": "not modified"}, **problem_responses(401, 404, 422)})
async def envmap_preview(envmap_id: str, request: Request, envmaps: EnvmapsDep) -> StarletteResponse:
    """Tone-mapped 8-bit preview (content-addressed: strong ETag, immutable)."""
    path, digest = await envmaps.preview(envmap_id)
    return blob_response(request, path, digest, "image/png")
