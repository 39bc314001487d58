"""``GET /envmaps/{id}/ibl``: an engine-ready export of a map as a resource, computed as an ``ibl`` job and cached,
and ``GET /dfg``: the split-sum DFG table, a ``dfg`` job (:mod:`relight.server.services.ibl`)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from starlette.responses import Response as StarletteResponse

from relight.contract.models import DfgCreate, IblCreate, JobPublic, JobState, JobSubmit
from relight.server.api.deps import ServicesDep
from relight.server.api.http import blob_response
from relight.server.problems import Unprocessable, problem_responses
from relight.server.services import submissions

router = APIRouter(tags=["envmaps"])
#: Seconds a client is asked to wait before asking again while the job runs (a 256^2 chain takes seconds).
RETRY_AFTER_S = 1


@router.get("/envmaps/{envmap_id}/ibl", response_class=StarletteResponse, responses={
    200: {"description": "the export: chain.ktx2 (image/ktx2), lighting.glb (model/gltf-binary) or sh.json; "
                         "``X-Relight-Job`` names its job, whose result holds the manifest",
          "content": {"image/ktx2": {"schema": {"type": "string", "format": "binary"}},
                      "model/gltf-binary": {"schema": {"type": "string", "format": "binary"}},
                      "application/json": {"schema": {"type": "object"}}}},
    202: {"description": "computing: the job (``Location: /jobs/{id}``); ask again when it has succeeded",
          "model": JobPublic},
    304: {"description": "not modified"}, **problem_responses(401, 404, 422, 429, 503)})
async def envmap_ibl(envmap_id: str, request: Request, services: ServicesDep,
                     target: Literal["three", "filament", "gltf", "babylon"] = "three",
                     format: Literal["ktx2", "sh", "gltf"] = "ktx2",
                     size: Annotated[int, Query(ge=1, le=1024)] = 256,
                     levels: Annotated[int | None, Query(ge=1, le=11)] = None,
                     epsilon: Annotated[float, Query(ge=1e-8, lt=1.0)] = 2.5e-5,
                     sun: Annotated[str, Query(max_length=40)] = "keep",
                     pixel_format: Literal["rgba16f", "b10g11r11", "e5b9g9r9"] = "rgba16f",
                     brdf: Annotated[str | None, Query(min_length=1, max_length=400)] = None) -> StarletteResponse:
    """The prefiltered cube chain (``format=ktx2``), the glTF lighting GLB (``format=gltf``, ``target=gltf``) or
    SH9 (``format=sh``) of the map for an engine: the same parameters and bytes as ``relight export``
    (``brdf`` is ``--brdf SPEC``). 202 with the job until it has succeeded, then the file."""
    body: dict[str, Any] = {"envmap": envmap_id, "target": target, "format": format, "size": size,
                            "levels": levels, "epsilon": epsilon, "sun": sun, "pixel_format": pixel_format}
    if brdf is not None:
        body["brdf"] = brdf
    return await _resource(request, services, "ibl", IblCreate, body)


@router.get("/dfg", response_class=StarletteResponse, tags=["engine"], responses={
    200: {"description": "the table: dfg.exr, dfg.png or dfg.ktx2, the bytes ``relight dfg --out`` writes; "
                         "``X-Relight-Job`` names its job",
          "content": {"image/x-exr": {"schema": {"type": "string", "format": "binary"}},
                      "image/png": {"schema": {"type": "string", "format": "binary"}},
                      "image/ktx2": {"schema": {"type": "string", "format": "binary"}}}},
    202: {"description": "computing: the job (``Location: /jobs/{id}``); ask again when it has succeeded",
          "model": JobPublic},
    304: {"description": "not modified"}, **problem_responses(401, 422, 429, 503)})
async def dfg(request: Request, services: ServicesDep, size: Annotated[int, Query(ge=2, le=1024)] = 128,
              multiscatter: bool = False, format: Literal["exr", "png", "ktx2"] = "exr") -> StarletteResponse:
    """The split-sum DFG table (``relight dfg [--size N] [--multiscatter] --out FILE.<format>``), computed as a
    ``dfg`` job and cached: 202 with the job until it has succeeded, then the file."""
    body = {"size": size, "multiscatter": multiscatter, "format": format}
    return await _resource(request, services, "dfg", DfgCreate, body)


async def _resource(request: Request, services: Any, kind: str, model: Any, body: dict[str, Any]) -> StarletteResponse:
    """A job's file as a resource: validate as the kind's model, submit (or join) the job, 202 while it runs."""
    try:
        model.model_validate(body)
    except ValidationError as exc:
        raise RequestValidationError([{**e, "loc": ("query", *e["loc"])} for e in exc.errors()]) from None
    job, _ = await submissions.submit(services, JobSubmit(kind=kind, request=body))
    if job.state in (JobState.queued, JobState.running):
        return JSONResponse(job.model_dump(mode="json"), status_code=202,
                            headers={"Location": f"/jobs/{job.id}", "Retry-After": str(RETRY_AFTER_S)})
    if job.state != JobState.succeeded:
        raise Unprocessable(f"the {kind} job {job.id} {job.state}: {job.failure_reason or 'no reason recorded'}",
                            job=job.id)
    name = str((await submissions.result(services.jobs, job.id)).get("file"))
    path, digest, media_type = await submissions.file(services.jobs, job.id, name)
    resp = blob_response(request, path, digest, media_type, filename=name)
    resp.headers["X-Relight-Job"] = job.id
    # the same URL gives other bytes after an algorithm change: revalidate (the ETag is the content's hash)
    resp.headers["Cache-Control"] = "no-cache"
    return resp
