"""``relight factorize``: how many in-out terms a BRDF needs (Mahajan, Tseng & Ramamoorthi 2008).

    relight factorize BRDF_SPEC [--domain hemisphere|sphere] [--resolution N] [--phi M] [--grid gauss|equal-area]
                      [--no-cosine] [--method auto|block|dense] [--factors F] [--no-convergence] --out DIR

Prints K per threshold (90 / 95 / 99 % of the energy) and the SVD-free predictions, and writes
``DIR/factorization.json`` (``terms``, ``singular_values``, ``predicted_terms``, ``prediction``, ``convergence``,
grid and timing) plus the leading factor images ``DIR/factors_g.npy`` and ``DIR/factors_h.npy`` (F x n_theta x n_phi,
float32, on the grid nodes ``DIR/grid.npz``: ``theta``, ``phi``, ``weights``). ``register(subparsers)`` adds it
(``relight.cli.COMMAND_PROVIDERS``); errors are ``InputError``: one line on stderr, exit status 2.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from relight import validate

#: Grid size N (N nodes in cos theta, N azimuths: the paper's N^4 matrix, §3.2) when --resolution is not given.
DEFAULT_RESOLUTION = 40
def cmd_factorize(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_frame_brdf
    from relight.factor_analysis import analyse

    validate.at_least("--factors", args.factors, 0)
    n = args.resolution
    doc, res = analyse(parse_frame_brdf(args.brdf), domain=args.domain, resolution=n, phi=args.phi, grid=args.grid,
                       include_cosine=not args.no_cosine, method=args.method, factors=args.factors,
                       check_convergence=not args.no_convergence)
    pred = doc["prediction"] if doc["predicted_terms"] is not None else None
    conv = doc["convergence"]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if res.factors:
        np.save(out / "factors_g.npy", np.stack([f.g for f in res.factors]).astype(np.float32))
        np.save(out / "factors_h.npy", np.stack([f.h for f in res.factors]).astype(np.float32))
        np.savez(out / "grid.npz", theta=res.grid.theta, phi=res.grid.phi,
                 weights=res.grid.weights.reshape(res.grid.n_theta, res.grid.n_phi))
        doc["factors"]["files"] = ["factors_g.npy", "factors_h.npy", "grid.npz"]
    (out / "factorization.json").write_text(json.dumps(doc, indent=2))
    print(f"{args.brdf}: {res.method} SVD over the {args.domain}, {res.grid.n_theta} x {res.grid.n_phi} "
          f"{res.grid.kind} nodes, {doc['quantity']}, {res.seconds:.2f} s")
    for t, k in res.terms.items():
        p = pred["terms"].get(f"{t:g}") if pred else None
        print(f"  {t:.0%} of the energy: K = {k}" + (f"  (predicted {p})" if p is not None else ""))
    if pred and "paper_terms" in pred:
        print(f"  paper's (l*)^2 / 4: {pred['paper_terms']}, l* = {pred['l_star']}")
    if pred and "paper" in pred:
        print(f"  paper's closed forms: 6s = {pred['paper']['eq12_6s']:g}, Fig. 3A = {pred['paper']['fig3a']:g}")
    if conv:
        print(f"  resolution check {conv['resolutions'][0]} -> {conv['resolutions'][1]}: "
              f"{'converged' if conv['converged'] else 'NOT converged'} {conv['terms'][1]}")
    print(f"wrote {out / 'factorization.json'}")
    return 0


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("factorize", help="in-out BRDF factorization: singular values and terms K")
    p.add_argument("brdf", help="phong:s=30, microfacet:sigma=0.2, merl:file.binary, ward:alpha_x=0.1,alpha_y=0.3,"
                   "rho_d=0,rho_s=1 (anisotropic: dense SVD), ... or a JSON file")
    p.add_argument("--domain", choices=["hemisphere", "sphere"], default="hemisphere")
    p.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION, help="nodes in cos(theta) (and phi)")
    p.add_argument("--phi", type=int, help="azimuths (default: the resolution)")
    p.add_argument("--grid", choices=["gauss", "equal-area"], default="gauss")
    p.add_argument("--no-cosine", action="store_true", help="factor f_r instead of f_r cos(theta_i)")
    p.add_argument("--method", choices=["auto", "block", "dense"], default="auto")
    p.add_argument("--factors", type=int, default=8, help="leading factor images to write (default 8)")
    p.add_argument("--no-convergence", action="store_true", help="skip the 1.5x finer resolution check")
    p.add_argument("--out", required=True)
    p.set_defaults(func=cmd_factorize)
