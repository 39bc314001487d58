"""Seed-002 commands of the ``relight`` CLI (Green, Kautz & Durand 2007, §3.2, §4, §5.1).

    relight fit BRDF_SPEC [--lobes K] [--elevations N] [--theta-max DEG] [--max-lobes M] --out FIT.json
        per-elevation Gaussian-lobe fit (``relight.sgfit``); prints the error table; FIT.json is a
        ``gaussian-lobes`` material: {"kind", "elevations": [{"theta_o", "error", "lobes": [{"mu", "sigma",
        "weight"}]}], "fit": report}, angles in radians.
    relight chain ENVMAP [--levels L | --epsilon E] [--ratio 2|sqrt2] [--sigma0 RAD] --out DIR
        Gaussian-prefiltered chain (``relight.gaussian_chain``): DIR/chain.json + DIR/level_JJ.exr (float16).
        ``--levels`` fixes the number of levels (orders from the default tolerance); ``--epsilon`` sets the
        tolerance for every level's order and the levels run from sigma0 (default: the map's pixel angle) to 90
        degrees.

Errors raise :class:`relight.errors.InputError` (the CLI prints one line and exits with status 2).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any


def cmd_fit(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_brdf
    from relight.sgfit import FitSettings, error_table, fit_gaussian_lobes

    brdf = parse_brdf(args.brdf)
    st = FitSettings(lobes=args.lobes, elevations=args.elevations, theta_max=math.radians(args.theta_max),
                     max_lobes=args.max_lobes)
    mat = fit_gaussian_lobes(brdf, st)
    Path(args.out).write_text(json.dumps(mat.spec(), indent=1))
    print(error_table(mat))
    print(f"wrote {args.out}")
    return 0


def cmd_chain(args: argparse.Namespace) -> int:
    from relight.envmap import read_envmap
    from relight.gaussian_chain import RATIOS, build_chain, write_chain
    from relight.prefilter import DEFAULT_EPSILON

    env = read_envmap(args.envmap)
    chain = build_chain(env.pixels, sigma0=args.sigma0, ratio=RATIOS[args.ratio], levels=args.levels,
                        epsilon=args.epsilon if args.epsilon is not None else DEFAULT_EPSILON)
    man: dict[str, Any] = write_chain(args.out, chain)
    for j, e in enumerate(man["levels"]):
        o = e["orders"]
        print(f"level {j:2d}: sigma {math.degrees(e['sigma']):8.3f} deg  F={o['F_B']:4d}  {e['width']}x{e['height']}"
              f"  App. B bound (relative RMS) {o['rms_appendix_b']:.3g}")
    print(f"wrote {args.out}/chain.json and {len(man['levels'])} float16 levels in "
          f"{chain.report['timings']['total']:.3f} s")
    return 0


def register(sub: Any) -> None:
    fp = sub.add_parser("fit", help="fit Gaussian lobes to an isotropic BRDF (seed 002)")
    fp.add_argument("brdf", help="BRDF spec: torrance-sparrow:alpha=0.2,fresnel=none, merl:file.binary, a JSON file")
    fp.add_argument("--lobes", type=int, default=3, help="Gaussians per elevation (default 3)")
    fp.add_argument("--elevations", type=int, default=15, help="view elevations (default 15)")
    fp.add_argument("--theta-max", type=float, default=87.0, help="largest elevation in degrees (default 87)")
    fp.add_argument("--max-lobes", type=int, default=None,
                    help="add lobes (up to this many) only at elevations whose error exceeds 5 %%")
    fp.add_argument("--out", required=True, help="FIT.json")
    fp.set_defaults(func=cmd_fit)

    cp = sub.add_parser("chain", help="Gaussian-prefiltered environment chain (seed 002 §5.1)")
    cp.add_argument("envmap")
    g = cp.add_mutually_exclusive_group()
    g.add_argument("--levels", type=int, help="number of levels")
    g.add_argument("--epsilon", type=float, help="tolerance (uncaptured energy) for every level's order")
    cp.add_argument("--ratio", choices=["2", "sqrt2"], default="2", help="sigma ratio between levels (default 2)")
    cp.add_argument("--sigma0", type=float, help="sharpest level's sigma in radians (default: pi / height)")
    cp.add_argument("--out", required=True, help="output folder")
    cp.set_defaults(func=cmd_chain)
