"""Seed 002's precomputations as job kinds (Green, Kautz & Durand 2007): ``gaussian_fit`` (Gaussian lobes of one
BRDF, ``relight.sgfit``) and ``gaussian_chain`` (the Gaussian-prefiltered chain of one map, ``relight.gaussian_chain``).

A kind and nothing else (``server/README.md``, "Adding a kind of job"): submitted through ``POST /jobs {"kind":
"gaussian_fit" | "gaussian_chain", "request": {...}}``, followed through the job routes, its result (``GET
/jobs/{id}/result``: the ``gaussian-lobes`` material and the error table, or the chain's level list) and float16
files (``GET /jobs/{id}/files/{name}``) from the generic routes. The BRDF is resolved like the SHRM kind's (an id, a
spec string or object; measured files by digest only) and the map must exist, so a bad reference is a 4xx now
rather than a failed job later. The tasks are ``relight.worker.gaussian``'s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from relight.contract.models import GaussianChainCreate, GaussianFitCreate
from relight.server.services.kinds import JobKind, register
from relight.worker.gaussian import compute_gaussian_chain, compute_gaussian_fit

if TYPE_CHECKING:
    from relight.server.state import Services


async def _prepare_fit(create: GaussianFitCreate, services: Services) -> dict[str, Any]:
    brdf = await services.brdfs.resolve(create.brdf)
    return {"brdf": brdf.id, "brdf_spec": brdf.spec, **create.model_dump(mode="json", exclude={"brdf"})}


async def _prepare_chain(create: GaussianChainCreate, services: Services) -> dict[str, Any]:
    env = await services.envmaps.get(create.envmap)
    await services.envmaps.input_ok(env.id)
    return {"envmap": env.id, **create.model_dump(mode="json", exclude={"envmap"})}


GAUSSIAN_FIT = register(JobKind("gaussian_fit", compute_gaussian_fit, request=GaussianFitCreate,
                                prepare=_prepare_fit))
GAUSSIAN_CHAIN = register(JobKind("gaussian_chain", compute_gaussian_chain, request=GaussianChainCreate,
                                  prepare=_prepare_chain))
