"""Seed 002 fit and chain benchmark: per-elevation error table, fit time, chain time, level-blend kernel error.

    .venv/bin/python bench/fit.py [--brdf SPEC] [--json OUT.json]
    .venv/bin/python bench/fit.py --materials [--json OUT.json]

Fits the BRDF (default Torrance-Sparrow Beckmann alpha 0.2, no Fresnel: the issue's target model) with K = 3, N = 15
and again with lobes added only where K = 3 exceeds 5 % (up to 5), prints both error tables with wall-clock and CPU
seconds (the 2-core machine is shared: CPU seconds are the stable figure), then the Gaussian chain of
data/envmaps/courtyard.exr (ratios 2 and sqrt 2) with its ratio to the SH-transform floor (the bare projection and
per-level syntheses alone, :func:`sh_floor`) and the blend kernel errors; the same numbers as JSON at the end.

``--materials``: the issue's mid-elevation rule (interpolated lobes within 1.5x the larger neighbour) on several
materials, K = 3 and up to 5 lobes, without and with the bisection pass (``relight.sgfit_refine``): worst ratio,
worst envelope (everything inside an original interval over its original ends), elevations, CPU seconds.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from relight import sh
from relight.brdf.spec import parse_brdf
from relight.envmap import read_envmap
from relight.gaussian_chain import RATIOS, GaussianChain, blend_kernel_error, build_chain
from relight.sgfit import FitSettings, error_table, fit_gaussian_lobes

DATA = Path(__file__).resolve().parents[1] / "data" / "envmaps"


def sh_floor(env: np.ndarray, chain: GaussianChain) -> float:
    """The bare transforms the chain cannot avoid, timed alone: one projection at its projection order, one
    synthesis per level at the level's order and size (``relight.sh``, ducc0)."""
    f_proj = int(chain.report.projection_order or 0)
    t0 = time.perf_counter()
    alm = sh.project(np.asarray(env, dtype=np.float64), f_proj)
    for lv in chain.levels:
        f, size = int(lv.orders["F_B"]), int(lv.orders["size"])
        sh.synthesize(sh.truncate(alm, f_proj, f), f, size, 2 * size)
    return time.perf_counter() - t0


MATERIALS = ("torrance-sparrow:alpha=0.2,fresnel=none", "torrance-sparrow:alpha=0.1,fresnel=none",
             "torrance-sparrow:alpha=0.05,fresnel=none", "ggx:alpha=0.1", "ggx:alpha=0.2", "ggx:alpha=0.3",
             "blinn-phong:s=64", "ward:alpha=0.15")


def materials() -> dict[str, object]:
    out: dict[str, object] = {}
    print(f"{'material':>42} {'lobes':>5} {'plain max':>9} {'max':>6} {'envelope':>8} {'N':>3} {'CPU s':>6}")
    for spec in MATERIALS:
        for ml in (3, 5):
            row = {}
            for ins in (0, None):
                st = FitSettings(max_lobes=ml)
                if ins is not None:
                    st.max_inserted = ins
                c0 = time.process_time()
                m = fit_gaussian_lobes(parse_brdf(spec), st)
                e = np.asarray(m.errors)
                ratio = np.asarray(m.fit["mid_errors"]) / np.maximum(e[:-1], e[1:])
                row["plain" if ins == 0 else "bisected"] = {
                    "max_ratio": float(ratio.max()), "envelope": float(max(m.fit["envelope_ratios"])),
                    "elevations": int(m.elevations.size), "cpu_s": time.process_time() - c0}
            b = row["bisected"]
            print(f"{spec:>42} {ml:>5} {row['plain']['max_ratio']:9.2f} {b['max_ratio']:6.2f} {b['envelope']:8.2f} "
                  f"{b['elevations']:>3} {b['cpu_s']:6.1f}")
            out[f"{spec} K<={ml}"] = row
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--brdf", default="torrance-sparrow:alpha=0.2,fresnel=none")
    ap.add_argument("--materials", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    if args.materials:
        text = json.dumps(materials(), indent=1)
        print(text)
        if args.json:
            Path(args.json).write_text(text)
        return
    brdf = parse_brdf(args.brdf)
    out: dict[str, object] = {"brdf": args.brdf}
    for name, st in (("K3", FitSettings()), ("K3_upto5", FitSettings(max_lobes=5))):
        w0, c0 = time.perf_counter(), time.process_time()
        m = fit_gaussian_lobes(brdf, st)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        print(f"== {name}: wall {wall:.1f} s, CPU {cpu:.1f} s")
        print(error_table(m))
        out[name] = {"theta_o_deg": [math.degrees(x) for x in m.elevations], "errors": m.fit["errors"],
                     "mid_errors": m.fit["mid_errors"], "lobes_used": m.fit["lobes_used"],
                     "wall_s": wall, "cpu_s": cpu}
    env = read_envmap(DATA / "courtyard.exr").pixels
    for rname, ratio in RATIOS.items():
        w0 = time.perf_counter()
        ch = build_chain(env, ratio=ratio)
        wall = time.perf_counter() - w0
        floor = sh_floor(env, ch)
        print(f"chain ratio {rname}: {len(ch.levels)} levels, wall {wall:.2f} s, SH-transform floor {floor:.2f} s "
              f"({wall / floor:.2f}x), {ch.report['timings']}")
        out[f"chain_{rname}"] = {"levels": len(ch.levels), "wall_s": wall, "timings": ch.report.timings,
                                 "sh_floor_s": floor, "ratio_to_floor": wall / floor,
                                 "blend_kernel_error": {str(f): blend_kernel_error(ratio, f) for f in (0.25, .5, .75)}}
        print(f"  blend kernel error at 1/4, 1/2, 3/4 level: "
              f"{[round(100 * blend_kernel_error(ratio, f), 1) for f in (0.25, 0.5, 0.75)]} %")
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text)


if __name__ == "__main__":
    main()
