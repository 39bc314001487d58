"""SHRM commands of the ``relight`` CLI (seed 000 §4, §7.5, App. C).

    relight prefilter ENVMAP --brdf SPEC [--epsilon E | --order F,P] [--size S] --out SHRM.exr [--report R.json]
        (non-radial BRDFs: ``relight.cli`` calls :func:`prefilter_shrm`)
    relight reference ENVMAP --brdf SPEC --size S --view X,Y,Z --out MAP.exr     (:func:`reference_view`)
    relight reflect SHRM.exr --view X,Y,Z --out MAP.exr [--size S]              (eq. 12 map for a distant view)
    relight render SHRM.exr --view X,Y,Z --size N --out sphere.exr [--png sphere.png] [--local]
    relight render --fit FIT.json --chain DIR --view X,Y,Z --size N --out OUT.exr [--mesh NAME
                   --visibility none|ao|sh|sh-lobe]                           (seed 002: ``relight.cli_sg``)

Errors raise :class:`relight.errors.InputError` (the CLI prints one line and exits with status 2).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from relight import validate
from relight.errors import InputError


def parse_view(text: str) -> tuple[float, float, float]:
    """``X,Y,Z`` -> a finite, non-zero 3-vector (not normalised here)."""
    parts = str(text).split(",")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise InputError(f"--view must be three numbers X,Y,Z, got {text!r}")
    if vals[0] == vals[1] == vals[2] == 0.0:
        raise InputError("--view must not be the zero vector")
    return vals[0], vals[1], vals[2]


def prefilter_shrm(
    args: argparse.Namespace, brdf: Any, env: Any, order: int | None, p_order: int | None
) -> int:
    """``relight prefilter`` for view-dependent BRDFs: write the SHRM EXR + manifest, print one summary line."""
    from relight.reports import ShrmReport
    from relight.shrm import create_shrm
    from relight.shrm_io import sidecar_path, write_shrm

    epsilon = getattr(args, "epsilon", None)
    shrm = create_shrm(
        env.pixels,
        brdf,
        epsilon=epsilon if order is None else None,
        order=order,
        p_order=p_order,
        size=getattr(args, "size", None),
        grazing_limit=getattr(args, "grazing_limit", None),
    )
    assert isinstance(shrm.report, ShrmReport)
    shrm.report.input.update(
        {
            "path": str(getattr(args, "envmap", "")),
            "negatives_clamped": getattr(env, "negatives_clamped", 0),
            "min_negative": getattr(env, "min_negative", 0.0),
            "sun": getattr(args, "sun_report", {"mode": "keep"}),
        }
    )
    man = write_shrm(args.out, shrm)
    report_path = getattr(args, "report", None)
    if report_path:
        Path(report_path).write_text(json.dumps(man, indent=2, sort_keys=True))
    orders = ", ".join(f"{c.center}:{c.structure} F={c.F} P={c.P}" for c in shrm.components)
    pred = shrm.report.predicted
    rim = pred.by_view[0] if pred.by_view else None
    unmet = [b for c in shrm.report.components for b in c.orders.get("unmet_bands", [])]
    reach = {tuple(a["ndotv"]): a["epsilon_brdf"] for c in shrm.report.components
             for a in c.orders.get("achievable_by_view", [])}
    print(
        f"wrote {args.out} (+ {sidecar_path(args.out).name}): SHRM {shrm.height}x{shrm.width}, "
        f"{shrm.report.output['maps']} maps [{orders}], predicted relative RMS {pred.rms_brdf:.3g} "
        f"(min of errors {pred.rms_min_of_errors:.3g}"
        + (f"; N.V in {rim.ndotv[0]:g}-{rim.ndotv[1]:g}: {rim.rms:.3g}" if rim is not None else "")
        + f"), {shrm.report.total_seconds:.3f} s"
    )
    if unmet:  # issue 18: which bands cannot meet the tolerance within the caps, and what each can reach
        bands = ", ".join(f"[{a:g}, {b:g}]" + (f" (reaches {reach[(a, b)]:.2g})" if (a, b) in reach else "")
                          for a, b in unmet)
        print(f"tolerance {shrm.report.epsilon:g} not met for N.V in {bands} within P <= 16 "
              "(orders.achievable_by_view in the report)")
    return 0


def reference_view(args: argparse.Namespace, brdf: Any, env: Any) -> int:
    """``relight reference --view``: the angular-domain reflection map for one distant view, indexed by R."""
    import time

    from relight.envmap.exr import write_exr
    from relight.reference import DEFAULT_TRUNCATION
    from relight.reference_view import reference_view as ref

    view = parse_view(args.view)
    if args.size is None or args.size < 1:
        raise InputError(f"--size must be a positive integer, got {args.size}")
    t = time.perf_counter()
    truncation = float(getattr(args, "truncation", DEFAULT_TRUNCATION))
    out = ref(env.pixels, brdf, np.array(view), int(args.size), truncation=truncation)
    seconds = time.perf_counter() - t
    meta = {"view": list(view), "truncation": truncation, "seconds": seconds,
            "kind": "angular-domain reference (seed 000 eq. 1)"}
    write_exr(args.out, out.astype(np.float32), attributes={"relight.reference": json.dumps(meta)})
    print(f"wrote {args.out}: {out.shape[0]}x{out.shape[1]} (angular-domain reference, view {view}), {seconds:.2f} s")
    return 0


def cmd_reflect(args: argparse.Namespace) -> int:
    """``relight reflect``: the eq. 12 reflection map (indexed by R) of an SHRM file for a distant view (§7.5)."""
    from relight.envmap.exr import write_exr
    from relight.shrm import reflect
    from relight.shrm_io import read_shrm

    shrm = read_shrm(args.shrm)
    view = parse_view(args.view)
    if args.size is not None and args.size < 1:
        raise InputError(f"--size must be a positive integer, got {args.size}")
    out = reflect(shrm, np.array(view), size=args.size)
    write_exr(args.out, out.astype(np.float32), attributes={"relight.view": json.dumps(list(view))})
    print(f"wrote {args.out}: {out.shape[0]}x{out.shape[1]} reflection map for view {view} (eq. 12)")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """``relight render``: a sphere rendered with an SHRM file (global eq. 12, or local eq. 6 with ``--local``);
    with ``--fit`` and ``--chain`` seed 002's Gaussian lobes instead (``relight.cli_sg.render_gaussian``)."""
    if args.table is not None:
        from relight.cli_shtable import render_table

        return render_table(args)
    if args.fit is not None or args.chain is not None:
        from relight.cli_sg import render_gaussian

        return render_gaussian(args)
    if args.shrm is None:
        raise InputError("render needs an SHRM file, or --fit FIT.json --chain DIR")
    if args.mesh is not None or args.visibility != "none":
        raise InputError("--mesh and --visibility need --fit and --chain (Gaussian lobes)")
    from relight.envmap.display import write_png_preview
    from relight.envmap.exr import write_exr
    from relight.shrm import render_sphere
    from relight.shrm_io import read_shrm

    shrm = read_shrm(args.shrm)
    view = parse_view(args.view)
    validate.int_in_range("--size", args.size, 1, 8192)
    img = render_sphere(shrm, np.array(view), args.size, local=args.local)
    write_exr(args.out, img.astype(np.float32))
    msg = f"wrote {args.out}"
    if args.png:
        write_png_preview(args.png, img, exposure=args.exposure)
        msg += f" and {args.png}"
    print(f"{msg}: {args.size}x{args.size} sphere, view {view}, {'local (eq. 6)' if args.local else 'global (eq. 12)'}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``reflect`` and ``render`` to the ``relight`` command line."""
    rf = subparsers.add_parser("reflect", help="reflection map of an SHRM for a distant view (seed 000 eq. 12)")
    rf.add_argument("shrm", help="SHRM .exr written by 'relight prefilter'")
    rf.add_argument("--view", required=True, help="X,Y,Z direction toward the viewer")
    rf.add_argument("--size", type=int, help="output rows S (S x 2S); default: the SHRM's")
    rf.add_argument("--out", required=True)
    rf.set_defaults(func=cmd_reflect)

    rd = subparsers.add_parser("render", help="render a sphere with an SHRM, or a sphere or mesh with Gaussian "
                               "lobes (orthographic camera, +Y up)")
    rd.add_argument("shrm", nargs="?", help="SHRM .exr (omit with --fit/--chain)")
    rd.add_argument("--view", required=True, help="X,Y,Z direction toward the (distant) viewer")
    rd.add_argument("--size", type=int, required=True, help="image size N (N x N)")
    rd.add_argument("--out", required=True, help="output EXR")
    rd.add_argument("--png", help="also write a tone-mapped PNG preview")
    rd.add_argument("--exposure", type=float, default=0.0, help="PNG exposure in stops")
    rd.add_argument("--local", action="store_true", help="evaluate the local SHRM per pixel (eq. 6)")
    from relight.cli_sg import add_render_arguments

    add_render_arguments(rd)
    from relight.cli_shtable import add_render_arguments as add_table_arguments

    add_table_arguments(rd)
    rd.set_defaults(func=cmd_render)
