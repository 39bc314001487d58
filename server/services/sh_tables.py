"""Per-view SH tables as jobs (the ``sh_table`` kind; seed 003 §3): ``POST /jobs {"kind": "sh_table", "request":
{"brdf": SPEC, "order": 4, "resolution": 128, "layout": "parabolic"}}``.

A kind with no route of its own (``relight.server.services.kinds``): the request is validated by
:class:`ShTableCreate`, the BRDF parsed by ``relight.brdf.spec.parse_frame_brdf`` (isotropic, anisotropic) and made
canonical (its ``spec()``), so two spellings of one BRDF share one job; an invalid BRDF is a 422 naming the
parameter. Specs that name files (``merl``, ``measured``, ``lobe1d`` with a path) are refused: a job never reads
the server's file system. A BRDF *id* (``POST /brdfs``, or a measured MERL file uploaded with ``POST
/brdfs/measured``) names a registered BRDF (404 when unknown): measured ones travel as ``{"kind": "merl", "sha256":
...}`` and become the blob's path only inside the worker (``relight.worker.specs.to_core``). The task is
:func:`relight.worker.sh_tables.compute_sh_table`; its result (the manifest) and files (``table.npz``,
``table.bin``) are served by ``GET /jobs/{id}/result`` and ``GET /jobs/{id}/files/{name}``. Transfer matrices
are the ``visibility`` kind (``kind: shadow_matrix``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from relight.errors import InputError
from relight.server.problems import Unprocessable
from relight.server.services.kinds import JobKind, register
from relight.worker.blobs import DIGEST_RE
from relight.worker.sh_tables import compute_sh_table

if TYPE_CHECKING:
    from relight.server.state import Services

#: Largest table the service computes (R = 256: 4x the paper's 128 x 128 texels).
MAX_RESOLUTION = 256


class ShTableCreate(BaseModel):
    """A per-view SH table of a BRDF (``relight sh-table``)."""

    model_config = ConfigDict(extra="forbid")

    brdf: str | dict[str, Any] | list[Any] = Field(description="BRDF spec (string, object or list of lobes), "
                                                               "isotropic or anisotropic, or a BRDF id (e.g. of "
                                                               "a MERL file uploaded with POST /brdfs/measured)")
    order: int = Field(4, ge=0, le=8, description="SH order F: l <= F, (F+1)^2 coefficients (4: the paper's 25)")
    resolution: int = Field(128, ge=2, le=MAX_RESOLUTION, description="view map size R (R x R texels)")
    layout: Literal["parabolic", "hemi-octahedral"] = "parabolic"


def _no_files(spec: Any) -> None:
    if isinstance(spec, dict):
        if "path" in spec or spec.get("kind") in ("merl", "measured"):
            raise Unprocessable("brdf: specs that name files (merl, measured, lobe1d paths) are not accepted by "
                                "sh_table jobs")
        for v in spec.values():
            _no_files(v)
    elif isinstance(spec, list):
        for v in spec:
            _no_files(v)
    elif isinstance(spec, str) and spec.split(":", 1)[0].strip() in ("merl", "measured"):
        raise Unprocessable("brdf: specs that name files (merl, measured) are not accepted by sh_table jobs")


async def _prepare(create: ShTableCreate, services: Services) -> dict[str, Any]:
    from relight.brdf.spec import parse_frame_brdf

    if isinstance(create.brdf, str) and DIGEST_RE.match(create.brdf):
        registered = await services.brdfs.get(create.brdf)  # 404 when unknown
        if registered.measured:  # checked by the core on upload; the worker reads the blob
            return {"brdf": registered.spec, "order": create.order, "resolution": create.resolution,
                    "layout": create.layout}
        create = create.model_copy(update={"brdf": registered.spec})
    _no_files(create.brdf)
    try:
        spec = parse_frame_brdf(create.brdf).spec()
    except InputError as exc:
        raise Unprocessable(f"brdf: {exc}") from None
    _no_files(spec)
    return {"brdf": spec, "order": create.order, "resolution": create.resolution, "layout": create.layout}


SH_TABLE = register(JobKind("sh_table", compute_sh_table, request=ShTableCreate, prepare=_prepare))
