"""Render endpoints: a result seen from a view (OpenGL, the viewer's shaders), its brute-force reference, and an
environment map as a float16 texture for the viewer's background.

* ``GET /shrms/{id}/render.png|.exr?view=x,y,z&size=N&object=sphere|bunny|teapot&mode=distant|near`` — the
  object lit by the result (seed 000 §7.5: ``distant`` = eq. 12 once per frame, ``near`` = eq. 6 per pixel),
  orthographic camera looking along -V, +Y up (``relight.shrm.sphere_geometry``), rendered headless with
  moderngl (``relight.gl.render``) in the server process: the coefficient texture is the service's own output.
* ``GET /shrms/{id}/reference.png|.exr?view=x,y,z&size=N`` — the angular-domain brute force of the same sphere
  image (``relight.reference_view.reference_sphere``), computed in a worker process (it decodes the uploaded map).
* ``GET /envmaps/{id}/texture.bin?rows=R`` — the map as little-endian float16 RGB, ``X-Texture-Shape: H,W,3``.

PNGs go through the project's display transform (``exposure`` stops, ``tonemap`` aces|reinhard|none); EXRs are
float32 linear radiance. Everything is cached in memory (bounded) by content: result digest, canonical view,
parameters (:class:`relight.server.services.render.RenderService`, which also owns the GL thread).
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import Annotated, Any, Literal

import numpy as np
from fastapi import APIRouter, Query, Request
from starlette.responses import Response

from relight.contract.models import parse_view
from relight.errors import InputError
from relight.server.api.deps import EnvmapsDep, RenderDep, ServicesDep, ShrmsDep
from relight.server.problems import Unavailable, Unprocessable, problem_responses
from relight.server.services.base import content_id

log = logging.getLogger("relight.server")

router = APIRouter(tags=["render"])

Format = Literal["png", "exr"]
MEDIA = {"png": "image/png", "exr": "image/x-exr"}
ERRORS = problem_responses(401, 404, 409, 422, 503)
REFERENCE_TIMEOUT_S = 300.0
#: Default resampling of the map for the reference: 4 (F_B + 1) rows keeps every band the result holds (a box
#: filter of that pixel size attenuates band F_B by under 3 %), at least 64, never above the map's own rows.
REFERENCE_ROWS_PER_BAND, REFERENCE_MIN_ROWS = 4, 64
TEXTURE_TIMEOUT_S = 120.0
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


async def _in_thread(fn: Any, *args: Any) -> Any:
    return await asyncio.get_running_loop().run_in_executor(None, fn, *args)


@router.get("/shrms/{shrm_id}/render.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}}}, **ERRORS})
async def render_view(
    shrm_id: str,
    fmt: Format,
    shrms: ShrmsDep,
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
    digest, manifest = await shrms.manifest(shrm_id)
    key = ("render", digest, tuple(v), size, object, mode, rotation)
    image = renders.cached(key)
    if image is None:
        f = await shrms.result_file(shrm_id, "coefficients.bin")
        data = await _in_thread(f.path.read_bytes)
        try:
            image = await renders.render(digest, manifest, data, view=v, size=size, obj=object, mode=mode,
                                     env_rotation=math.radians(rotation))
        except RuntimeError as exc:
            raise Unavailable(f"no OpenGL context on this server: {exc}") from None
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        renders.keep(key, image)
    body = await _in_thread(_encode, image, fmt, exposure, tonemap,
                            {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.object": object})
    return Response(body, media_type=MEDIA[fmt], headers={"Cache-Control": "public, max-age=3600"})


@router.get("/shrms/{shrm_id}/reference.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}}}, **ERRORS})
async def reference_view(
    shrm_id: str,
    fmt: Format,
    shrms: ShrmsDep,
    renders: RenderDep,
    envmaps: EnvmapsDep,
    services: ServicesDep,
    view: ViewQuery = "0,0,1",
    size: Annotated[int, Query(ge=8, le=256, description="image edge in pixels")] = 128,
    env_rows: Annotated[int | None, Query(ge=8, le=4096, description="resample the map to this many rows first "
                                                                     "(area average; default 4 (F_B + 1), at least "
                                                                     "64)")] = None,
    exposure: ExposureQuery = 0.0,
    tonemap: TonemapQuery = "aces",
) -> Response:
    """Angular-domain brute force of the unit sphere for the same view and camera as ``render`` (slow)."""
    from relight.gl.views import reference_sphere_image

    v = _view(view)
    digest, manifest = await shrms.manifest(shrm_id)
    envmap_id = envmaps.known_digest(str(manifest.get("envmap", "")))
    if env_rows is None:
        f_b = int((manifest.get("orders") or {}).get("F_B") or 32)
        env_rows = max(REFERENCE_MIN_ROWS, REFERENCE_ROWS_PER_BAND * (f_b + 1))
    env_rows = min(env_rows, int((manifest.get("input") or {}).get("height") or env_rows))
    key = ("reference", digest, tuple(v), size, env_rows)
    image = renders.cached(key)
    if image is None:
        await envmaps.input_ok(envmap_id)
        path = str(services.store.path(envmap_id))
        fut = services.cluster.submit(reference_sphere_image, path, manifest.get("brdf"), v, size,
                                      key=f"relight-reference-{content_id(list(key))}", env_rows=env_rows,
                                      max_pixels=services.settings.max_pixels)
        try:
            image = np.asarray(await asyncio.wait_for(fut, REFERENCE_TIMEOUT_S))
        except (InputError, ValueError, KeyError, TypeError) as exc:
            raise Unprocessable(f"no brute-force reference for this result: {exc}") from None
        except TimeoutError:
            await services.cluster.cancel(fut)
            raise Unavailable(f"the reference took longer than {REFERENCE_TIMEOUT_S:.0f} s; ask for a smaller size "
                              "or env_rows", headers={"Retry-After": "10"}) from None
        except asyncio.CancelledError:
            await services.cluster.cancel(fut)  # the client went away: free the worker
            raise
        renders.keep(key, image)
    body = await _in_thread(_encode, image, fmt, exposure, tonemap,
                            {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.reference": "angular",
                             "relight.env_rows": str(env_rows)})
    return Response(body, media_type=MEDIA[fmt], headers={"Cache-Control": "public, max-age=3600",
                                                          "X-Reference-Env-Rows": str(env_rows),
                                                          "Access-Control-Expose-Headers": "X-Reference-Env-Rows"})


@router.get("/envmaps/{envmap_id}/texture.bin", response_class=Response,
            responses={200: {"content": {"application/octet-stream": {}},
                             "headers": {"X-Texture-Shape": {"description": "height,width,3"}}},
                       **problem_responses(401, 404, 422, 503)})
async def envmap_texture(
    envmap_id: str,
    request: Request,
    envmaps: EnvmapsDep,
    services: ServicesDep,
    renders: RenderDep,
    rows: Annotated[int, Query(ge=8, le=2048, description="rows of the lat-long texture (area-resampled)")] = 256,
) -> Response:
    """The environment map as little-endian float16 RGB, rows x 2 rows x 3, row 0 = +Y (the viewer's background)."""
    from relight.gl.views import envmap_texture as make_texture

    await envmaps.get(envmap_id)  # 404 for an unknown map
    key = ("texture", envmap_id, rows)
    cached = renders.cached(key)
    if cached is None:
        await envmaps.input_ok(envmap_id)
        path = str(services.store.path(envmap_id))
        fut = services.cluster.submit(make_texture, path, rows, key=f"relight-texture-{envmap_id[:16]}-{rows}",
                                      max_pixels=services.settings.max_pixels)
        try:
            cached = await asyncio.wait_for(fut, TEXTURE_TIMEOUT_S)
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        renders.keep(key, cached)
    data, h, w = cached
    etag = f'"{envmap_id[:32]}-{rows}"'
    headers = {"X-Texture-Shape": f"{h},{w},3", "ETag": etag, "Cache-Control": "public, max-age=31536000, immutable",
               "Access-Control-Expose-Headers": "X-Texture-Shape"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    return Response(data, media_type="application/octet-stream", headers=headers)
