"""Planning commands of the ``relight`` CLI: the accuracy–time explorer, the scene planner and the cost model.

    relight tradeoff ENVMAP --brdf SPEC --out DIR [--rows H] [--size S] [--view X,Y,Z] [--epsilons E,...]
                     [--truncations T,...] [--mitsuba {auto,on,off}] [--title TEXT]
        DIR/tradeoff.json (the points), DIR/tradeoff_meta.json and three PNG plots (``relight.tradeoff``); with a
        Mitsuba 3 twin of the material each point's error against Mitsuba too (auto; on: an error without one)
    relight scene plan SCENE.json [--json]             what each object needs, what is skipped and why
    relight scene run SCENE.json --out DIR [--preview N] [--json]
    relight costmodel [--recalibrate] [--json]         the calibrated constants (``relight.costmodel``)

``register(subparsers)`` adds them (``relight.cli.COMMAND_PROVIDERS``). Errors are ``InputError``: one line on stderr,
exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from typing import Any

import numpy as np

from relight import validate
from relight.errors import InputError

#: Input rows the tradeoff works on by default (area-averaged, ``relight.envmap.resample_latlong``): its reference
#: is the untruncated angular method, O(S_L^2 S_B^2).
DEFAULT_TRADEOFF_ROWS = 64
#: ``--mitsuba`` to ``relight.tradeoff.sweep(mitsuba=...)``: auto measures when the material has a Mitsuba 3 twin.
MITSUBA_MODES: dict[str, bool | None] = {"auto": None, "on": True, "off": False}


def _floats(text: str | None, what: str) -> list[float] | None:
    if text is None:
        return None
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--{what} must be comma-separated numbers, got {text!r}") from None
    if not vals or not all(math.isfinite(v) and 0.0 < v < 1.0 for v in vals):
        raise InputError(f"--{what} must be numbers in (0, 1), got {text!r}")
    return vals


def _load_pixels(path: str, rows: int | None) -> tuple[Any, int]:
    from relight.envmap.environment import read_envmap
    from relight.envmap.resample import resample_latlong

    env = read_envmap(path)
    px = np.asarray(env.pixels, dtype=np.float64)
    h = px.shape[0]
    if rows is not None:
        validate.at_least("--rows", rows, 4)
        if rows < h:
            px = np.asarray(resample_latlong(px, rows), dtype=np.float64)
    return px, h


def cmd_tradeoff(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_brdf
    from relight.cli_shrm import parse_view
    from relight.tradeoff import sweep, write_tradeoff

    brdf = parse_brdf(args.brdf)
    px, h_in = _load_pixels(args.envmap, args.rows)
    view = parse_view(args.view) if args.view else None
    kwargs: dict[str, Any] = {}
    if view is not None:
        kwargs["view"] = view
    eps = _floats(args.epsilons, "epsilons")
    trunc = _floats(args.truncations, "truncations")
    if trunc is not None:
        kwargs["truncations"] = trunc
    res = sweep(px, brdf, epsilons=eps, size=args.size, mitsuba=MITSUBA_MODES[args.mitsuba], **kwargs)
    res.meta = replace(res.meta, input=replace(res.meta.input, path=str(args.envmap), original_height=h_in))
    paths = write_tradeoff(res, args.out, title=args.title)
    lo, hi = res.meta.time_ratio_range or (math.nan, math.nan)
    front = [p for p in res.points if p.pareto_overall]
    print(f"wrote {', '.join(sorted(p.name for p in paths.values()))} to {args.out}: {len(res.points)} points "
          f"({px.shape[0]} x {px.shape[1]} input, {res.meta.output.height} x {res.meta.output.width} "
          f"output), {len(front)} on the overall Pareto front; predicted/measured time {lo:.2f}..{hi:.2f}")
    mits = res.meta.mitsuba
    if mits.computed:
        print(f"against Mitsuba 3 ({mits.variant}, {mits.spp} spp, {mits.seconds or 0.0:.1f} s): noise floor "
              f"{mits.noise or 0.0:.2g}, angular reference {mits.reference_error or 0.0:.2g}")
    else:
        print(f"not measured against Mitsuba 3: {mits.reason}")
    return 0


def _scene_and_pixels(path: str) -> tuple[Any, Any]:
    from relight.envmap.environment import read_envmap
    from relight.planning import load_scene

    scene = load_scene(path)
    env = read_envmap(scene.environment)
    return scene, np.asarray(env.pixels, dtype=np.float64)


def cmd_scene_plan(args: argparse.Namespace) -> int:
    from relight.planning import format_plan, plan_json, plan_scene

    scene, px = _scene_and_pixels(args.scene)
    plan = plan_scene(scene, px)
    print(plan_json(plan) if args.json else format_plan(plan))
    return 0


def cmd_scene_run(args: argparse.Namespace) -> int:
    from relight.planning import format_plan, plan_scene, run_plan

    validate.int_in_range("--preview", args.preview, 0, 4096)
    scene, px = _scene_and_pixels(args.scene)
    plan = plan_scene(scene, px)
    result = run_plan(plan, args.out, preview_size=args.preview).result
    if args.json:
        print(json.dumps(result.to_json(), indent=1))
    else:
        print(format_plan(plan))
        print(f"wrote {len(result.objects)} object(s) to {args.out} (result.json, plan.json): measured "
              f"{result.measured_seconds:.3g} s, predicted {result.predicted_seconds:.3g} s")
    return 0


def cmd_costmodel(args: argparse.Namespace) -> int:
    from relight import costmodel

    cal = costmodel.load_calibration(recalibrate=args.recalibrate)
    path = costmodel.cache_path(key=cal.key)
    lo, hi = cal.ratio_range()
    if args.json:
        print(json.dumps({**cal.as_dict(), "cache": str(path), "ratio_range": [lo, hi]}, indent=1))
        return 0
    print(f"cost model {'calibrated ' + cal.created if cal.calibrated else '(uncalibrated defaults)'} in "
          f"{cal.calibration_seconds:.1f} s on {cal.machine.get('cpu')} ({cal.machine.get('cpu_count')} cores); "
          f"cache {path}")
    for stage, feats in costmodel.STAGES.items():
        print(f"  {stage}: " + ", ".join(f"{f} = {cal.constants[f]:.3g}" for f in feats))
    print(f"  predicted / measured time over the calibration runs: {lo:.2f} .. {hi:.2f}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``tradeoff``, ``scene plan``, ``scene run`` and ``costmodel`` to the ``relight`` command line."""
    tr = subparsers.add_parser("tradeoff", help="accuracy against time: frequency vs angular method, Pareto fronts")
    tr.add_argument("envmap")
    tr.add_argument("--brdf", required=True, help="lambert, phong:s=32, microfacet:sigma=0.2, ... or a JSON file")
    tr.add_argument("--out", required=True, help="output folder (tradeoff.json, tradeoff_meta.json, PNG plots)")
    tr.add_argument("--rows", type=int, default=DEFAULT_TRADEOFF_ROWS,
                    help=f"area-average the input to this many rows first (default {DEFAULT_TRADEOFF_ROWS})")
    tr.add_argument("--size", type=int, help="output rows S of every map (default: rows / 2, at most 64)")
    tr.add_argument("--view", help="X,Y,Z view direction for view-dependent BRDFs and the Mitsuba sphere "
                                   "(default 0,0.5,0.866)")
    tr.add_argument("--epsilons", help="comma-separated tolerances of the frequency method")
    tr.add_argument("--truncations", help="comma-separated lobe truncations of the angular method")
    tr.add_argument("--mitsuba", choices=tuple(MITSUBA_MODES), default="auto",
                    help="also measure every point against a Mitsuba 3 render when the material has a twin "
                         "(auto, the default); on: fail without one; off: never")
    tr.add_argument("--title", help="plot title (default: the BRDF kind)")
    tr.set_defaults(func=cmd_tradeoff)

    sc = subparsers.add_parser("scene", help="plan and run a scene: simulate only what it calls for")
    ssub = sc.add_subparsers(dest="scene_command", required=True)
    sp = ssub.add_parser("plan", help="print the plan: per object what is simulated, what is skipped and why")
    sp.add_argument("scene", help="scene JSON file (relight.planning.scene)")
    sp.add_argument("--json", action="store_true", help="print the plan as JSON")
    sp.set_defaults(func=cmd_scene_plan)
    sr = ssub.add_parser("run", help="plan and execute a scene, sharing the lighting projection")
    sr.add_argument("scene")
    sr.add_argument("--out", required=True, help="output folder")
    sr.add_argument("--preview", type=int, default=0, help="also render N x N sphere previews (PNG)")
    sr.add_argument("--json", action="store_true", help="print the result summary as JSON")
    sr.set_defaults(func=cmd_scene_run)

    cm = subparsers.add_parser("costmodel", help="show (or redo) this machine's cost-model calibration")
    cm.add_argument("--recalibrate", action="store_true")
    cm.add_argument("--json", action="store_true")
    cm.set_defaults(func=cmd_costmodel)

