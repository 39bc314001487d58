"""Seed 002's Figures 3 and 4 for relight's fits (Green, Kautz & Durand 2007): parameters and error vs elevation.

    .venv/bin/python bench/fit_figures.py [--out bench/results]

Fig. 4: relative L2 fit error against theta_o for five isotropic BRDFs (the paper: five MERL materials; no MERL file
ships, so analytic models of increasing gloss), K = 3 fixed (the paper's) and K = 3 with lobes added where the
error exceeds 5 % (relight's default), interpolated mid-elevations dotted. Fig. 3: mu, sigma and the weight of each
lobe against theta_o for Torrance-Sparrow alpha 0.2 (the paper shows them as two K x N textures). PNGs
(matplotlib, Agg) and the numbers as JSON in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from relight.brdf.spec import parse_brdf
from relight.sgfit import DEFAULT_EXTRA_LOBES, FitSettings, fit_gaussian_lobes

BRDFS = ["torrance-sparrow:alpha=0.1,fresnel=none", "torrance-sparrow:alpha=0.2,fresnel=none",
         "torrance-sparrow:alpha=0.4,fresnel=none", "ggx:alpha=0.2", "phong:s=64"]


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data: dict[str, object] = {}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, (label, extra) in zip(axes, (("K = 3", 0), ("K = 3 + lobes where needed", DEFAULT_EXTRA_LOBES)),
                                  strict=True):
        for spec in BRDFS:
            t0 = time.perf_counter()
            m = fit_gaussian_lobes(parse_brdf(spec), FitSettings(max_lobes=3 + extra))
            secs = time.perf_counter() - t0
            deg = np.degrees(m.elevations)
            mid = np.degrees(np.asarray(m.fit["mid_elevations"]))
            e = np.asarray(m.fit["errors"])
            me = np.asarray(m.fit["mid_errors"])
            line = ax.plot(deg, 100 * e, marker="o", ms=3, label=spec.split(",")[0])[0]
            ax.plot(mid, 100 * me, ls=":", color=line.get_color())
            data[f"{label} | {spec}"] = {"theta_o_deg": deg.tolist(), "errors": e.tolist(), "mid_deg": mid.tolist(),
                                         "mid_errors": me.tolist(), "lobes_used": m.fit["lobes_used"],
                                         "seconds": secs}
            print(f"{label:28s} {spec:42s} max error {100 * e.max():6.2f} % (at {deg[np.argmax(e)]:.0f} deg), "
                  f"mid/neighbour <= {np.max(me / np.maximum(e[:-1], e[1:])):.2f}, {secs:.1f} s")
        ax.set_title(f"Fig. 4: fit error vs elevation, {label}")
        ax.set_xlabel("theta_o (degrees)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("relative L2 error (%)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "sg_fig4_errors.png", dpi=120)

    m = fit_gaussian_lobes(parse_brdf(BRDFS[1]), FitSettings(max_lobes=3))
    deg = np.degrees(m.elevations)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for k in range(m.n_lobes):
        live = m.weight[:, k].sum(axis=1) > 0
        for ax, vals in zip(axes, (np.degrees(m.mu[:, k]), np.degrees(m.sigma[:, k]), m.weight[:, k, 1]), strict=True):
            ax.plot(deg, np.where(live, vals, math.nan), marker="o", ms=3, label=f"lobe {k}")
    for ax, title in zip(axes, ("mu (degrees, + toward n)", "sigma (degrees)", "weight"), strict=True):
        ax.set_title(f"Fig. 3: {title}")
        ax.set_xlabel("theta_o (degrees)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{BRDFS[1]}, K = 3, N = 15", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "sg_fig3_parameters.png", dpi=120)
    data["fig3"] = m.spec()
    (out / "sg_figures.json").write_text(json.dumps(data, indent=1))
    print(f"wrote {out / 'sg_fig4_errors.png'}, {out / 'sg_fig3_parameters.png'}, {out / 'sg_figures.json'}")


if __name__ == "__main__":
    main()
