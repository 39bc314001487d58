"""Render endpoints: a result seen from a view (OpenGL, the viewer's shaders), its brute-force reference, and an
environment map as a float16 texture for the viewer's background.

* ``GET /shrms/{id}/render.png|.exr?view=x,y,z&size=N&object=sphere|bunny|teapot&mode=distant|near`` — the
  object lit by the result (seed 000 §7.5: ``distant`` = eq. 12 once per frame, ``near`` = eq. 6 per pixel),
  orthographic camera looking along -V, +Y up (``relight.shrm.sphere_geometry``), rendered headless with
  moderngl (``relight.gl.render``) in the server process: the coefficient texture is the service's own output.
* ``GET /shrms/{id}/reference.png|.exr?view=x,y,z&size=N`` — the angular-domain brute force of the same sphere
  image (``relight.reference_view.reference_sphere``), computed in a worker process (it decodes the uploaded map).
* ``GET /meshes/{id}/reference.png|.exr?envmap=ID&view=x,y,z&size=N&spp=S&max_depth=D&albedo=A&rotation=DEG``
  — Mitsuba 3's path-traced image of the mesh (Lambertian, exact self-shadowing; ``max_depth`` 2 = direct light,
  each step above one interreflection bounce) under the map turned by ``rotation`` about +Y, with the orthographic
  camera of the viewer's fixed views (``relight.gl.views.mesh_reference_image``); ``X-Reference-Noise`` is the
  relative Monte Carlo standard deviation of the whole image's luminance.
* ``GET /envmaps/{id}/texture.bin?rows=R`` — the map as little-endian float16 RGB, ``X-Texture-Shape: H,W,3``.

PNGs go through the project's display transform (``exposure`` stops, ``tonemap`` aces|reinhard|none); EXRs are
float32 linear radiance. Everything is cached in memory (bounded) by content: result digest, canonical view,
parameters (:class:`relight.server.services.render.RenderService`, which also owns the GL thread and submits the
worker tasks of :mod:`relight.worker.render`).
"""

from __future__ import annotations

import logging
import math
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Query, Request
from starlette.responses import Response

from relight.contract.models import parse_view
from relight.conventions import luminance
from relight.server.api.deps import RenderDep
from relight.server.problems import Unprocessable, problem_responses
from relight.server.services.base import in_thread

log = logging.getLogger("relight.server")

router = APIRouter(tags=["render"])

Format = Literal["png", "exr"]
MEDIA = {"png": "image/png", "exr": "image/x-exr"}
ERRORS = problem_responses(401, 404, 409, 422, 503)
MAX_RENDER_SIZE = 1024

ViewQuery = Annotated[str, Query(description="view direction x,y,z toward the viewer (normalised here)",
                                 examples=["0,0,1"])]
ExposureQuery = Annotated[float, Query(ge=-20.0, le=20.0, description="PNG only: exposure in stops")]
TonemapQuery = Annotated[Literal["aces", "reinhard"], Query(description="PNG only: display transform "
                                                                      "(relight.envmap.tonemap)")]


def _view(text: str) -> list[float]:
    try:
        v = parse_view(text)
    except ValueError as exc:
        raise Unprocessable(str(exc)) from None
    return [round(c, 9) + 0.0 for c in v]


def _encode(image: np.ndarray, fmt: Format, exposure: float, tonemap: str, attributes: dict[str, str]) -> bytes:
    from relight.gl.views import encode_exr, encode_png

    return encode_png(image, exposure=exposure, operator=tonemap) if fmt == "png" else encode_exr(image, attributes)


@router.get("/shrms/{shrm_id}/render.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}}}, **ERRORS})
async def render_view(
    shrm_id: str,
    fmt: Format,
    renders: RenderDep,
    view: ViewQuery = "0,0,1",
    size: Annotated[int, Query(ge=8, le=MAX_RENDER_SIZE)] = 256,
    object: Annotated[Literal["sphere", "bunny", "teapot"], Query()] = "sphere",  # noqa: A002 - the API's name
    mode: Annotated[Literal["distant", "near"], Query(description="distant: eq. 12; near: eq. 6 per pixel")]
    = "distant",
    rotation: Annotated[float, Query(ge=-360.0, le=360.0, description="environment rotation about +Y, degrees")]
    = 0.0,
    exposure: ExposureQuery = 0.0,
    tonemap: TonemapQuery = "aces",
) -> Response:
    """The result on a sphere, bunny or teapot seen from the distant direction V (orthographic, +Y up)."""
    v = _view(view)
    image = await renders.view(shrm_id, v, size=size, obj=object, mode=mode, env_rotation=math.radians(rotation))
    body = await in_thread(_encode, image, fmt, exposure, tonemap,
                           {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.object": object})
    return Response(body, media_type=MEDIA[fmt], headers={"Cache-Control": "public, max-age=3600"})


@router.get("/shrms/{shrm_id}/reference.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}}}, **ERRORS})
async def reference_view(
    shrm_id: str,
    fmt: Format,
    renders: RenderDep,
    view: ViewQuery = "0,0,1",
    size: Annotated[int, Query(ge=8, le=256, description="image edge in pixels")] = 128,
    env_rows: Annotated[int | None, Query(ge=8, le=4096, description="resample the map to this many rows first "
                                                                     "(area average; default 4 (F_B + 1), at least "
                                                                     "64)")] = None,
    exposure: ExposureQuery = 0.0,
    tonemap: TonemapQuery = "aces",
) -> Response:
    """Angular-domain brute force of the unit sphere for the same view and camera as ``render`` (slow)."""
    v = _view(view)
    image, rows = await renders.reference(shrm_id, v, size, env_rows)
    body = await in_thread(_encode, image, fmt, exposure, tonemap,
                           {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.reference": "angular",
                            "relight.env_rows": str(rows)})
    return Response(body, media_type=MEDIA[fmt], headers={"Cache-Control": "public, max-age=3600",
                                                          "X-Reference-Env-Rows": str(rows),
                                                          "Access-Control-Expose-Headers": "X-Reference-Env-Rows"})


@router.get("/meshes/{mesh_id}/reference.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}}}, **ERRORS})
async def mesh_reference(
    mesh_id: str,
    fmt: Format,
    renders: RenderDep,
    envmap: Annotated[str, Query(description="the environment map's id", min_length=1, max_length=128)],
    view: ViewQuery = "0,0,1",
    size: Annotated[int, Query(ge=8, le=256, description="image edge in pixels")] = 128,
    spp: Annotated[int, Query(ge=1, le=4096, description="Mitsuba samples per pixel (size^2 x spp at most "
                                                         "256^2 x 256)")] = 64,
    max_depth: Annotated[int, Query(ge=2, le=5, description="path depth: 2 = direct light with exact shadows, "
                                                            "each step above adds one interreflection bounce")] = 2,
    albedo: Annotated[float, Query(ge=0.0, le=1.0, description="Lambertian albedo")] = 0.8,
    rotation: Annotated[float, Query(ge=-360.0, le=360.0, description="environment rotation about +Y, degrees")]
    = 0.0,
    env_rows: Annotated[int, Query(ge=8, le=256, description="area-resample the map to this many rows first")] = 64,
    exposure: ExposureQuery = 0.0,
    tonemap: TonemapQuery = "aces",
) -> Response:
    """Mitsuba's image of the mesh for the viewer's comparison panel (slow: seconds)."""
    v = _view(view)
    rgb, var = await renders.mesh_reference(mesh_id, envmap, v, size, spp=spp, albedo=round(albedo, 6),
                                            max_depth=max_depth, rotation=math.radians(rotation), env_rows=env_rows)
    lum = luminance(rgb)
    noise = float(np.sqrt(var.sum()) / max(np.sqrt(np.square(lum).sum()), 1e-30))
    headers = {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.reference": "mitsuba3",
               "relight.spp": str(spp), "relight.max_depth": str(max_depth), "relight.env_rows": str(env_rows)}
    body = await in_thread(_encode, rgb, fmt, exposure, tonemap, headers)
    return Response(body, media_type=MEDIA[fmt], headers={
        "Cache-Control": "public, max-age=3600", "X-Reference-Noise": f"{noise:.6g}", "X-Reference-Spp": str(spp),
        "Access-Control-Expose-Headers": "X-Reference-Noise, X-Reference-Spp"})


@router.get("/envmaps/{envmap_id}/texture.bin", response_class=Response,
            responses={200: {"content": {"application/octet-stream": {}},
                             "headers": {"X-Texture-Shape": {"description": "height,width,3"}}},
                       **problem_responses(401, 404, 422, 503)})
async def envmap_texture(
    envmap_id: str,
    request: Request,
    renders: RenderDep,
    rows: Annotated[int, Query(ge=8, le=2048, description="rows of the lat-long texture (area-resampled)")] = 256,
) -> Response:
    """The environment map as little-endian float16 RGB, rows x 2 rows x 3, row 0 = +Y (the viewer's background)."""
    data, h, w = await renders.texture(envmap_id, rows)
    etag = f'"{envmap_id[:32]}-{rows}"'
    headers = {"X-Texture-Shape": f"{h},{w},3", "ETag": etag, "Cache-Control": "public, max-age=31536000, immutable",
               "Access-Control-Expose-Headers": "X-Texture-Shape"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    return Response(data, media_type="application/octet-stream", headers=headers)
