"""The ``ibl`` job kind (issue 17): engine-ready exports of an uploaded map, computed as jobs and cached.

Submitted through ``POST /jobs {"kind": "ibl", "request": {...}}`` or read as a resource, ``GET
/envmaps/{id}/ibl?target=...&format=ktx2|sh|gltf&size=...&brdf=...`` (``relight.server.api.routes.ibl``): the GET
submits (or joins) the job with the same canonical request and answers 202 with the job until it has succeeded, then
the file itself (``chain.ktx2``, ``lighting.glb`` or ``sh.json``; the manifest from ``GET /jobs/{id}/result``).
The job id is the hash of the canonical request, so every later GET with the same parameters is served from the
cache. The task is ``relight.worker.ibl``'s; its files are byte-identical to ``relight export`` / ``relight bake``
of the same map.

The ``dfg`` kind (``GET /dfg?size=&multiscatter=&format=exr|png|ktx2``, ``relight.server.api.routes.ibl``) is the
split-sum DFG table, ``relight dfg``'s file; its request has no reference to resolve (the default prepare).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from relight.contract.models import DfgCreate, IblCreate
from relight.errors import InputError
from relight.server.problems import Unprocessable
from relight.server.services.kinds import JobKind, register
from relight.worker.ibl import compute_dfg, compute_ibl

if TYPE_CHECKING:
    from relight.server.state import Services


async def _prepare(create: IblCreate, services: Services) -> dict[str, Any]:
    from relight.sun import parse_sun

    env = await services.envmaps.get(create.envmap)
    await services.envmaps.input_ok(env.id)
    try:
        parse_sun(create.sun)
    except InputError as exc:
        raise Unprocessable(f"sun: {exc}") from None
    if create.format == "sh":  # the chain's parameters do not change an SH export: one job for all of them
        return {"envmap": env.id, "format": "sh", "sun": create.sun}
    exclude = {"envmap"}
    if create.brdf is None:  # defaults are left out of the canonical request: earlier jobs keep their ids
        exclude.add("brdf")
    else:
        from relight.brdf.normal_view import ChainBrdf

        try:
            ChainBrdf(create.brdf)
        except InputError as exc:
            raise Unprocessable(f"brdf: {exc}") from None
    if create.pixel_format == "rgba16f":
        exclude.add("pixel_format")
    return {"envmap": env.id, **create.model_dump(mode="json", exclude=exclude)}


IBL = register(JobKind("ibl", compute_ibl, request=IblCreate, prepare=_prepare))
DFG = register(JobKind("dfg", compute_dfg, request=DfgCreate))
