"""``/brdfs``: register a BRDF (strictly validated spec, or a measured MERL file) and read it back."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from relight.contract.brdfs import BrdfSpec
from relight.contract.models import BrdfPublic
from relight.server.api.deps import BrdfsDep
from relight.server.problems import problem_responses

router = APIRouter(prefix="/brdfs", tags=["brdfs"])


@router.post("", status_code=201, response_model=BrdfPublic,
             responses={200: {"description": "already registered", "model": BrdfPublic},
                        **problem_responses(400, 401, 422)})
async def create_brdf(spec: BrdfSpec, response: Response, brdfs: BrdfsDep) -> BrdfPublic:
    """Register an analytic BRDF; unknown keys, NaN and out-of-range parameters are 422 naming the field."""
    pub, created = await brdfs.create(spec)
    response.status_code = 201 if created else 200
    response.headers["Location"] = f"/brdfs/{pub.id}"
    return pub


@router.post("/measured", status_code=201, response_model=BrdfPublic,
             openapi_extra={"requestBody": {"required": True, "description": "a MERL .binary file (35,004,012 "
                                            "bytes: dimensions 90 x 90 x 180, then doubles)", "content": {
                 "application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}}},
             responses={200: {"description": "already registered", "model": BrdfPublic},
                        **problem_responses(400, 401, 413, 422)})
async def upload_measured_brdf(request: Request, response: Response, brdfs: BrdfsDep) -> BrdfPublic:
    """Upload a measured BRDF in the MERL binary format."""
    pub, created = await brdfs.upload_measured(request.stream(), request.headers.get("content-length"))
    response.status_code = 201 if created else 200
    response.headers["Location"] = f"/brdfs/{pub.id}"
    return pub


@router.get("/{brdf_id}", response_model=BrdfPublic, responses=problem_responses(401, 404, 422))
async def get_brdf(brdf_id: str, brdfs: BrdfsDep) -> BrdfPublic:
    return await brdfs.get(brdf_id)
