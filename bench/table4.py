"""Reproduce seed 000 Table 4 on this machine: Phong prefiltering, angular vs frequency space.

Input: a 1024 x 512 sample map; output 128 x 256; Phong s = 8 ... 512. For each s:

* frequency: ``prefilter_radial`` with the paper's setting F_B = 1 + sqrt(6 s) (epsilon ~ 0.01, §7.4);
* angular: ``reference_radial`` with the paper's aggressive truncation epsilon = 0.05 (§7.4);
* both compared (relight's relative RMS metric) against a high-accuracy angular reference (truncation 1e-6);
* the SH-transform floor measured in the same run: projecting the same map to L = 30 and synthesising 128 x 256.

Prints a markdown table and writes JSON (``--json``). Times are medians of ``--repeat`` runs (the angular method runs
once: it is slow). ``--quick`` uses a 256 x 128 input and a 32 x 64 output.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from relight import sh
from relight.brdf.radial import Phong
from relight.envmap import read_envmap, resample_latlong
from relight.metrics import relative_rms
from relight.prefilter import prefilter_radial
from relight.reference import reference_radial

ROOT = Path(__file__).resolve().parents[1]


def median_time(fn: Any, repeat: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", default=str(ROOT / "data" / "envmaps" / "courtyard.exr"))
    ap.add_argument("--exponents", default="8,16,32,64,128,256,512")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="256x128 input, 32x64 output")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "table4.json"))
    args = ap.parse_args()

    env = np.asarray(read_envmap(args.map).pixels, dtype=np.float64)
    size = 128  # the 128 x 256 output
    if args.quick:
        env, size = np.asarray(resample_latlong(env, 128), dtype=np.float64), 32
    h = env.shape[0]

    # SH-transform floor: projection to L = 30 plus synthesis at the output size (what any SH method must pay).
    def floor() -> None:
        alm = sh.project(env, 30)
        sh.synthesize(alm, 30, size)

    t_floor, _ = median_time(floor, args.repeat)

    rows = []
    for s in [float(x) for x in args.exponents.split(",")]:
        order = min(int(1 + math.sqrt(6 * s)), h - 1)
        lobe = Phong(s)
        t_freq, res = median_time(lambda lobe=lobe, order=order: prefilter_radial(env, lobe, order=order, size=size),
                                  args.repeat)
        t0 = time.perf_counter()
        ang = reference_radial(env, lobe, size, epsilon=0.05)
        t_ang = time.perf_counter() - t0
        exact = reference_radial(env, lobe, size, epsilon=1e-6)
        rows.append(
            {
                "s": s,
                "F_B": order,
                "angular_seconds": t_ang,
                "frequency_seconds": t_freq,
                "ratio_angular_over_frequency": t_ang / t_freq,
                "frequency_over_sh_floor": t_freq / t_floor,
                "angular_error": relative_rms(ang, exact),
                "frequency_error": relative_rms(res.map, exact),
                "frequency_predicted_error": res.report.orders.rms_min_of_errors,
            }
        )
        print(f"s={s:g} done", flush=True)

    print()
    print(f"Seed 000 Table 4 on this machine: input {env.shape[1]}x{h}, output {2 * size}x{size}, "
          f"SH-transform floor (L=30) {t_floor * 1e3:.2f} ms")
    print()
    print("| s | F_B | angular (s) | frequency (s) | ratio ang/freq | freq / SH floor | angular err | freq err |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['s']:g} | {r['F_B']} | {r['angular_seconds']:.3f} | {r['frequency_seconds']:.4f} | "
            f"{r['ratio_angular_over_frequency']:.0f} | {r['frequency_over_sh_floor']:.2f} | "
            f"{r['angular_error']:.2e} | {r['frequency_error']:.2e} |"
        )
    out = {
        "machine_note": "ratios are measured side by side in one run",
        "input": [h, env.shape[1]],
        "output": [size, 2 * size],
        "sh_floor_seconds": t_floor,
        "rows": rows,
    }
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
