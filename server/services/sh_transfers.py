"""Interreflected transfer for SH tables as a job kind (seed 003 §5): ``POST /jobs {"kind": "sh_transfer",
"request": {"mesh": ID, "brdf": SPEC_OR_ID, "order": 4, "resolution": 64, "tangent": {"kind": "project",
"direction": [1, 0.3, 0.2]}, "bounces": 1, "rays": 256}}``.

A kind and nothing else (``server/README.md``, "Adding a kind of job"): the mesh must exist (``POST /meshes``; its
``geometry.bin`` digest and counts go into the canonical request), the BRDF is made canonical as the ``sh_table``
kind does (422 naming the parameter; files refused; ids resolved), the tangent field is one of
``relight.sh_render.frames_for``'s. The task is :func:`relight.worker.sh_transfers.compute_sh_transfer`; its result
and files (``direct.bin``, ``transfer.bin``) are served by the generic job routes. Shadow-only matrices (BRDF
changeable on the fly) are the ``visibility`` kind's ``shadow_matrix``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from relight.server.services.kinds import JobKind, register
from relight.server.services.sh_tables import MAX_RESOLUTION, ShTableCreate
from relight.server.services.sh_tables import _prepare as prepare_table
from relight.worker.sh_transfers import compute_sh_transfer

if TYPE_CHECKING:
    from relight.server.state import Services


class TangentField(BaseModel):
    """A tangent field: ``project`` (a constant direction projected on each tangent plane, Kautz §6),
    ``azimuthal`` (``axis x n``, axis +Y by default) or ``mesh`` (the geometry's glTF tangents)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["project", "azimuthal", "mesh"]
    direction: list[float] | None = Field(None, min_length=3, max_length=3)
    axis: list[float] | None = Field(None, min_length=3, max_length=3)

    @field_validator("direction", "axis")
    @classmethod
    def _non_zero(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and (not all(math.isfinite(x) for x in v) or not any(v)):
            raise ValueError("must be a finite non-zero 3-vector")
        return v


class ShTransferCreate(BaseModel):
    """Per-vertex transfer matrices with interreflections of a mesh in one BRDF's SH table."""

    model_config = ConfigDict(extra="forbid")

    mesh: str = Field(pattern=r"^[0-9a-f]{64}$", description="a mesh id from POST /meshes")
    brdf: str | dict[str, Any] | list[Any] = Field(description="a grey BRDF spec or id (as the sh_table kind)")
    order: int = Field(4, ge=0, le=8, description="SH order F: (F+1)^2 x (F+1)^2 matrices")
    resolution: int = Field(64, ge=2, le=MAX_RESOLUTION, description="the table's view map size R")
    tangent: TangentField = Field(default_factory=lambda: TangentField(kind="azimuthal"))
    bounces: int = Field(1, ge=0, le=4, description="interreflection bounces B")
    rays: int = Field(256, ge=16, le=4096, description="rays per vertex (Fibonacci directions)")
    seed: int = Field(0, ge=0, le=2**31 - 1)


async def _prepare(create: ShTransferCreate, services: Services) -> dict[str, Any]:
    if create.tangent.kind == "project" and create.tangent.direction is None:
        from relight.server.problems import Unprocessable

        raise Unprocessable("tangent.direction: the project field needs a direction")
    mesh = await services.meshes.get(create.mesh)
    table = await prepare_table(ShTableCreate(brdf=create.brdf, order=create.order, resolution=create.resolution),
                                services)
    _grey_only(table["brdf"])
    geometry = {"sha256": mesh.geometry["sha256"], "vertices": mesh.vertices, "faces": mesh.faces}
    return {"mesh": mesh.id, "geometry": geometry, "brdf": table["brdf"],
            "tangent": create.tangent.model_dump(mode="json", exclude_none=True),
            **create.model_dump(mode="json", exclude={"mesh", "brdf", "tangent"})}


def _measured(spec: Any) -> bool:
    """Whether a canonical spec holds a measured (MERL) term anywhere (the service's ``{"kind": "merl", ...}``)."""
    if isinstance(spec, dict):
        return spec.get("kind") == "merl" or any(_measured(v) for v in spec.values())
    if isinstance(spec, list):
        return any(_measured(v) for v in spec)
    return False


def _grey_only(spec: Any) -> None:
    """422 for a coloured BRDF before any job exists: its bounces differ per channel (one matrix per vertex holds
    one channel; the worker refuses such a table too). A measured (MERL) BRDF is RGB by its format."""
    from relight.brdf.spec import parse_frame_brdf
    from relight.server.problems import Unprocessable

    if _measured(spec):
        raise Unprocessable("brdf: a measured BRDF is RGB, and a coloured BRDF's interreflections differ per "
                            "channel; sh_transfer takes a grey BRDF")
    if int(parse_frame_brdf(spec).channels) != 1:
        raise Unprocessable("brdf: a coloured BRDF's interreflections differ per channel; sh_transfer takes a grey "
                            "BRDF (one value per parameter)")


SH_TRANSFER = register(JobKind("sh_transfer", compute_sh_transfer, request=ShTransferCreate, prepare=_prepare))
