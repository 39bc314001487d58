"""The in-out factorization analysis as a job kind (seed 004: Mahajan, Tseng & Ramamoorthi 2008):
``POST /jobs {"kind": "factorization", "request": {"brdf": SPEC_OR_ID, "domain": "hemisphere", "resolution": 40,
...}}``.

A kind and nothing else (``server/README.md``, "Adding a kind of job"): the request is validated by
:class:`FactorizationCreate`, the BRDF resolved like the SHRM and Gaussian-fit kinds' (an id, a spec string or
object; uploaded measured BRDFs by digest), so two spellings of one BRDF share one job and a bad BRDF is a 4xx now.
The task is :func:`relight.worker.factorizations.compute_factorization`; its result (the analysis: K per
threshold, singular values, predictions, convergence) and files (``factors.png``, ``factors.bin``) are served by
``GET /jobs/{id}/result`` and ``GET /jobs/{id}/files/{name}``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from relight.contract.models import BrdfRef
from relight.server.services.kinds import JobKind, register
from relight.worker.factorizations import compute_factorization

if TYPE_CHECKING:
    from relight.server.state import Services

#: Largest theta grid the service decomposes (block SVD: seconds at 512; the convergence check runs 1.5x finer).
MAX_RESOLUTION = 512
#: Largest azimuth count (blocks per grid); the dense SVD of an anisotropic BRDF is further capped at 6400 nodes.
MAX_PHI = 256


class FactorizationCreate(BaseModel):
    """An in-out factorization analysis of a BRDF (``relight factorize``)."""

    model_config = ConfigDict(extra="forbid")

    brdf: BrdfRef
    domain: Literal["hemisphere", "sphere"] = "hemisphere"
    resolution: int = Field(40, ge=4, le=MAX_RESOLUTION, description="Gauss-Legendre nodes in cos(theta) (and "
                            "azimuths unless phi is given): the paper's N^4 matrix")
    phi: int | None = Field(None, ge=4, le=MAX_PHI, description="azimuths (default: the resolution, at most 256)")
    grid: Literal["gauss", "equal-area"] = "gauss"
    include_cosine: bool = Field(True, description="factor f_r cos(theta_i) (relight's lobe value; default) or f_r")
    factors: int = Field(8, ge=0, le=16, description="leading factors returned as images")
    convergence: bool = Field(True, description="repeat at a 1.5x finer grid and report whether K changed")

    @model_validator(mode="after")
    def _phi(self) -> FactorizationCreate:
        if self.phi is None and self.resolution > MAX_PHI:
            raise ValueError(f"resolution {self.resolution} > {MAX_PHI} needs an explicit phi (<= {MAX_PHI})")
        return self


async def _prepare(create: FactorizationCreate, services: Services) -> dict[str, Any]:
    brdf = await services.brdfs.resolve(create.brdf)
    return {"brdf": brdf.id, "brdf_spec": brdf.spec, **create.model_dump(mode="json", exclude={"brdf"})}


FACTORIZATION = register(JobKind("factorization", compute_factorization, request=FactorizationCreate,
                                 prepare=_prepare))
