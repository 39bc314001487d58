"""Seed 002's render route (Green, Kautz & Durand 2007, §5):

* ``GET /gaussian/render.png|.exr?fit=ID&chain=ID[&visibility=ID&mode=none|ao|sh|sh-lobe]&view=x,y,z&size=N`` --
  a ``gaussian_fit`` job's lobes lit by a ``gaussian_chain`` job's prefiltered map: the unit sphere, or with a
  ``visibility`` job the mesh it was computed for, with eq. 7's glossy shadows (orthographic camera looking along
  -V, +Y up, 2 x 2 samples per pixel; ``relight.server.services.gaussian_render``). The EXR carries the mode and,
  for shadowed renders, the visibility's range before clamping to [0, 1] (also in ``X-Visibility-Range``).
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query
from starlette.responses import Response

from relight.server.api.deps import ServicesDep
from relight.server.api.routes.render import MEDIA, ExposureQuery, Format, TonemapQuery, ViewQuery, _encode, _view
from relight.server.problems import problem_responses
from relight.server.services.base import in_thread
from relight.server.services.gaussian_render import gaussian_render

router = APIRouter(tags=["render"])

#: Largest image edge: the CPU renders size^2 x 4 supersamples x K lookups in a worker.
MAX_GAUSSIAN_SIZE = 512
JobQuery = Annotated[str, Query(min_length=1, max_length=64, pattern=r"^[0-9a-f]+$")]


@router.get("/gaussian/render.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/x-exr": {}},
                             "headers": {"X-Visibility-Range": {"description": "min,max before clamping"}}},
                       **problem_responses(401, 404, 409, 422, 503)})
async def render_gaussian(
    fmt: Format,
    services: ServicesDep,
    fit: JobQuery,
    chain: JobQuery,
    visibility: Annotated[str | None, Query(min_length=1, max_length=64, pattern=r"^[0-9a-f]+$",
                                            description="a visibility job: draw its mesh, shadowed per mode")] = None,
    mode: Annotated[Literal["none", "ao", "sh", "sh-lobe"], Query(description="eq. 7's per-lobe visibility")]
    = "none",
    view: ViewQuery = "0,0,1",
    size: Annotated[int, Query(ge=8, le=MAX_GAUSSIAN_SIZE)] = 128,
    exposure: ExposureQuery = 0.0,
    tonemap: TonemapQuery = "aces",
) -> Response:
    """The fit's material lit by the chain, on the sphere or the visibility job's mesh (module docstring)."""
    v = _view(view)
    image, report = await gaussian_render(services, fit, chain, visibility, mode, v, size)
    attrs = {"relight.view": ",".join(f"{c:.9g}" for c in v), "relight.object": report.object,
             "relight.visibility": mode}
    headers = {"Cache-Control": "public, max-age=3600"}
    if report.unclamped_min is not None:
        rng = f"{report.unclamped_min:.6g},{report.unclamped_max:.6g}"
        attrs["relight.visibility_range"] = rng
        headers |= {"X-Visibility-Range": rng, "Access-Control-Expose-Headers": "X-Visibility-Range"}
    body = await in_thread(_encode, image, fmt, exposure, tonemap, attrs)
    return Response(body, media_type=MEDIA[fmt], headers=headers)
