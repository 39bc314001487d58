"""``/meshes``: upload (streamed, capped, sniffed, decoded in a worker under vertex and face caps), list, get, and
the canonical geometry (``geometry.bin``, ``relight.mesh.geometry``)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from starlette.responses import Response as StarletteResponse

from relight.contract.models import MeshList, MeshPublic
from relight.server.api.deps import MeshesDep
from relight.server.api.http import blob_response
from relight.server.problems import problem_responses

router = APIRouter(prefix="/meshes", tags=["meshes"])

UPLOAD_BODY = {
    "requestBody": {
        "required": True,
        "description": "The mesh file itself as the body: Wavefront OBJ, glTF 2.0 JSON with embedded (data: URI) "
                       "buffers, or GLB. Triangles (polygons are fanned); file normals are ignored.",
        "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}


@router.post("", status_code=201, response_model=MeshPublic, openapi_extra=UPLOAD_BODY,
             responses={200: {"description": "already uploaded", "model": MeshPublic},
                        **problem_responses(400, 401, 413, 415, 422, 503)})
async def upload_mesh(request: Request, response: Response, meshes: MeshesDep,
                      name: Annotated[str | None, Query(max_length=255)] = None) -> MeshPublic:
    """Upload a mesh; its id is the SHA-256 of the bytes (201 new, 200 known). It is welded into relight's
    canonical vertex order, and its counts, bounds and defects are reported."""
    mesh, created = await meshes.ingest_stream(request.stream(), request.headers.get("content-length"), name)
    response.status_code = 201 if created else 200
    response.headers["Location"] = f"/meshes/{mesh.id}"
    return mesh


@router.get("", response_model=MeshList, responses=problem_responses(401, 422))
async def list_meshes(meshes: MeshesDep, limit: Annotated[int, Query(ge=1, le=1000)] = 100) -> MeshList:
    return MeshList(items=await meshes.list(limit))


@router.get("/{mesh_id}", response_model=MeshPublic, responses=problem_responses(401, 404, 422))
async def get_mesh(mesh_id: str, meshes: MeshesDep) -> MeshPublic:
    """The manifest: counts, bounds, defects and the layout of ``geometry.bin``."""
    return await meshes.get(mesh_id)


@router.get("/{mesh_id}/geometry.bin", response_class=StarletteResponse,
            responses={200: {"content": {"application/octet-stream": {"schema": {"type": "string",
                                                                                  "format": "binary"}}}},
                       304: {"description": "not modified"}, **problem_responses(401, 404, 422)})
async def geometry(mesh_id: str, request: Request, meshes: MeshesDep) -> StarletteResponse:
    """Positions, normals, tangents (float32) and indices (uint32) in canonical order (content-addressed: strong
    ETag, immutable); offsets in the manifest's ``geometry``."""
    path, digest = await meshes.geometry(mesh_id)
    return blob_response(request, path, digest, "application/octet-stream")
