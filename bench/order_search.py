"""Order search time for the cases of issue 18 ("tight tolerances cost minutes and then fail"): the view-band search
(``relight.shrm.order_search``, the tolerance held in every band with N.V >= 0.1) against App. C's whole-lobe search
(``relight.brdf.lpq_search.select_orders``), each from a cold cache, side by side in one run.

Before issue 18 the whole-lobe search ran to the caps (F = 511..1024, P = 16) for 60–111 s and reported "not met"
for microfacet sigma = 0.1 and 0.3 at epsilon = 1e-3 and GGX alpha = 0.1 at 0.01, and did not finish in 180 s for
Torrance–Sparrow alpha = 0.2 at 0.01 and GGX alpha = 0.4 at 1e-3. The whole-lobe search is run here under a time
limit (``--limit``, default 30 s, in a child process; "> limit" when it does not finish). Prints a markdown table
and writes JSON (``bench/results/order_search.json``, or ``--json``).

    .venv/bin/python bench/order_search.py [--limit 30] [--skip-old]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: (BRDF spec, epsilon): the cases listed under "Why" in issue 18, and a few easy ones beside them.
CASES: list[tuple[str, float]] = [
    ("microfacet:sigma=0.1", 1e-3), ("microfacet:sigma=0.3", 1e-3), ("ggx:alpha=0.1", 0.01),
    ("torrance-sparrow:alpha=0.2", 0.01), ("ggx:alpha=0.4", 1e-3),
    ("microfacet:sigma=0.1", 0.1), ("microfacet:sigma=0.1", 0.01), ("ggx:alpha=0.1", 0.1),
    ("ggx:alpha=0.3", 0.01), ("ggx:alpha=0.05", 1e-4), ("phong:s=64", 1e-4), ("kajiya-kay:s=32", 0.01),
]


def _new(spec: str, eps: float) -> dict[str, Any]:
    from relight.brdf import lobe_cache
    from relight.brdf.spec import parse_brdf
    from relight.shrm import order_search

    lobe_cache.clear()
    lobe = parse_brdf(spec)
    t = time.perf_counter()
    res = order_search.search_orders(lobe, eps)
    return {"seconds": time.perf_counter() - t, "F": res.F, "P": res.P, "met": res.met,
            "unmet_bands": [list(b) for b in res.unmet], "extrapolated": res.extrapolated}


def _old_child(spec: str, eps: float, out: Any) -> None:
    from relight.brdf import lobe_cache, lpq_search
    from relight.brdf.spec import parse_brdf

    lobe_cache.clear()
    t = time.perf_counter()
    sel = lpq_search.select_orders(parse_brdf(spec), eps)
    out.put({"seconds": time.perf_counter() - t, "F": sel.F, "P": sel.P, "met": sel.met})


def _old(spec: str, eps: float, limit: float) -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_old_child, args=(spec, eps, q))
    p.start()
    p.join(limit)
    if p.is_alive():
        p.terminate()
        p.join()
        return {"seconds": None, "timed_out": True}
    return dict(q.get())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=float, default=30.0, help="seconds allowed to the whole-lobe search per case")
    ap.add_argument("--skip-old", action="store_true", help="time the view-band search only")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "order_search.json"))
    args = ap.parse_args()
    _new("phong:s=8", 0.1)  # imports and SciPy's first call out of the timings
    rows = []
    for spec, eps in CASES:
        new = _new(spec, eps)
        old = None if args.skip_old else _old(spec, eps, args.limit)
        rows.append({"brdf": spec, "epsilon": eps, "view_bands": new, "whole_lobe": old})
    print("| BRDF | epsilon | view-band search s | F, P | met (N.V >= 0.1) | unmet bands | whole-lobe search s "
          "| F, P | met |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        n, o = r["view_bands"], r["whole_lobe"]
        old_s = "-" if o is None else (f"> {args.limit:g}" if o.get("timed_out") else f"{o['seconds']:.2f}")
        old_fp = "-" if o is None or o.get("timed_out") else f"{o['F']}, {o['P']}"
        old_met = "-" if o is None or o.get("timed_out") else str(o["met"])
        print(f"| {r['brdf']} | {r['epsilon']:g} | {n['seconds']:.2f} | {n['F']}, {n['P']} | {n['met']} | "
              f"{', '.join(f'[{a:g}, {b:g}]' for a, b in n['unmet_bands']) or '-'} | {old_s} | {old_fp} | {old_met} |")
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"limit_s": args.limit, "cases": rows}, indent=1))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
