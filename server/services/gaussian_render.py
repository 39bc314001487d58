"""Seed 002's render route behind ``GET /gaussian/render.{png,exr}`` (Green, Kautz & Durand 2007, §5, eqs. 5, 7):
a ``gaussian_fit`` result lit by a ``gaussian_chain`` result, optionally shadowed by a ``visibility`` result.

The three are job ids of the one job system (``relight.server.services.gaussian``, ``.visibility``); each must have
succeeded (409 otherwise, 404 for an unknown id or one of another kind). Without visibility the unit sphere is
drawn; with it, the visibility job's mesh (its ``geometry.bin``, normalised into the unit ball as the CLI does)
with eq. 7's per-lobe visibility (``mode``: none, ao, sh, sh-lobe; ``relight.sg_shadow``). The image is computed in
a worker (:func:`relight.worker.gaussian_render.gaussian_image`) and kept in the render service's bounded image
cache, keyed by the three ids (content hashes of their canonical requests), the mode, view and size.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from relight.contract.models import JobState
from relight.errors import InputError
from relight.server.problems import Conflict, Unavailable, Unprocessable
from relight.server.services.base import content_id
from relight.worker import gaussian_render as tasks

if TYPE_CHECKING:
    from relight.server.state import Services
    from relight.sg_render import GaussianRenderReport

GAUSSIAN_RENDER_TIMEOUT_S: Final = 300.0
MODES: Final = ("none", "ao", "sh", "sh-lobe")


async def _result(services: Services, job_id: str, kind: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(request, result) of a succeeded job of ``kind`` whose files are intact (503 and recomputed otherwise)."""
    row = await services.jobs.row(job_id, kind)
    if row.state != JobState.succeeded or row.result is None:
        raise Conflict(f"{kind} job {job_id} is {row.state}; it has no result yet", state=row.state)
    await services.jobs.require_files(row)
    return dict(row.request or {}), dict(row.result)


async def gaussian_render(services: Services, fit: str, chain: str, visibility: str | None, mode: str,
                          view: list[float], size: int) -> tuple[np.ndarray, GaussianRenderReport]:
    """The (size, size, 3) image and its report (module docstring)."""
    if mode not in MODES:
        raise Unprocessable(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if mode != "none" and visibility is None:
        raise Unprocessable(f"mode {mode!r} needs a visibility job (the sphere does not shadow itself)")
    key = ("gaussian", fit, chain, visibility, mode, tuple(view), size)
    cached = services.render.cached(key)
    if cached is not None:
        return cached  # type: ignore[no-any-return]
    _, fit_result = await _result(services, fit, "gaussian_fit")
    _, chain_result = await _result(services, chain, "gaussian_chain")
    material = {k: fit_result["material"][k] for k in ("kind", "elevations")}
    geometry = npz = None
    if visibility is not None:
        vis_request, _ = await _result(services, visibility, "visibility")
        _, manifest = await services.visibility.manifest(visibility)
        geometry = vis_request["geometry"]
        npz = str(manifest["files"]["visibility.npz"]["sha256"])
        await services.jobs.verified_file(visibility, npz)
    fut = services.cluster.submit(tasks.gaussian_image, str(services.store.root), material, chain_result, view, size,
                                  geometry=geometry, visibility_npz=npz, mode=mode,
                                  key=f"relight-gaussian-render-{content_id(list(key))}")
    try:
        image, report = await asyncio.wait_for(fut, GAUSSIAN_RENDER_TIMEOUT_S)
    except (InputError, ValueError, KeyError) as exc:
        raise Unprocessable(f"cannot render this fit, chain and visibility: {exc}") from None
    except TimeoutError:
        await services.cluster.cancel(fut)
        raise Unavailable(f"the render took longer than {GAUSSIAN_RENDER_TIMEOUT_S:.0f} s; ask for a smaller size",
                          headers={"Retry-After": "10"}) from None
    except asyncio.CancelledError:
        await services.cluster.cancel(fut)
        raise
    out = (np.asarray(image), report)
    services.render.keep(key, out)
    return out
