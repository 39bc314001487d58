"""The ``inout_prt`` job kind's task: in-out factorized PRT data of one (mesh, BRDF) pair (Mahajan, Tseng &
Ramamoorthi 2008, eqs. 2–3; ``relight.inout_factors``, ``relight.inout_prt``), what the viewer's in-out object draws
(``web/src/inout_object.js``, ``web/shaders/inout.vert.glsl``).

Files: ``transport.bin`` (the per-vertex transport T (V, K, (F+1)^2) packed by ``relight.vertex_texture.pack_float16``
as little-endian float16 RGBA texels, layout in the result's ``transport_texture``) and ``factors.bin`` (little-endian
float32 (K, N + 2): m, parity, then sigma_k times h_k's radial profile; the shader's ``u_factors``). The result also
lists sigma, m, parity, the captured energy, the predicted truncation error and the RMS Monte Carlo error of T.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import to_core

OCTET = "application/octet-stream"


def compute_inout(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.spec import parse_brdf
    from relight.gl.inout import factor_texture
    from relight.inout_factors import build_factors
    from relight.inout_prt import frame_operations, mesh_transport
    from relight.mesh import geometry
    from relight.vertex_texture import pack_float16

    t0 = time.perf_counter()
    ctx.report("factoring", 0.05)
    brdf = parse_brdf(to_core(request["brdf_spec"], ctx.store))
    terms = request.get("terms")
    f = build_factors(brdf, terms=None if terms is None else int(terms), energy=float(request["energy"]))
    ctx.report.check_cancelled()
    geo = request["geometry"]
    mesh = geometry.from_bytes(ctx.store.read(geo["sha256"]), int(geo["vertices"]), int(geo["faces"]),
                               source=f"geometry {geo['sha256']}")
    ctx.report("tracing", 0.2)
    order = int(request["order"])
    out = mesh_transport(mesh, f, order, rays=int(request["rays"]), seed=int(request["seed"]),
                         shadows=bool(request["shadows"]))
    ctx.report.check_cancelled()
    ctx.report("writing", 0.95)
    tex, layout = pack_float16(out["transport"])
    files = {"transport.bin": {"sha256": ctx.store.put_bytes(np.ascontiguousarray(tex, dtype="<f2").tobytes()),
                               "media_type": OCTET},
             "factors.bin": {"sha256": ctx.store.put_bytes(np.ascontiguousarray(factor_texture(f), dtype="<f4")
                                                           .tobytes()), "media_type": OCTET}}
    err = out["transport_error"].reshape(mesh.n_vertices, -1)
    return {**f.manifest(), "order": order, "rays": int(request["rays"]), "shadows": bool(request["shadows"]),
            "vertices": mesh.n_vertices, "transport_texture": layout,
            "factors_texture": {"width": int(f.theta.size + 2), "height": f.terms, "format": "R32F",
                                "rows": "m, parity, sigma_k h_k(theta_i), theta_i = i (pi/2) / (N - 1)"},
            "monte_carlo_error_rms": float(np.sqrt(np.mean(np.sum(err * err, axis=1)))),
            "frame_operations": frame_operations(mesh.n_vertices, f.terms, order),
            "task_seconds": time.perf_counter() - t0, "files": files}
