"""In-out factorized PRT data as a job kind (seed 004 eqs. 2–4): ``POST /jobs {"kind": "inout_prt", "request":
{"mesh": ID, "brdf": SPEC_OR_ID, "energy": 0.99, "order": 4, "rays": 1024, "shadows": true}}``.

A kind and nothing else (``server/README.md``, "Adding a kind of job"): the mesh must exist (``POST /meshes``; its
``geometry.bin`` digest and counts go into the canonical request, so the job names the exact vertices), the BRDF is
resolved like the other kinds' (id, spec string or object; isotropic: the block SVD), and the task is
:func:`relight.worker.inout.compute_inout`; its result and files (``transport.bin``, ``factors.bin``) are served
by the generic job routes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field

from relight.contract.models import BrdfRef
from relight.server.services.kinds import JobKind, register
from relight.worker.inout import compute_inout

if TYPE_CHECKING:
    from relight.server.state import Services


class InOutCreate(BaseModel):
    """Per-vertex in-out PRT transport of a mesh for one BRDF (``relight.inout_prt``)."""

    model_config = ConfigDict(extra="forbid")

    mesh: str = Field(pattern=r"^[0-9a-f]{64}$", description="a mesh id from POST /meshes")
    brdf: BrdfRef
    energy: float = Field(0.99, gt=0.0, lt=1.0, description="energy fraction the kept terms capture (the paper's "
                          "99 %); ignored when terms is given")
    terms: int | None = Field(None, ge=1, le=256, description="number of terms K (rounded up to whole pairs)")
    order: int = Field(4, ge=0, le=8, description="SH order F of the lighting: (F+1)^2 coefficients per term")
    rays: int = Field(1024, ge=16, le=16384, description="visibility rays per vertex")
    shadows: bool = True
    seed: int = Field(0, ge=0, le=2**31 - 1)


async def _prepare(create: InOutCreate, services: Services) -> dict[str, Any]:
    mesh = await services.meshes.get(create.mesh)
    brdf = await services.brdfs.resolve(create.brdf)
    geometry = {"sha256": mesh.geometry["sha256"], "vertices": mesh.vertices, "faces": mesh.faces}
    return {"mesh": mesh.id, "geometry": geometry, "brdf": brdf.id, "brdf_spec": brdf.spec,
            **create.model_dump(mode="json", exclude={"mesh", "brdf"})}


INOUT_PRT = register(JobKind("inout_prt", compute_inout, request=InOutCreate, prepare=_prepare))
