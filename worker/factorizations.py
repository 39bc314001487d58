"""The ``factorization`` job kind's task: the in-out factorization analysis of one BRDF (Mahajan, Tseng &
Ramamoorthi 2008; ``relight.factor_analysis``).

The result is the analysis document of ``relight factorize`` (``terms`` per threshold, ``terms_whole_groups``,
``singular_values`` with their azimuthal ``frequencies``, ``predicted_terms`` and ``prediction``, the resolution
``convergence`` check, grid, quantity, seconds) plus two files: ``factors.png`` (the leading factors as images, g_k
above h_k: ``relight.factor_analysis.factor_image``) and ``factors.bin`` (little-endian float16 ``[F, 2, n_theta,
n_phi]``: g_k then h_k on the grid nodes, rows the ``grid.theta`` nodes, columns the ``grid.phi`` azimuths, both
listed in the result). The request's ``brdf_spec`` is the service's canonical spec (``relight.worker.specs``), so
uploaded measured BRDFs are analysed too.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import from_core, to_core

OCTET = "application/octet-stream"


def compute_factorization(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.spec import parse_brdf
    from relight.envmap.exr import to_half_safe
    from relight.factor_analysis import analyse, factor_image, png_bytes

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    brdf = parse_brdf(to_core(request["brdf_spec"], ctx.store))
    ctx.report("decomposing", 0.1)
    doc, res = analyse(brdf, domain=str(request["domain"]), resolution=int(request["resolution"]),
                       phi=request.get("phi"), grid=str(request["grid"]),
                       include_cosine=bool(request["include_cosine"]), factors=int(request["factors"]),
                       check_convergence=bool(request["convergence"]))
    ctx.report.check_cancelled()
    doc["brdf"] = from_core(doc["brdf"], ctx.store)
    files: dict[str, dict[str, str]] = {}
    doc["grid_nodes"] = {"theta": [float(x) for x in res.grid.theta], "phi": [float(x) for x in res.grid.phi]}
    if res.factors:
        ctx.report("writing", 0.9)
        stack = np.stack([np.stack([f.g, f.h]) for f in res.factors])  # (F, 2, n_theta, n_phi)
        half, clamped = to_half_safe(stack)
        files["factors.bin"] = {"sha256": ctx.store.put_bytes(np.ascontiguousarray(half, dtype="<f2").tobytes()),
                                "media_type": OCTET}
        files["factors.png"] = {"sha256": ctx.store.put_bytes(png_bytes(factor_image(res))),
                                "media_type": "image/png"}
        doc["factors"]["layout"] = ("factors.bin: float16 [F, 2, n_theta, n_phi], g then h on the grid nodes; "
                                    "factors.png: g row above h row, hemisphere disks seen from the normal")
        doc["factors"]["shape"] = list(stack.shape)
        doc["factors"]["float16_clamped"] = int(clamped)
    doc["task_seconds"] = time.perf_counter() - t0
    return {"analysis": doc, "files": files}
