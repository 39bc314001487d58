"""The ``gaussian_fit`` and ``gaussian_chain`` job kinds' tasks (seed 002: Green, Kautz & Durand 2007, §4, §5.1).

:func:`compute_gaussian_fit` fits Gaussian lobes to a BRDF (``relight.sgfit``; the request's ``brdf_spec`` is the
service's canonical spec, turned into the core's by ``relight.worker.specs.to_core``) and returns the
``gaussian-lobes`` material (the JSON of ``relight fit``, ~1 KB) with the fit report, plus ``lobes.bin``: the
paper's two K x N textures as little-endian float16, (N, K, 8) = (mu, sigma, 0, 0, w_r, w_g, w_b, 0) per texel
(radians), what the viewer uploads (``web/src/gaussian.js``).

:func:`compute_gaussian_chain` prefilters an uploaded map (``relight.gaussian_chain.build_chain``) and stores one
file per level, ``level_JJ.bin``: little-endian float16 RGB, H_j x 2 H_j x 3, row 0 = +Y (the lat-long layout of
``docs/conventions.md``), listed with sigma, size and orders in the result.

The elevations are fitted in sequence (each warm-starts the next: continuation, ``relight.sgfit``), so a fit is not
fanned out over workers; a chain is one projection plus a synthesis per level (about a second for 1024 x 512).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import from_core, to_core

OCTET = "application/octet-stream"


def compute_gaussian_fit(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    import math

    from relight.brdf.spec import parse_brdf
    from relight.sgfit import DEFAULT_EXTRA_LOBES, FitSettings, fit_gaussian_lobes

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    brdf = parse_brdf(to_core(request["brdf_spec"], ctx.store))
    lobes = int(request["lobes"])
    max_lobes = request.get("max_lobes")
    settings = FitSettings(lobes=lobes, elevations=int(request["elevations"]),
                           theta_max=math.radians(float(request["theta_max_deg"])),
                           max_lobes=min(lobes + DEFAULT_EXTRA_LOBES, 8) if max_lobes is None else int(max_lobes))
    ctx.report("fitting", 0.1)
    material = fit_gaussian_lobes(brdf, settings)
    ctx.report.check_cancelled()
    n, k = material.mu.shape
    tex = np.zeros((n, k, 8), dtype="<f2")
    tex[..., 0], tex[..., 1], tex[..., 4:7] = material.mu, material.sigma, material.weight
    digest = ctx.store.put_bytes(tex.tobytes())
    spec = from_core(material.spec(), ctx.store)
    return {"material": spec, "lobes": k, "elevations": n,
            "errors": [float(e) for e in material.fit["errors"]],
            "mid_errors": [float(e) for e in material.fit["mid_errors"]],
            "lobes_used": material.fit["lobes_used"], "fit_seconds": material.fit["seconds"],
            "task_seconds": time.perf_counter() - t0,
            "layout": "lobes.bin: float16 (N, K, 8) = mu, sigma, 0, 0, w_r, w_g, w_b, 0 (radians)",
            "files": {"lobes.bin": {"sha256": digest, "media_type": OCTET}}}


def compute_gaussian_chain(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.envmap import read_envmap, to_half_safe
    from relight.gaussian_chain import RATIOS, build_chain

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    env = read_envmap(ctx.store.read(request["envmap"]), max_pixels=ctx.max_pixels)
    ctx.report("prefiltering", 0.2)
    chain = build_chain(env.pixels, sigma0=request.get("sigma0"), ratio=RATIOS[request["ratio"]],
                        levels=request.get("levels"), epsilon=float(request["epsilon"]),
                        uniform_size=bool(request.get("uniform_size", False)))
    ctx.report.check_cancelled()
    files: dict[str, dict[str, str]] = {}
    levels = []
    clamped = 0
    for j, lv in enumerate(chain.levels):
        half, count = to_half_safe(np.asarray(lv.map))
        clamped += int(count)
        name = f"level_{j:02d}.bin"
        files[name] = {"sha256": ctx.store.put_bytes(np.ascontiguousarray(half, dtype="<f2").tobytes()),
                       "media_type": OCTET}
        levels.append({"file": name, "sigma": lv.sigma, "height": int(lv.map.shape[0]),
                       "width": int(lv.map.shape[1]), "orders": lv.orders})
    return {"sigma0": chain.sigma0, "ratio": chain.ratio, "levels": levels, "half_clamped": clamped,
            "layout": "level_JJ.bin: float16 RGB lat-long, H x 2H x 3, row 0 = +Y",
            "timings": chain.report["timings"], "blend_kernel_error": chain.report["blend_kernel_error"],
            "task_seconds": time.perf_counter() - t0, "files": files}
