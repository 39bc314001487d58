"""How far the split-sum approximation (what every engine does) is from the GGX material it stands for, at grazing
views (issue 17, item 5): writes docs/accuracy/splitsum.md.

The material: GGX with alpha = r^2, the height-correlated Smith visibility and F = 1 (F0 = 1, so the DFG's
``A + B``): ``L_o(n, v) = int L(l) D(h) V(n.v, n.l) (n.l)+ dl``, the BRDF relight's SHRM of a ``ggx`` material
represents to its stated tolerance (docs/accuracy/README.md) and that ``relight.dfg`` integrates. Here it is the
pixel sum over the whole map (every pixel with its exact solid angle), the brute force the SHRM is measured against.

The split-sum: ``LD(R) (A + B)(n.v, r)`` with ``R = reflect(-v, n)``, ``LD`` the engines' prefilter lobe
(``relight.brdf.splitsum.GGXSplitSum``: view = normal, ``D(h) (R.l)+`` normalised) summed over the same pixels, and
``(A, B)`` relight's DFG table terms (``relight.dfg.dfg_terms``, within 2e-5 of adaptive quadrature). Both sides use
the same pixels and point sampling, so the difference is the approximation's, not the quadrature's (down to
r ~ 0.1 at 512 rows, where the lobe is ~3 pixels wide and both sums are coarse).

Per map, roughness and N.V: ``--normals`` random normals (fixed seed), each with one random view azimuth; the
error is relight's metric on luminance over them, ``sqrt(mean((split - exact)^2) / mean(exact^2))``, and the bias
``mean(split) / mean(exact) - 1``. ``--rows`` area-averages the maps first (``resample_latlong``). At grazing
views the split-sum's lobe about R reaches below the horizon (the ground, dark in city and courtyard) where the
material's lobe is cut off, besides being the wrong shape: both show here.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "accuracy" / "splitsum.md"


def frames(n: np.ndarray, nov: float, rng: np.random.Generator) -> np.ndarray:
    """A unit view per normal with ``n . v = nov`` at a random azimuth about n."""
    helper = np.where(np.abs(n[:, 1:2]) < 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    a = rng.uniform(0, 2 * np.pi, n.shape[0])[:, None]
    s = np.sqrt(1 - nov * nov)
    return np.asarray(nov * n + s * (np.cos(a) * t1 + np.sin(a) * t2))


def evaluate(px: np.ndarray, r: float, nov: float, normals: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
    from relight.brdf.splitsum import GGXSplitSum, ggx_d
    from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, pixel_solid_angles
    from relight.dfg import dfg_terms, v_smith_ggx_correlated

    h, w = px.shape[:2]
    dirs = latlong_dirs(h, w).reshape(-1, 3)
    lw = (px * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3) @ LUMINANCE_WEIGHTS  # L Omega, luminance
    views = frames(normals, nov, rng)
    refl = 2 * nov * normals - views
    alpha = r * r
    lobe = GGXSplitSum(r)
    a, b = dfg_terms(np.array([nov]), np.array([r]))[0]
    exact = np.empty(len(normals))
    split = np.empty(len(normals))
    for i, (n, v, rr) in enumerate(zip(normals, views, refl, strict=True)):
        nol = dirs @ n
        hv = dirs + v
        hv /= np.linalg.norm(hv, axis=1, keepdims=True)
        noh = hv @ n
        f = ggx_d(noh * noh, alpha) * v_smith_ggx_correlated(np.float64(nov), np.maximum(nol, 1e-12),
                                                              np.float64(alpha)) * np.maximum(nol, 0.0)
        exact[i] = float(lw @ np.where(nol > 0, f, 0.0))
        split[i] = float(lw @ lobe.u(dirs @ rr)[:, 0]) * (a + b)
    # relight's one error metric (relight/metrics.py): RMS of the difference over the RMS of the reference
    return {"rms": float(np.sqrt(np.mean((split - exact) ** 2) / np.mean(exact**2))),
            "bias": float(np.mean(split) / np.mean(exact) - 1.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", default="city,courtyard")
    ap.add_argument("--rows", type=int, default=256, help="area-average the maps to this many rows")
    ap.add_argument("--roughness", default="0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8")
    ap.add_argument("--nov", default="0.1,0.25,0.5,1.0")
    ap.add_argument("--normals", type=int, default=24)
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    from relight.envmap import read_envmap, resample_latlong

    t0 = time.perf_counter()
    rough = [float(x) for x in args.roughness.split(",")]
    novs = [float(x) for x in args.nov.split(",")]
    lines = []
    # the quadrature's own error: on a uniform map both sides equal A + B exactly, so any difference is the pixel
    # sum's (sharp lobes at grazing views); rows whose check is not small are resolution-limited
    check_normals = np.random.default_rng(5).normal(size=(8, 3))
    check_normals /= np.linalg.norm(check_normals, axis=1, keepdims=True)
    ones = np.ones((args.rows, 2 * args.rows, 3))
    check = {r: evaluate(ones, r, min(novs), check_normals, np.random.default_rng(6))["bias"] for r in rough}
    for name in args.maps.split(","):
        px = np.asarray(read_envmap(ROOT / "data" / "envmaps" / f"{name}.exr").pixels, dtype=np.float64)
        if px.shape[0] > args.rows:
            px = np.asarray(resample_latlong(px, args.rows), dtype=np.float64)
        rng = np.random.default_rng(11)
        normals = rng.normal(size=(args.normals, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        for r in rough:
            cells = [evaluate(px, r, c, normals, np.random.default_rng(int(1000 * r + 100 * c))) for c in novs]
            lines.append(f"| {name} | {r:.1f} | " + " | ".join(f"{e['rms']:.1%} ({e['bias']:+.1%})" for e in cells)
                         + f" | {check[r]:+.1%} |")
    head = " | ".join(f"N.V = {c:g}" for c in novs)
    text = f"""# How far the split-sum approximation is from the GGX material

Generated by `python bench/splitsum_accuracy.py` (do not edit by hand; rerun it). {time.perf_counter() - t0:.0f} s.

Every engine (three.js PMREM, Filament, Babylon, glTF-IBL-Sampler) shades a GGX material from a prefiltered
environment as `LD(R) (F0 A + B)`: the lighting convolved with the lobe *for view = normal*, times the DFG table.
The exact material integrates the lighting against the view's own lobe, which at grazing views is stretched and
tilted away from R, and cut by the horizon where the prefiltered lobe about R is not. Below: relative RMS
(relight's metric, luminance, over {args.normals} random normals with one random view azimuth each) of
`LD(R) (A + B)` against the exact integral `int L D V (n.l)+ dl` (F = 1, height-correlated Smith, alpha = r^2),
both summed over every pixel of the map ({args.rows} rows, area-averaged); in brackets the bias
`mean(split) / mean(exact) - 1`.
relight's SHRM of the same `ggx` material reproduces the exact integral to its own stated tolerance at every
view (docs/accuracy/README.md, docs/accuracy/grazing.md), so this is also how far an engine's result is from
relight's. Method: `bench/splitsum_accuracy.py`'s docstring.

The last column is the same comparison on a uniform map at N.V = {min(novs):g}, where both sides are exactly
`A + B`: it is the pixel sum's own error, and a row where it is not small (the sharpest lobes at the most grazing
view) is limited by the map's resolution, not by the split-sum.

| map | r | {head} | uniform-map check |
|---|---|{'---|' * (len(novs) + 1)}
""" + "\n".join(lines) + "\n"
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
