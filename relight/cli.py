"""The ``relight`` command line (a contract other parts and external checks rely on).

    relight prefilter ENVMAP --brdf SPEC [--epsilon E | --order F] [--size S] --out OUT.exr [--report R.json]
    relight reference ENVMAP --brdf SPEC --size S --out OUT.exr
    relight compare A.exr B.exr [--json]
    relight info ENVMAP

Errors: exit status 2 and one clear line on stderr.

Start-up: a small job's process is mostly imports (issue 11, bench/startup.py), so nothing heavy is imported at
module level here, and a run of one of the four commands above does not load the other commands' modules at all
(:func:`build_parser` with ``argv``). Further commands register themselves with a
``register(subparsers)`` function: the core's own (SHRM rendering, scene planning) are listed in
``COMMAND_PROVIDERS``; every other package's (``relight serve`` from ``relight.server.cli``, ``relight worker`` from
``relight.worker.cli``, the client's ``upload``/``submit``/``jobs``) are entry points of the group
``relight.commands`` (``name = "module:register"`` in pyproject.toml), so the core never names them.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from relight.errors import InputError, RelightError

Handler = Callable[[argparse.Namespace], int]

#: The core's own modules with a ``register(subparsers)`` function adding more subcommands.
COMMAND_PROVIDERS = ["relight.cli_shrm", "relight.cli_plan", "relight.cli_factorize", "relight.cli_mesh",
                     "relight.cli_sg", "relight.cli_shtable", "relight.cli_export", "relight.cli_bake"]
#: The entry point group through which other packages add subcommands (value ``module:register``).
ENTRY_POINT_GROUP = "relight.commands"
#: The commands this module defines itself (a run of one of them loads no provider).
CORE_COMMANDS = ("prefilter", "reference", "compare", "info")


def _parse_order(text: str) -> tuple[int, int | None]:
    parts = text.split(",")
    try:
        if len(parts) == 1:
            return int(parts[0]), None
        if len(parts) == 2:
            return int(parts[0]), int(parts[1])
    except ValueError:
        pass
    raise InputError(f"--order must be F or F,P with integers, got {text!r}")


def _load_env(path: str) -> Any:
    from relight.envmap.environment import read_envmap

    return read_envmap(path)


def cmd_prefilter(args: argparse.Namespace) -> int:
    import numpy as np

    from relight.brdf.base import RadialLobe
    from relight.brdf.spec import parse_brdf
    from relight.envmap.exr import write_exr
    from relight.prefilter import prefilter_radial

    brdf = parse_brdf(args.brdf)
    env = _load_env(args.envmap)
    if getattr(args, "sun", "keep") != "keep":  # relight.sun: the map without its sun (or clamped), reported
        import dataclasses

        from relight.sun import apply_sun

        sun = apply_sun(env.pixels, args.sun)
        env = dataclasses.replace(env, pixels=sun.pixels)
        args.sun_report = sun.report
    order = p_order = None
    if args.order is not None:
        order, p_order = _parse_order(args.order)
    if not isinstance(brdf, RadialLobe) or p_order:
        try:
            shrm_cli = importlib.import_module("relight.cli_shrm")
        except ImportError as exc:
            raise InputError(f"BRDF {args.brdf!r} is not radially symmetric and SHRM support is unavailable") from exc
        result: int = shrm_cli.prefilter_shrm(args, brdf, env, order, p_order)
        return result
    res = prefilter_radial(env.pixels, brdf, epsilon=args.epsilon, order=order, size=args.size)
    res.report.input.update(
        {"path": str(args.envmap), "negatives_clamped": env.negatives_clamped, "min_negative": env.min_negative,
         "sun": getattr(args, "sun_report", {"mode": "keep"})}
    )
    write_exr(args.out, res.map.astype(np.float32), attributes={"relight.report": json.dumps(res.report.to_json())})
    if args.report:
        Path(args.report).write_text(json.dumps(res.report.to_json(), indent=2))
    o = res.report.orders
    print(
        f"wrote {args.out}: {res.map.shape[0]}x{res.map.shape[1]}, F_B={o.F_B}, predicted relative RMS "
        f"{o.rms_min_of_errors:.3g} (App. B bound {o.rms_appendix_b:.3g}), {res.report.total_seconds:.3f} s"
    )
    return 0


def cmd_reference(args: argparse.Namespace) -> int:
    import numpy as np

    from relight.brdf.base import RadialLobe
    from relight.brdf.spec import parse_brdf
    from relight.envmap.exr import write_exr
    from relight.reference import reference_radial

    brdf = parse_brdf(args.brdf)
    env = _load_env(args.envmap)
    if args.view is not None:
        try:
            shrm_cli = importlib.import_module("relight.cli_shrm")
        except ImportError as exc:
            raise InputError("view-dependent references need SHRM support") from exc
        result: int = shrm_cli.reference_view(args, brdf, env)
        return result
    if not isinstance(brdf, RadialLobe):
        raise InputError(f"BRDF {args.brdf!r} is view dependent: give --view X,Y,Z")
    out = reference_radial(env.pixels, brdf, args.size, epsilon=args.truncation)
    write_exr(args.out, out.astype(np.float32))
    print(f"wrote {args.out}: {out.shape[0]}x{out.shape[1]} (angular-domain reference)")
    return 0


def _read_map(path: str) -> Any:
    import numpy as np

    from relight.envmap.environment import read_image

    pixels, _ = read_image(path)
    return np.asarray(pixels, dtype=np.float64)


def cmd_compare(args: argparse.Namespace) -> int:
    from relight.metrics import compare

    a, b = _read_map(args.a), _read_map(args.b)
    if a.shape != b.shape:
        raise InputError(f"images differ in size: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    res = compare(a, b)
    if args.json:
        print(json.dumps(res, indent=2))
    else:
        print(
            f"relative RMS {res['relative_rms']:.4g}  max error {res['max_abs_error']:.4g} "
            f"({res['max_error_relative_to_peak']:.3g} of peak)  energy error {res['energy_error']:+.4g}"
        )
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    import numpy as np

    from relight.envmap.environment import read_envmap
    from relight.prefilter import project_lighting

    env = read_envmap(args.envmap)
    px = env.pixels
    lmax = min(args.lmax, px.shape[0] - 1)
    lighting = project_lighting(px, lmax)
    spectrum = lighting.band_energy()
    captured = np.cumsum(spectrum) / lighting.total_energy if lighting.total_energy > 0 else np.zeros_like(spectrum)
    info = {
        "path": args.envmap,
        "format": env.source_format,
        "width": int(px.shape[1]),
        "height": int(px.shape[0]),
        "min": float(px.min()),
        "max": float(px.max()),
        "mean": float(px.mean()),
        "negatives_clamped": env.negatives_clamped,
        "min_negative": env.min_negative,
        "sh_power_spectrum": [float(x) for x in spectrum],
        "energy_captured": [float(x) for x in captured],
    }
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(f"{args.envmap}: {info['width']}x{info['height']} {info['format']}")
        print(f"  range [{info['min']:.4g}, {info['max']:.4g}], mean {info['mean']:.4g}")
        print(f"  negative texel values clamped: {env.negatives_clamped} (most negative {env.min_negative:.3g})")
        print("  luminance energy captured by order F:")
        for f in [0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 511]:
            if f <= lmax:
                print(f"    F={f:4d}: {captured[f]:.6f}")
    return 0


#: ``relight.reference.DEFAULT_TRUNCATION``, repeated so that building the parser imports nothing numerical
#: (tests/relight/test_cli_export.py checks they agree and what the parser imports).
REFERENCE_TRUNCATION = 1e-8


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``relight`` parser with every command; or, when ``argv`` names one of :data:`CORE_COMMANDS`, with the
    core's commands only (the providers and entry points are not imported: a small job starts faster)."""
    p = argparse.ArgumentParser(prog="relight", description=__doc__.split("\n\n")[0] if __doc__ else None)
    sub = p.add_subparsers(dest="command", required=True)

    pf = sub.add_parser("prefilter", help="frequency-space prefilter (reflection map or SHRM)")
    pf.add_argument("envmap")
    pf.add_argument("--brdf", required=True, help="lambert, phong:s=32, microfacet:sigma=0.2, ... or a JSON file")
    g = pf.add_mutually_exclusive_group()
    g.add_argument("--epsilon", type=float, help="the paper's tolerance: energy fraction not captured")
    g.add_argument("--order", help="explicit order F (or F,P for SHRMs)")
    pf.add_argument("--size", type=int, help="output rows S (S x 2S); default S ~ 10 F")
    pf.add_argument("--grazing-limit", type=float, default=None,
                    help="SHRMs: epsilon holds for views with N.V at least this (default 0.1, RELIGHT_GRAZING_LIMIT)")
    pf.add_argument("--out", required=True)
    pf.add_argument("--report", help="write the JSON report here")
    pf.add_argument("--sun", default="keep", help="extract (prefilter without the sun; the report's input.sun "
                    "holds it as a directional light), clamp=V (pixel luminance <= V, removed energy recorded) or "
                    "keep (default); relight.sun")
    pf.set_defaults(func=cmd_prefilter)

    rf = sub.add_parser("reference", help="angular-domain brute-force reference")
    rf.add_argument("envmap")
    rf.add_argument("--brdf", required=True)
    rf.add_argument("--size", type=int, required=True)
    rf.add_argument("--view", help="X,Y,Z view direction for view-dependent BRDFs")
    rf.add_argument("--truncation", type=float, default=REFERENCE_TRUNCATION,
                    help=f"lobe energy fraction dropped (App. D; default {REFERENCE_TRUNCATION:g})")
    rf.add_argument("--out", required=True)
    rf.set_defaults(func=cmd_reference)

    cp = sub.add_parser("compare", help="relative RMS / max / energy error of A against reference B")
    cp.add_argument("a")
    cp.add_argument("b")
    cp.add_argument("--json", action="store_true")
    cp.set_defaults(func=cmd_compare)

    inf = sub.add_parser("info", help="size, range, negatives and SH spectrum of an environment map")
    inf.add_argument("envmap")
    inf.add_argument("--lmax", type=int, default=64)
    inf.add_argument("--json", action="store_true")
    inf.set_defaults(func=cmd_info)

    if argv is not None and _command(argv) in CORE_COMMANDS:
        return p
    for name in COMMAND_PROVIDERS:
        importlib.import_module(name).register(sub)
    for register in _entry_point_providers():
        register(sub)
    return p


def _command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names: its first word that is not an option (the top level has only ``-h``)."""
    return next((a for a in argv if not a.startswith("-")), None)


def _entry_point_providers() -> list[Callable[[Any], None]]:
    """The ``register`` functions of the ``relight.commands`` entry points, sorted by entry point name.

    ``importlib.metadata`` lists each distribution once (the first copy on ``sys.path``, the one Python imports),
    so an editable checkout and a wheel both on the path do not register a command twice; two distributions that
    claim one command name make argparse refuse the second.
    """
    from importlib.metadata import entry_points

    return [ep.load() for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name)]


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv).parse_args(argv)
    try:
        code: int = args.func(args)
        return code
    except (RelightError, OSError) as exc:
        print(f"relight: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
