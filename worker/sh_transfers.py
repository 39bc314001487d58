"""The ``sh_transfer`` job's task: per-vertex transfer matrices with interreflections for an SH table (seed 003 §5,
``relight.sh_prt_bounce``), what the viewer's brushed-metal panel draws with PRT shadows and interreflections.

The BRDF is fixed (the paper: "to include interreflections, the desired BRDF must be fixed and accounted for in the
global illumination simulation"): its table (``relight.sh_table.build_table`` at the request's order and resolution)
gives every bounce's exit radiance, in the frames of the request's tangent field (``relight.sh_render.frames_for``
on the mesh's normals; ``mesh`` uses the geometry's glTF tangents). Files, both world-frame ``(V, n, n)`` matrices
(unfolded: the GPU rotates ``T_p L'`` into each frame) packed by ``relight.vertex_texture.pack_float16`` as
little-endian float16 RGBA texels: ``direct.bin`` (``T^0``, shadows only) and ``transfer.bin`` (``T^0 + ... + T^B``).
Grey tables only (one matrix per vertex); a coloured BRDF's bounces differ per channel and are refused.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import to_core

OCTET = "application/octet-stream"


def compute_sh_transfer(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.spec import parse_frame_brdf
    from relight.errors import InputError
    from relight.mesh import geometry
    from relight.sh_prt_bounce import BounceSettings, vertex_transfer
    from relight.sh_render import frames_for
    from relight.sh_table import build_table
    from relight.vertex_texture import pack_float16

    t0 = time.perf_counter()
    ctx.report("tabulating", 0.05)
    order = int(request["order"])
    table = build_table(parse_frame_brdf(to_core(request["brdf"], ctx.store)), order=order,
                        resolution=int(request["resolution"]))
    if table.coefficients.shape[-1] != 1:
        raise InputError("sh_transfer: a coloured BRDF's interreflections differ per channel; use a grey BRDF")
    geo = request["geometry"]
    mesh = geometry.from_bytes(ctx.store.read(geo["sha256"]), int(geo["vertices"]), int(geo["faces"]),
                               source=f"geometry {geo['sha256']}")
    tangent = dict(request["tangent"])
    if tangent["kind"] == "mesh":
        tangent["tangents"] = mesh.tangents
    frames = frames_for(mesh.normals, tangent)
    ctx.report.check_cancelled()
    ctx.report("tracing", 0.2)
    settings = BounceSettings(rays=int(request["rays"]), bounces=int(request["bounces"]), seed=int(request["seed"]))
    vt = vertex_transfer(table, mesh, frames, settings)
    ctx.report.check_cancelled()
    ctx.report("writing", 0.95)
    files: dict[str, Any] = {}
    textures: dict[str, Any] = {}
    for name, values in (("direct.bin", vt.direct), ("transfer.bin", vt.total()[..., 0])):
        tex, layout = pack_float16(values)
        files[name] = {"sha256": ctx.store.put_bytes(np.ascontiguousarray(tex, dtype="<f2").tobytes()),
                       "media_type": OCTET}
        textures[name] = layout
    direct_norm = max(float(np.linalg.norm(vt.direct)), 1e-300)
    bounce_share = [float(np.linalg.norm(b)) / direct_norm for b in vt.bounces]
    return {"order": order, "coefficients": (order + 1) ** 2, "rays": settings.rays, "bounces": settings.bounces,
            "vertices": mesh.n_vertices, "brdf": request["brdf"], "tangent": request["tangent"],
            "textures": textures, "bounce_norm_ratio": bounce_share, "task_seconds": time.perf_counter() - t0,
            "files": files}
