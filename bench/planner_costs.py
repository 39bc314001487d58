"""Calibrate planner v2's precompute cost model (``relight.planning.costs``) on this machine and print it.

    .venv/bin/python bench/planner_costs.py [--full] [--json OUT.json]

Times Gaussian-lobe fits, Gaussian chains, SH tables (isotropic 1-D and anisotropic 2-D) and per-vertex transfers at
a few sizes (``relight.planning.costs.calibrate_precompute``), fits the constants by NNLS on relative error
(``relight.costmodel.fit``) and prints each run's measured and predicted seconds with their ratio, then the constants
(the values of ``PRECOMPUTE_CONSTANTS``). Timings vary with the machine's load: compare ratios within one run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from relight.planning.costs import PRECOMPUTE_CONSTANTS, calibrate_precompute


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="more and larger runs")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    consts, runs = calibrate_precompute(quick=not args.full)
    print("| run | features | measured s | predicted s | ratio |")
    print("|---|---|---|---|---|")
    for k, r in enumerate(runs):
        feats = ", ".join(f"{n}={v:.3g}" for n, v in r["features"].items() if n != "job_call")
        print(f"| {k} | {feats} | {r['measured']:.3f} | {r['predicted']:.3f} | "
              f"{r['predicted'] / r['measured']:.2f} |")
    print("\nconstants (fitted, previous):")
    for name, value in consts.items():
        print(f"    {name!r}: {value:.2e},   # was {PRECOMPUTE_CONSTANTS[name]:.2e}")
    if args.json is not None:
        args.json.write_text(json.dumps({"constants": consts, "runs": runs}, indent=1))


if __name__ == "__main__":
    main()
