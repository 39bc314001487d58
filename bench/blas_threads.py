"""BLAS threads pinned through ``relight.settings`` against BLAS at its own default (issue 11, item 8).

``RELIGHT_THREADS`` limits ducc0 and every BLAS library (NumPy's and SciPy's own OpenBLAS) to one count
(``relight/settings.py``). Without it OpenBLAS starts one thread per core once a product is large enough (band
matrices of order >= 64) and its threads keep spinning after each call, so the ducc0 transform that follows
competes with them for the cores (docs/facts.md, "do not run two thread pools"; the issue measured 46 ms against
17.5 ms pinned).

Each variant runs in its own process, the variants alternate ``--rounds`` times (a load change on the machine hits
both alike), and each process reports the median of ``--repeat`` steps. One step is what an SH-table or SHRM path
does per frame: rotate coefficients band by band (``relight.sh_rotation.rotate_coefficients``, BLAS products
(2l+1) x (2l+1) @ (2l+1) x C) and then project a map (``relight.sh.project``, ducc0):

* ``pinned``: ``RELIGHT_THREADS=1`` as the service runs (ducc0 and both OpenBLAS at one thread);
* ``BLAS default``: the same, then BLAS put back to one thread per core (``threadpool_limits(os.cpu_count())``),
  what a process gets when nothing pins it.

Prints a markdown table and writes JSON (``--json``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: Columns rotated per band: the channels x vertices/texels one product handles.
COLUMNS = 64

CHILD = r"""
import json, os, statistics, sys, time
import numpy as np
from relight import sh
from relight.sh_rotation import band_rotations, rotate_coefficients
from threadpoolctl import threadpool_info, threadpool_limits
mode, lmaxes, repeat, columns = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
if mode == "default":
    threadpool_limits(limits=os.cpu_count(), user_api="blas")
rng = np.random.default_rng(0)
out = {"blas_threads": [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"],
       "ducc0_threads": sh.NTHREADS, "rows": []}
q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
rot = q * np.sign(np.linalg.det(q))
for lmax in lmaxes:
    blocks = band_rotations(rot, lmax)
    coeffs = rng.normal(size=((lmax + 1) ** 2, columns))
    h = 2 * lmax + 2
    field = rng.random((h, 2 * h, 3))
    rotate_coefficients(blocks, coeffs); sh.project(field, lmax)  # warm-up
    t_rot, t_sh = [], []
    for _ in range(repeat):
        t0 = time.perf_counter(); rotate_coefficients(blocks, coeffs)
        t1 = time.perf_counter(); sh.project(field, lmax)
        t2 = time.perf_counter()
        t_rot.append(t1 - t0); t_sh.append(t2 - t1)
    out["rows"].append({"lmax": lmax, "rotate_ms": 1e3 * statistics.median(t_rot),
                        "project_ms": 1e3 * statistics.median(t_sh),
                        "step_ms": 1e3 * statistics.median([a + b for a, b in zip(t_rot, t_sh)])})
print(json.dumps(out))
"""


def run(mode: str, lmaxes: list[int], repeat: int) -> dict[str, Any]:
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env["RELIGHT_THREADS"] = "1"
    proc = subprocess.run([sys.executable, "-c", CHILD, mode, json.dumps(lmaxes), str(repeat), str(COLUMNS)],
                          env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    result: dict[str, Any] = json.loads(proc.stdout)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lmax", default="32,64,128,256", help="comma-separated orders")
    ap.add_argument("--repeat", type=int, default=15, help="steps per process (median)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating process pairs (median over rounds)")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "blas_threads.json"))
    args = ap.parse_args()
    lmaxes = [int(x) for x in args.lmax.split(",")]
    runs: dict[str, list[dict[str, Any]]] = {"pinned": [], "default": []}
    for _ in range(args.rounds):
        for mode in runs:
            runs[mode].append(run(mode, lmaxes, args.repeat))
    rows = []
    for k, lmax in enumerate(lmaxes):
        row: dict[str, Any] = {"lmax": lmax}
        for mode, results in runs.items():
            for key in ("rotate_ms", "project_ms", "step_ms"):
                row[f"{mode}_{key}"] = statistics.median(r["rows"][k][key] for r in results)
        row["step_ratio"] = row["default_step_ms"] / row["pinned_step_ms"]
        rows.append(row)
    cores = os.cpu_count()
    print(f"cores {cores}; BLAS threads pinned {runs['pinned'][0]['blas_threads']}, "
          f"default {runs['default'][0]['blas_threads']}; ducc0 threads {runs['pinned'][0]['ducc0_threads']}; "
          f"{COLUMNS} columns rotated; medians of {args.repeat} steps x {args.rounds} rounds\n")
    print("| lmax | rotate pinned | rotate default | project pinned | project default | step pinned | step default "
          "| default / pinned |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['lmax']} | {r['pinned_rotate_ms']:.2f} ms | {r['default_rotate_ms']:.2f} ms | "
              f"{r['pinned_project_ms']:.2f} ms | {r['default_project_ms']:.2f} ms | {r['pinned_step_ms']:.2f} ms | "
              f"{r['default_step_ms']:.2f} ms | {r['step_ratio']:.2f} |")
    out = {"cores": cores, "columns": COLUMNS, "repeat": args.repeat, "rounds": args.rounds,
           "blas_threads": {m: runs[m][0]["blas_threads"] for m in runs}, "rows": rows}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
