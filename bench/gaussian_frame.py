"""Seed 002 per-frame cost on the GPU path (moderngl; llvmpipe here): Gaussian lobes vs a plain environment lookup.

    .venv/bin/python bench/gaussian_frame.py [--size 512] [--frames 20] [--json OUT.json]

One run, one GL context: the unit sphere and the ~100K-vertex bunny (``bunny-100k``) drawn with the chain's sharpest
level looked up at R (``plain``: one bilinear lookup per pixel in an RGBA16F 2-D texture, the baseline), K = 3
Gaussian lobes (eq. 5: two rows of the lobe table, two unfiltered RGBA32UI fetches each, and per lobe one
trilinear lookup in the chain's 3-D texture), and K = 3 with 16-coefficient SH visibility at the lobe centres
(eq. 7, ``sh``) or convolved with the lobes (``sh-lobe``), all through ``web/shaders/gaussian*.glsl``
(``relight.gl.gaussian``). Milliseconds per frame (the
median of ``--repeats`` timed batches of ``--frames`` frames each, after a warm-up; the shaders take turns batch by
batch, so a change of the shared machine's load hits them alike; the load average is in the JSON) and the ratio to
``plain`` of the same object (the issue's target: <= 3x for K = 3 + SH16). SwiftShader/llvmpipe absolute times
say nothing about a GPU; the ratios are the figure.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path

import numpy as np

from relight import resources
from relight.brdf.models import TorranceSparrow
from relight.envmap import read_envmap, resample_latlong
from relight.gaussian_chain import build_chain
from relight.gl.gaussian import GaussianRenderer
from relight.mesh import sample_mesh
from relight.sgfit import FitSettings, fit_gaussian_lobes
from relight.visibility import TransferSettings, compute_transfer


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mesh", default="bunny-100k")
    ap.add_argument("--rays", type=int, default=64, help="visibility rays per vertex (values do not change timing)")
    ap.add_argument("--json")
    args = ap.parse_args()
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "courtyard.exr"))
    px = np.asarray(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 256), dtype=np.float64)
    fit = fit_gaussian_lobes(TorranceSparrow(0.2, fresnel="none"), FitSettings(max_lobes=3))
    chain = build_chain(px, sigma0=math.pi / 256, ratio=math.sqrt(2), uniform_size=True)
    mesh = sample_mesh(args.mesh).normalised()
    t0 = time.perf_counter()
    vis = compute_transfer(mesh, TransferSettings(order=3, rays=args.rays)).arrays["visibility"]
    vis_s = time.perf_counter() - t0
    r = GaussianRenderer(fit, chain)
    bufs = r.mesh_buffers(mesh, vis)
    view = np.array([0.3, 0.4, 1.0])
    cases = [("plain", {"plain": True}), ("K3", {}), ("K3+SH16", {"mode": "sh"}), ("K3+SH16 lobe", {"mode": "sh-lobe"})]
    out: dict[str, object] = {"size": args.size, "frames": args.frames, "mesh": args.mesh,
                              "vertices": mesh.n_vertices, "lobes": fit.n_lobes, "levels": len(chain.levels),
                              "visibility_seconds": vis_s, "load_average": os.getloadavg(), "objects": {}}
    print(f"{args.size}x{args.size}, K = {fit.n_lobes}, {len(chain.levels)} chain levels of "
          f"{chain.levels[0].map.shape[0]} rows; {args.mesh}: {mesh.n_vertices} vertices")
    print(f"{'object':>10} {'shader':>14} {'ms/frame':>10} {'x plain':>8}")
    for obj in ("sphere", "mesh"):
        mesh_kw = {} if obj == "sphere" else {"mesh": bufs}
        todo = [(name, kw) for name, kw in cases if obj == "mesh" or "mode" not in kw]
        for _, kw in todo:
            r.render(view, args.size, frames=2, **mesh_kw, **kw)  # type: ignore[arg-type]  # warm-up, compile
        times: dict[str, list[float]] = {name: [] for name, _ in todo}
        for _ in range(args.repeats):  # round robin: a change of the machine's load hits every shader alike
            for name, kw in todo:
                t0 = time.perf_counter()
                r.render(view, args.size, frames=args.frames, **mesh_kw, **kw)  # type: ignore[arg-type]
                times[name].append((time.perf_counter() - t0) / args.frames * 1e3)
        rows = {name: statistics.median(t) for name, t in times.items()}
        for name, ms in rows.items():
            print(f"{obj:>10} {name:>14} {ms:10.2f} {ms / rows['plain']:8.2f}")
        out["objects"][obj] = {name: {"ms": ms, "ratio": ms / rows["plain"]} for name, ms in rows.items()}  # type: ignore[index]
    r.release()
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text)


if __name__ == "__main__":
    main()
