"""In-out factorization benchmark and calibration (Mahajan, Tseng & Ramamoorthi 2008; relight.factorization).

    python bench/factorize.py [--out bench/results/factorize.json] [--quick] [--only PART] [--threads N]

1. **Phong** (Fig. 3A, eq. 13): K at 90 / 95 / 99 % over the hemisphere and the sphere (block SVD, 64 x 64 Gauss
   nodes, converged for s <= 50), the SVD-free predictions (``relight.factor_predict``), K / s and the least-squares
   line K = a s + b over s = 5..50.
2. **Eq. 14** half-angle lobe (``microfacet:sigma``): K on the paper's 40^4 grid and on a converged grid, l* of the
   theta_h curve, the paper's (l*)^2 / 4, the calibrated prediction, K / (l*)^2 (the provenance of
   ``HALF_ANGLE_SLOPE``); ``--quick`` skips the sharpest lobes.
3. **Singular values vs F_l** on the sphere (Phong s = 10, 40 x 40): largest error for l <= 9 on the Gauss and
   equal-area grids.
4. **Timing**: block SVD at 1000 theta nodes per hemisphere (Phong s = 30, 64 azimuths) with the randomized
   low-rank block SVD (default) and with full per-block decompositions, the block SVD on the paper's 40^4 grid and
   the dense SVD of the same 1600 x 1600 matrix, in one run: wall-clock and process CPU seconds. BLAS runs with
   ``--threads`` threads (default 1, set before numpy loads: on the shared 2-core machine multi-threaded OpenBLAS
   spin-waits and inflates CPU time ~100x for these small matrices). Compare ratios within one run; wall-clock
   on a loaded machine exceeds CPU time by the load.

Prints markdown tables and writes JSON. This is not a test.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # BLAS threads must be fixed before numpy loads
    _threads = sys.argv[sys.argv.index("--threads") + 1] if "--threads" in sys.argv[:-1] else "1"
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[_var] = _threads

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from relight.brdf.coefficients import phong_transfer  # noqa: E402
from relight.brdf.spec import parse_brdf  # noqa: E402
from relight.factor_predict import predict_terms  # noqa: E402
from relight.factorization import factorize  # noqa: E402

TAUS = (0.9, 0.95, 0.99)


def phong_table() -> dict[str, Any]:
    rows = []
    for s in (1, 2, 5, 10, 20, 30, 50):
        b = parse_brdf(f"phong:s={s}")
        h = factorize(b, n_theta=64)
        sp = factorize(b, n_theta=64, domain="sphere")
        ph, ps = predict_terms(b)["terms"], predict_terms(b, domain="sphere")["terms"]
        rows.append({"s": s, "hemisphere": h.terms[0.99], "sphere": sp.terms[0.99], "hemisphere_95": h.terms[0.95],
                     "hemisphere_90": h.terms[0.9], "predicted_hemisphere": ph[0.99], "predicted_sphere": ps[0.99],
                     "predicted_hemisphere_95": ph[0.95], "predicted_hemisphere_90": ph[0.9]})
    fit = [r for r in rows if r["s"] >= 5]
    s_arr = np.array([r["s"] for r in fit], dtype=float)
    line_h = np.polyfit(s_arr, [r["hemisphere"] for r in fit], 1)
    line_s = np.polyfit(s_arr, [r["sphere"] for r in fit], 1)
    print("\n| s | K hemi 99 % (pred) | K/s | K sphere 99 % (pred) | K/s | hemi 95 % (pred) | hemi 90 % (pred) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['s']} | {r['hemisphere']} ({r['predicted_hemisphere']}) | {r['hemisphere'] / r['s']:.2f} | "
              f"{r['sphere']} ({r['predicted_sphere']}) | {r['sphere'] / r['s']:.2f} | {r['hemisphere_95']} "
              f"({r['predicted_hemisphere_95']}) | {r['hemisphere_90']} ({r['predicted_hemisphere_90']}) |")
    print(f"lines over s = 5..50: hemisphere K = {line_h[0]:.3f} s + {line_h[1]:.2f}, "
          f"sphere K = {line_s[0]:.3f} s + {line_s[1]:.2f}")
    return {"rows": rows, "hemisphere_line": list(line_h), "sphere_line": list(line_s)}


def half_angle_table(quick: bool) -> list[dict[str, Any]]:
    sigmas = [(0.4, 120, 160), (0.3, 120, 160), (0.25, 160, 200), (0.2, 200, 256)]
    if not quick:
        sigmas += [(0.15, 300, 384)]
    rows = []
    print("\n| sigma | K 40^4 | K converged (grid) | K 1.5x finer | l* 99 % | (l*)^2/4 | predicted | K/(l*)^2 "
          "(90, 95, 99 %) |")
    print("|---|---|---|---|---|---|---|---|")
    for sigma, n_t, n_p in sigmas:
        b = parse_brdf(f"microfacet:sigma={sigma}")
        paper = factorize(b, n_theta=40).terms
        conv = factorize(b, n_theta=n_t, n_phi=n_p).terms
        finer = factorize(b, n_theta=n_t * 3 // 2, n_phi=n_p * 3 // 2).terms if sigma >= 0.2 else None
        p = predict_terms(b)
        ratio = {t: conv[t] / p["l_star"][t] ** 2 for t in TAUS}
        rows.append({"sigma": sigma, "terms_40": paper, "terms": conv, "grid": [n_t, n_p], "terms_finer": finer,
                     "l_star": p["l_star"], "paper_terms": p["paper_terms"], "predicted": p["terms"],
                     "ratio": ratio})
        print(f"| {sigma} | {paper[0.99]} | {conv[0.99]} ({n_t} x {n_p}) | {finer[0.99] if finer else '-'} | "
              f"{p['l_star'][0.99]} | {p['paper_terms'][0.99]} | {p['terms'][0.99]} | "
              + ", ".join(f"{ratio[t]:.3f}" for t in TAUS) + " |")
    return rows


def sigma_accuracy() -> dict[str, float]:
    f_l = phong_transfer(10.0, 9)
    out = {}
    for grid in ("gauss", "equal-area"):
        r = factorize(parse_brdf("phong:s=10"), domain="sphere", n_theta=40, grid=grid, n_values=100)
        out[grid] = float(max(np.max(np.abs(r.singular_values[l * l:(l + 1) ** 2] - f_l[l])) for l in range(10)))
    print(f"\nmax |sigma - F_l|, l <= 9, s = 10, sphere 40 x 40: Gauss {out['gauss']:.2e}, "
          f"equal-area {out['equal-area']:.2e}")
    return out


def timing() -> dict[str, Any]:
    import relight.factorization as fz

    b = parse_brdf("phong:s=30")
    fine = factorize(b, n_theta=1000, n_phi=64)
    saved = fz.LOWRANK_MIN_ROWS
    fz.LOWRANK_MIN_ROWS = 10**9
    try:
        full = factorize(b, n_theta=1000, n_phi=64)
    finally:
        fz.LOWRANK_MIN_ROWS = saved
    t0 = time.perf_counter()
    small = factorize(b, n_theta=40)
    t_small = time.perf_counter() - t0
    dense = factorize(b, n_theta=40, method="dense")
    out = {"block_1000": {"seconds": fine.seconds, "cpu_seconds": fine.cpu_seconds, "terms": fine.terms,
                          "blocks": fine.blocks_decomposed},
           "block_1000_full": {"seconds": full.seconds, "cpu_seconds": full.cpu_seconds, "terms": full.terms},
           "block_40": {"seconds": t_small, "cpu_seconds": small.cpu_seconds, "terms": small.terms},
           "dense_40": {"seconds": dense.seconds, "cpu_seconds": dense.cpu_seconds, "terms": dense.terms},
           "cpus": os.cpu_count(), "load_average": os.getloadavg(),
           "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}
    print(f"\nload average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs, "
          f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS')}")
    print("| SVD | grid | wall s | CPU s | K 99 % |\n|---|---|---|---|---|")
    print(f"| block | 1000 x 64 | {fine.seconds:.2f} | {fine.cpu_seconds:.2f} | {fine.terms[0.99]} "
          f"({fine.blocks_decomposed} blocks, low-rank) |")
    print(f"| block | 1000 x 64 | {full.seconds:.2f} | {full.cpu_seconds:.2f} | {full.terms[0.99]} (full eigen) |")
    print(f"| block | 40 x 40 | {t_small:.3f} | {small.cpu_seconds:.3f} | {small.terms[0.99]} |")
    print(f"| dense | 40 x 40 | {dense.seconds:.2f} | {dense.cpu_seconds:.2f} | {dense.terms[0.99]} |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "factorize.json"))
    ap.add_argument("--quick", action="store_true", help="skip sigma = 0.15 (minutes on 2 cores)")
    ap.add_argument("--only", choices=["phong", "half-angle", "accuracy", "timing"], help="run one part")
    ap.add_argument("--threads", default="1", help="BLAS threads (read before numpy loads; default 1)")
    args = ap.parse_args()
    parts = {"phong": phong_table, "half-angle": lambda: half_angle_table(args.quick), "accuracy": sigma_accuracy,
             "timing": timing}
    res = {name: fn() for name, fn in parts.items() if args.only in (None, name)}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)

    def keys(o: Any) -> Any:
        if isinstance(o, dict):
            return {(f"{k:g}" if isinstance(k, float) else k): keys(v) for k, v in o.items()}
        if isinstance(o, list):
            return [keys(v) for v in o]
        return float(o) if isinstance(o, np.floating) else o

    out.write_text(json.dumps(keys(res), indent=2))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
