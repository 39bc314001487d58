"""Measured against predicted error per view band, before and after issue 18 (``docs/accuracy/grazing.md``).

For each sample map (area-averaged to ``--rows`` rows), BRDF and tolerance:

* **before**: the orders of App. C's whole-lobe search (``relight.brdf.lpq_search.select_orders``, run in a child
  process under ``--limit`` seconds), ``F_B = min(F_rho, F_L, H - 1)``, the SHRM's raw expansion (no clamp), and the one
  figure the report had: ``rms_min_of_errors`` (and App. B's ``rms_appendix_b``) for the whole light field;
* **after**: ``create_shrm(epsilon=...)`` with the view-band search (N.V >= 0.1), clamped radiance, and the
  report's per-band ``rms`` / ``rms_average`` / ``rms_appendix_b`` (``relight.shrm.view_bands``).

Measured: the relative RMS per band N.V in [0, 0.1], [0.1, 0.3], [0.3, 0.7], [0.7, 1] against the angular brute
force (``relight.view_error.sample_by_view``: ``--views`` views spread over the sphere, ``--per-view`` texels of
each per band, with the jackknife standard error), the SHRM read at its own texel centres (``--size`` rows).
Prints markdown tables and writes JSON (``bench/results/grazing_accuracy.json``).

    .venv/bin/python bench/grazing_accuracy.py [--rows 64] [--size 64] [--limit 60] [--views 100] [--per-view 12]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BANDS = ((0.0, 0.1), (0.1, 0.3), (0.3, 0.7), (0.7, 1.0))
MAPS = ("city", "courtyard")
BRDFS = ("microfacet:sigma=0.1", "microfacet:sigma=0.3", "ggx:alpha=0.1", "torrance-sparrow:alpha=0.2",
         "phong:s=64")
EPSILONS = (0.1, 0.01)


def _old_child(spec: str, eps: float, out: Any) -> None:
    from relight.brdf import lpq_search
    from relight.brdf.spec import parse_brdf

    sel = lpq_search.select_orders(parse_brdf(spec), eps)
    out.put((sel.F, sel.P, sel.met))


def old_orders(spec: str, eps: float, limit: float) -> tuple[int, int, bool] | None:
    from relight.brdf.coefficients import spectrum_for_tolerance
    from relight.brdf.spec import parse_brdf

    lobe = parse_brdf(spec)
    if lobe.radially_symmetric:
        return spectrum_for_tolerance(lobe, eps)[1], 0, True
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_old_child, args=(spec, eps, q))
    p.start()
    p.join(limit)
    if p.is_alive():
        p.terminate()
        p.join()
        return None
    f, pp, met = q.get()
    return int(f), int(pp), bool(met)


def load(name: str, rows: int) -> np.ndarray:
    from relight.envmap import read_envmap, resample_latlong
    from relight.resources import sample_envmaps

    root = sample_envmaps()
    assert root is not None
    return np.asarray(resample_latlong(read_envmap(root / f"{name}.exr").pixels, rows), dtype=np.float64)


def after_prediction(px: np.ndarray, lobe: Any, eps: float, size: int, f_b: int, p_b: int) -> list[Any]:
    """The per-band prediction create_shrm made, for the measurement's bands (same cached spectrum)."""
    from relight.prefilter import project_lighting
    from relight.settings import SETTINGS
    from relight.shrm import order_search, structure_of
    from relight.shrm.view_bands import predicted_by_view
    from relight.shrm.view_spectrum import band_edges

    limit = SETTINGS.grazing_limit
    res, _ = order_search.cached_search(lobe, eps, grazing_limit=limit, structure=structure_of(lobe)[0], size=size)
    from relight.shrm.creation import spectrum_order

    f_cap = px.shape[0] - 1
    spec = res.spectrum
    if spec.F < spectrum_order(res.F, f_cap):  # as create_shrm: the prediction's spectrum reaches spectrum_order(F)
        spec = order_search.cached_spectrum(lobe, spectrum_order(res.F, f_cap), res.P, band_edges(limit))
    lig = project_lighting(px, min(max(res.F, spec.F), f_cap))
    return predicted_by_view(spec, lig, f_b, p_b, bands=BANDS)


def run(rows: int, size: int, limit: float, views: int, per_view: int) -> list[dict[str, Any]]:
    from relight.brdf.spec import parse_brdf
    from relight.orders import order_for_tolerance
    from relight.prefilter import project_lighting
    from relight.shrm import create_shrm
    from relight.view_error import sample_by_view

    out = []
    for name in MAPS:
        px = load(name, rows)
        lig = project_lighting(px, rows - 1)
        for spec in BRDFS:
            lobe = parse_brdf(spec)
            for eps in EPSILONS:
                row: dict[str, Any] = {"map": name, "brdf": spec, "epsilon": eps}
                t = time.perf_counter()
                sm = create_shrm(px, lobe, epsilon=eps, size=size)
                c = sm.components[0]
                meas = sample_by_view(sm, px, lobe, BANDS, views=views, per_view=per_view)
                pred = after_prediction(px, lobe, eps, size, c.F, c.P)
                row["after"] = {
                    "F_B": c.F, "P_B": c.P, "tolerance_met": c.report["orders"].get("tolerance_met"),
                    "unmet_bands": c.report["orders"].get("unmet_bands"),
                    "measured": meas.rms.tolist(), "measured_se": meas.standard_error().tolist(),
                    "rms": [b.rms for b in pred], "rms_average": [b.rms_average for b in pred],
                    "rms_appendix_b": [b.rms_appendix_b for b in pred], "negatives": meas.negatives.tolist(),
                    "report_by_view": sm.report["predicted"]["by_view"],
                }
                old = old_orders(spec, eps, limit)
                if old is None:
                    row["before"] = {"timed_out": limit}
                else:
                    f_l = order_for_tolerance(lig.band_energy(), lig.total_energy, eps)
                    f_b = min(old[0], rows - 1, f_l if f_l is not None else old[0])
                    smo = create_shrm(px, lobe, order=f_b, p_order=old[1], size=size)
                    mo = sample_by_view(smo, px, lobe, BANDS, clamp=False, views=views, per_view=per_view)
                    po = smo.report["predicted"]
                    row["before"] = {
                        "F_B": f_b, "P_B": old[1], "tolerance_met": old[2], "measured": mo.rms.tolist(),
                        "measured_se": mo.standard_error().tolist(), "rms_min_of_errors": po["rms_min_of_errors"],
                        "rms_appendix_b": po["rms_appendix_b"], "negatives": mo.negatives.tolist(),
                    }
                row["seconds"] = time.perf_counter() - t
                print(f"{name} {spec} eps={eps}: {row['seconds']:.0f} s", flush=True)
                out.append(row)
    return out


def table(rows: list[dict[str, Any]]) -> str:
    def pct(x: float | None) -> str:
        return "-" if x is None else f"{100 * x:.3g}"

    lines = ["| map | BRDF | eps | before F, P | before predicted (whole field) | before measured per band "
             "| after F, P | after predicted rms per band | after measured per band (± s.e.) | after rms / measured "
             "| met |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        b, a = r["before"], r["after"]
        if "timed_out" in b:
            bfp, bpred, bmeas = f"> {b['timed_out']:g} s", "-", "-"
        else:
            bfp = f"{b['F_B']}, {b['P_B']}"
            bpred = f"{pct(b['rms_min_of_errors'])} (B {pct(b['rms_appendix_b'])})"
            bmeas = " / ".join(pct(x) for x in b["measured"])
        amea = " / ".join(f"{pct(x)}±{pct(s)}" for x, s in zip(a["measured"], a["measured_se"], strict=True))
        ratio = " / ".join("-" if m <= 0 else f"{p / m:.2f}" for p, m in zip(a["rms"], a["measured"], strict=True))
        lines.append(f"| {r['map']} | {r['brdf']} | {r['epsilon']:g} | {bfp} | {bpred} | {bmeas} | "
                     f"{a['F_B']}, {a['P_B']} | {' / '.join(pct(x) for x in a['rms'])} | {amea} | {ratio} | "
                     f"{a['tolerance_met']} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=64)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--limit", type=float, default=60.0)
    ap.add_argument("--views", type=int, default=100, help="views spread over the sphere (all bands)")
    ap.add_argument("--per-view", type=int, default=12, help="texels per view and band")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "grazing_accuracy.json"))
    args = ap.parse_args()
    rows = run(args.rows, args.size, args.limit, args.views, args.per_view)
    print("\nRelative RMS in %, per band N.V in [0, 0.1] / [0.1, 0.3] / [0.3, 0.7] / [0.7, 1]\n")
    print(table(rows))
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = {"rows": args.rows, "size": args.size, "views": args.views, "per_view": args.per_view, "bands": BANDS}
    out.write_text(json.dumps({**meta, "cases": rows}, indent=1))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
