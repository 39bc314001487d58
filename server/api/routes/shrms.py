"""``/shrms``: submit a prefiltering job; read results (manifest, EXR, float16 texture, a view)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from starlette.responses import Response as StarletteResponse

from relight.contract.models import JobPublic, ShrmCreate, ShrmManifest
from relight.server.api.deps import ShrmsDep
from relight.server.api.http import bytes_response, file_or_bytes_response
from relight.server.problems import problem_responses
from relight.worker.results import BIN_NAME, EXR_NAME, canonical_json

router = APIRouter(prefix="/shrms", tags=["shrms"])

BINARY = {"schema": {"type": "string", "format": "binary"}}
RESULT_ERRORS = problem_responses(401, 404, 409, 422, 503)


@router.post("", status_code=202, response_model=JobPublic,
             responses={200: {"description": "the result exists already (cached)", "model": JobPublic},
                        **problem_responses(400, 401, 404, 422, 429, 503)})
async def submit(body: ShrmCreate, response: Response, shrms: ShrmsDep) -> JobPublic:
    """Start (or join) the job for these inputs: 202 with the job, or 200 when the result is already there."""
    job, status = await shrms.submit(body)
    response.status_code = status
    response.headers["Location"] = f"/jobs/{job.id}"
    if status == 200:
        response.headers["Content-Location"] = f"/shrms/{job.id}"
    return job


@router.get("/{shrm_id}", response_model=ShrmManifest,
            responses={304: {"description": "not modified"}, **RESULT_ERRORS})
async def manifest(shrm_id: str, request: Request, shrms: ShrmsDep) -> StarletteResponse:
    """The result's manifest: representation, orders, layers and the layout of every file."""
    digest, content = await shrms.manifest(shrm_id)
    return bytes_response(request, canonical_json(content), digest, "application/json")


@router.get("/{shrm_id}/coefficients.exr", response_class=StarletteResponse,
            responses={200: {"content": {"image/x-exr": BINARY}}, 304: {"description": "not modified"},
                       **RESULT_ERRORS})
async def coefficients_exr(shrm_id: str, request: Request, shrms: ShrmsDep) -> StarletteResponse:
    """float32 RGB layers (one per SHRM coefficient; plain R, G, B for a reflection map)."""
    f = await shrms.result_file(shrm_id, EXR_NAME)
    return file_or_bytes_response(request, f.content, f.path, f.sha256, f.media_type)


@router.get("/{shrm_id}/coefficients.bin", response_class=StarletteResponse,
            responses={200: {"content": {"application/octet-stream": BINARY}}, 304: {"description": "not modified"},
                       **RESULT_ERRORS})
async def coefficients_bin(shrm_id: str, request: Request, shrms: ShrmsDep) -> StarletteResponse:
    """float16 texture layers for WebGL2 (layout in the manifest's ``files``)."""
    f = await shrms.result_file(shrm_id, BIN_NAME)
    return file_or_bytes_response(request, f.content, f.path, f.sha256, f.media_type)


@router.get("/{shrm_id}/reflection.exr", response_class=StarletteResponse,
            responses={200: {"content": {"image/x-exr": BINARY}}, 304: {"description": "not modified"},
                       **RESULT_ERRORS})
async def reflection(shrm_id: str, request: Request, shrms: ShrmsDep,
                     view: Annotated[str, Query(description="view direction x,y,z (normalised here)",
                                                examples=["0,0,1"])] = "0,0,1") -> StarletteResponse:
    """The reflection map seen from the distant view V (seed 000 eq. 12), indexed by the reflection vector."""
    f = await shrms.reflection(shrm_id, view)
    return file_or_bytes_response(request, f.content, f.path, f.sha256, f.media_type)
