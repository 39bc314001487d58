"""The ``gaussian_fit`` and ``gaussian_chain`` job kinds' tasks (seed 002: Green, Kautz & Durand 2007, §4, §5.1).

:func:`compute_gaussian_fit` fits Gaussian lobes to a BRDF (``relight.sgfit``; the request's ``brdf_spec`` is the
service's canonical spec, turned into the core's by ``relight.worker.specs.to_core``) and returns the
``gaussian-lobes`` material (the JSON of ``relight fit``, ~1 KB) with the fit report, plus ``lobes.bin``: the
paper's two K x N textures as little-endian float16, (N, K, 8) = (mu, sigma, 0, 0, w_r, w_g, w_b, 0) per texel
(radians), what the viewer uploads (``web/src/gaussian.js``).

:func:`compute_gaussian_chain` prefilters an uploaded map (``relight.gaussian_chain.build_chain``) and stores one
file per level, ``level_JJ.bin``: little-endian float16 RGB, H_j x 2 H_j x 3, row 0 = +Y (the lat-long layout of
``docs/conventions.md``), listed with sigma, size and orders in the result.

A fit fans out over elevations: the part of each elevation's fit that depends on nothing else (its slice and the
fits from the cold starts, ``relight.sgfit.cold_elevation``) runs as one Dask task per elevation
(:func:`gaussian_cold_task`, submitted through ``distributed.worker_client``; the job's thread secedes while it
waits), then the continuation across elevations, the ordering and the bisection run in the job. The cold part is a
pure function of (BRDF spec, settings, theta_o), so the fanned-out fit equals the serial one (a direct call, outside
a worker, maps it in turn). A chain is one projection plus a synthesis per level (about a second for 1024 x 512).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import from_core, to_core

OCTET = "application/octet-stream"


def fit_settings(request: dict[str, Any]) -> Any:
    """The core's ``FitSettings`` of a canonical ``gaussian_fit`` request."""
    import math

    from relight.sgfit import DEFAULT_EXTRA_LOBES, FitSettings

    lobes = int(request["lobes"])
    max_lobes = request.get("max_lobes")
    return FitSettings(lobes=lobes, elevations=int(request["elevations"]),
                       theta_max=math.radians(float(request["theta_max_deg"])),
                       max_lobes=min(lobes + DEFAULT_EXTRA_LOBES, 8) if max_lobes is None else int(max_lobes))


def gaussian_cold_task(core_spec: Any, settings: Any, theta: float, first: bool) -> tuple[Any, str]:
    """One elevation's independent part (``relight.sgfit.cold_elevation``) and the process that computed it."""
    import os
    import socket

    from relight.brdf.spec import parse_brdf
    from relight.sgfit import cold_elevation

    return cold_elevation(parse_brdf(core_spec), settings, theta, first), f"{socket.gethostname()}:{os.getpid()}"


def _cold_map(ctx: JobContext, core_spec: Any, settings: Any, processes: set[str]) -> Any:
    """A ``relight.sgfit.ColdMap`` running one Dask task per elevation when on a worker, in turn otherwise."""
    fanned = True
    try:
        from distributed import get_worker, worker_client

        get_worker()
    except (ImportError, ValueError):
        fanned = False

    def run(items: list[tuple[float, bool]]) -> list[Any]:
        done: dict[int, Any] = {}
        if not fanned:
            for i, (th, first) in enumerate(items):
                done[i], proc = gaussian_cold_task(core_spec, settings, th, first)
                processes.add(proc)
                ctx.report("fitting elevations", 0.1 + 0.6 * (i + 1) / len(items))
            return [done[i] for i in range(len(items))]
        import distributed

        as_completed: Any = distributed.as_completed  # untyped
        with worker_client() as client:
            prefix = f"relight-gaussian-cold-{ctx.report.job_id}-{ctx.report.submission}"
            futures = {client.submit(gaussian_cold_task, core_spec, settings, th, first, pure=False,
                                     key=f"{prefix}-{i}"): i for i, (th, first) in enumerate(items)}
            try:
                for fut in as_completed(list(futures)):
                    done[futures[fut]], proc = fut.result()
                    processes.add(proc)
                    ctx.report("fitting elevations", 0.1 + 0.6 * len(done) / len(items))
            finally:
                client.cancel([f for f in futures if not f.done()])
        return [done[i] for i in range(len(items))]

    return run


def compute_gaussian_fit(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.spec import parse_brdf
    from relight.sgfit import fit_gaussian_lobes

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    core_spec = to_core(request["brdf_spec"], ctx.store)
    brdf = parse_brdf(core_spec)
    settings = fit_settings(request)
    ctx.report("fitting", 0.1)
    processes: set[str] = set()
    material = fit_gaussian_lobes(brdf, settings, cold_map=_cold_map(ctx, core_spec, settings, processes))
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
            "elevations_inserted": material.fit["elevations_inserted"], "processes": len(processes),
            "task_seconds": time.perf_counter() - t0,
            "layout": "lobes.bin: float16 (N, K, 8) = mu, sigma, 0, 0, w_r, w_g, w_b, 0 (radians)",
            "files": {"lobes.bin": {"sha256": digest, "media_type": OCTET}}}


def compute_gaussian_chain(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.envmap import read_envmap, to_half_safe
    from relight.gaussian_chain import RATIOS, build_chain

    t0 = time.perf_counter()
    ctx.report("loading", 0.05)
    env = read_envmap(ctx.store.read(ctx.store.stored_envmap(request["envmap"])), max_pixels=ctx.max_pixels)
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
            "timings": chain.report.timings, "blend_kernel_error": chain.report.blend_kernel_error,
            "task_seconds": time.perf_counter() - t0, "files": files}
