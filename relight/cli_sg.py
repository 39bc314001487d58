"""Seed-002 commands of the ``relight`` CLI (Green, Kautz & Durand 2007, §3.2, §4, §5.1).

    relight fit BRDF_SPEC [--lobes K] [--elevations N] [--theta-max DEG] [--max-lobes M] [--max-inserted I]
        --out FIT.json
        per-elevation Gaussian-lobe fit (``relight.sgfit``), K lobes plus up to M - K (default 2) only at
        elevations whose error exceeds 5 %; prints the error table; FIT.json is a
        ``gaussian-lobes`` material: {"kind", "elevations": [{"theta_o", "error", "lobes": [{"mu", "sigma",
        "weight"}]}], "fit": report}, angles in radians.
    relight chain ENVMAP [--levels L | --epsilon E] [--ratio 2|sqrt2] [--sigma0 RAD] --out DIR
        Gaussian-prefiltered chain (``relight.gaussian_chain``): DIR/chain.json + DIR/level_JJ.exr (float16).
        ``--levels`` fixes the number of levels (orders from the default tolerance); ``--epsilon`` sets the
        tolerance for every level's order and the levels run from sigma0 (default: the map's pixel angle) to 90
        degrees.

    relight render --fit FIT.json --chain DIR --view X,Y,Z --size N --out OUT.exr [--png P] [--mesh NAME
                   [--visibility none|ao|sh|sh-lobe] [--vis-order F] [--rays R | --visibility-data V.npz]]
        eq. 5 on the unit sphere, or on a mesh with eq. 7's glossy shadows (``relight.sg_render``,
        ``relight.sg_shadow``); the command is ``relight.cli_shrm``'s ``render``, extended here.

Errors raise :class:`relight.errors.InputError` (the CLI prints one line and exits with status 2).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from relight import validate


def cmd_fit(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_brdf
    from relight.sgfit import DEFAULT_EXTRA_LOBES, FitSettings, error_table, fit_gaussian_lobes

    brdf = parse_brdf(args.brdf)
    max_lobes = min(args.lobes + DEFAULT_EXTRA_LOBES, 8) if args.max_lobes is None else args.max_lobes
    st = FitSettings(lobes=args.lobes, elevations=args.elevations, theta_max=math.radians(args.theta_max),
                     max_lobes=max(max_lobes, args.lobes) if args.max_lobes is None else max_lobes,
                     **({} if args.max_inserted is None else {"max_inserted": args.max_inserted}))
    mat = fit_gaussian_lobes(brdf, st)
    Path(args.out).write_text(json.dumps(mat.spec(), indent=1))
    print(error_table(mat))
    print(f"wrote {args.out}")
    return 0


def cmd_chain(args: argparse.Namespace) -> int:
    from relight.envmap import read_envmap
    from relight.gaussian_chain import RATIOS, build_chain, write_chain
    from relight.prefilter import DEFAULT_EPSILON

    env = read_envmap(args.envmap)
    chain = build_chain(env.pixels, sigma0=args.sigma0, ratio=RATIOS[args.ratio], levels=args.levels,
                        epsilon=args.epsilon if args.epsilon is not None else DEFAULT_EPSILON)
    man: dict[str, Any] = write_chain(args.out, chain)
    for j, e in enumerate(man["levels"]):
        o = e["orders"]
        print(f"level {j:2d}: sigma {math.degrees(e['sigma']):8.3f} deg  F={o['F_B']:4d}  {e['width']}x{e['height']}"
              f"  App. B bound (relative RMS) {o['rms_appendix_b']:.3g}")
    timings = chain.report.timings
    assert timings is not None  # build_chain always reports them
    print(f"wrote {args.out}/chain.json and {len(man['levels'])} float16 levels in {timings['total']:.3f} s")
    return 0


def add_render_arguments(rd: argparse.ArgumentParser) -> None:
    """The seed-002 options of ``relight render`` (``relight.cli_shrm`` owns the command)."""
    rd.add_argument("--fit", help="gaussian-lobes material (FIT.json from 'relight fit', or written by hand)")
    rd.add_argument("--chain", help="Gaussian chain folder from 'relight chain'")
    rd.add_argument("--mesh", help="draw this mesh (OBJ / glTF / GLB or a sample: bunny, teapot, bunny-100k) "
                    "instead of the unit sphere")
    rd.add_argument("--visibility", choices=["none", "ao", "sh", "sh-lobe"], default="none",
                    help="glossy shadows on a mesh (eq. 7): none, ambient occlusion, SH visibility at each lobe "
                         "centre, or SH visibility convolved with each lobe (default none)")
    rd.add_argument("--vis-order", type=int, default=3,
                    help="SH visibility order F: 1, 2, 3 = 4, 9, 16 coefficients (default 3, the paper's)")
    rd.add_argument("--rays", type=int, default=1024, help="visibility rays per vertex (default 1024)")
    rd.add_argument("--visibility-data", help="per-vertex visibility from 'relight visibility' (.npz) instead of "
                    "ray casting here")
    rd.add_argument("--supersample", type=int, default=2, help="sub-pixels per pixel side (default 2)")


def render_gaussian(args: argparse.Namespace) -> int:
    """``relight render --fit FIT.json --chain DIR``: the unit sphere, or ``--mesh`` with ``--visibility``."""
    import numpy as np

    from relight.brdf.gaussian_lobes import GaussianLobes
    from relight.brdf.spec import parse_brdf
    from relight.cli_shrm import parse_view
    from relight.envmap.display import write_png_preview
    from relight.envmap.exr import write_exr
    from relight.errors import InputError
    from relight.gaussian_chain import read_chain
    from relight.sg_render import GaussianRenderReport, render_mesh_gaussian, render_sphere_gaussian

    if args.fit is None or args.chain is None:
        raise InputError("Gaussian-lobe rendering needs both --fit FIT.json and --chain DIR")
    if args.shrm is not None:
        raise InputError("give either an SHRM file or --fit/--chain, not both")
    if args.local:
        raise InputError("--local is an SHRM option (eq. 6); Gaussian lobes are evaluated per pixel already")
    validate.int_in_range("--size", args.size, 1, 8192)
    validate.int_in_range("--supersample", args.supersample, 1, 8)
    mat = parse_brdf(args.fit)
    if not isinstance(mat, GaussianLobes):
        raise InputError(f"--fit {args.fit!r} is not a gaussian-lobes material (kind {mat.kind!r})")
    chain = read_chain(args.chain)
    view = np.array(parse_view(args.view))
    report = GaussianRenderReport(object="sphere")
    if args.mesh is None:
        if args.visibility != "none" or args.visibility_data:
            raise InputError("--visibility needs --mesh (the sphere does not shadow itself)")
        img = render_sphere_gaussian(mat, chain, view, args.size, supersample=args.supersample)
        what = "sphere"
    else:
        from relight.mesh import load_mesh

        mesh = load_mesh(args.mesh).normalised()
        vis = None
        if args.visibility != "none":
            vis = _vertex_visibility(args, mesh)
        img, report = render_mesh_gaussian(mat, chain, mesh, view, args.size, supersample=args.supersample,
                                           visibility=vis, mode=args.visibility,
                                           order=args.vis_order if args.visibility != "none" else None)
        what = f"mesh {args.mesh} ({mesh.n_vertices} vertices)"
    write_exr(args.out, img.astype(np.float32))
    msg = f"wrote {args.out}"
    if args.png:
        write_png_preview(args.png, img, exposure=args.exposure)
        msg += f" and {args.png}"
    print(f"{msg}: {args.size}x{args.size} {what}, view {view.tolist()}, Gaussian lobes (K = {mat.n_lobes}), "
          f"visibility {args.visibility}")
    if report.unclamped_min is not None:
        print(f"visibility before clamping to [0, 1]: {report.unclamped_min:.3f} .. {report.unclamped_max:.3f} "
              f"({100 * (report.clamped_fraction or 0.0):.1f} % of lobe lookups clamped)")
    return 0


def _vertex_visibility(args: argparse.Namespace, mesh: Any) -> Any:
    import numpy as np

    from relight.errors import InputError
    from relight.visibility import TransferSettings, compute_transfer

    validate.int_in_range("--vis-order", args.vis_order, 0, 8)
    if args.visibility_data:
        with np.load(args.visibility_data) as data:
            if "visibility" not in data:
                raise InputError(f"{args.visibility_data!r} has no 'visibility' array")
            vis = np.asarray(data["visibility"], dtype=np.float64)
        if vis.shape[0] != mesh.n_vertices:
            raise InputError(f"{args.visibility_data!r} holds {vis.shape[0]} vertices, the mesh {mesh.n_vertices}")
        return vis
    return compute_transfer(mesh, TransferSettings(order=args.vis_order, rays=args.rays)).arrays["visibility"]


def register(sub: Any) -> None:
    fp = sub.add_parser("fit", help="fit Gaussian lobes to an isotropic BRDF (seed 002)")
    fp.add_argument("brdf", help="BRDF spec: torrance-sparrow:alpha=0.2,fresnel=none, merl:file.binary, a JSON file")
    fp.add_argument("--lobes", type=int, default=3, help="Gaussians per elevation (default 3)")
    fp.add_argument("--elevations", type=int, default=15, help="view elevations (default 15)")
    fp.add_argument("--theta-max", type=float, default=87.0, help="largest elevation in degrees (default 87)")
    fp.add_argument("--max-lobes", type=int, default=None,
                    help="add lobes (up to this many; default lobes + 2) only at elevations whose error exceeds "
                         "5 %%; --max-lobes equal to --lobes gives the paper's fixed K")
    fp.add_argument("--max-inserted", type=int, default=None,
                    help="elevations the fit may add where interpolated lobes fail the mid-elevation rule "
                         "(default 24; 0: exactly N elevations)")
    fp.add_argument("--out", required=True, help="FIT.json")
    fp.set_defaults(func=cmd_fit)

    cp = sub.add_parser("chain", help="Gaussian-prefiltered environment chain (seed 002 §5.1)")
    cp.add_argument("envmap")
    g = cp.add_mutually_exclusive_group()
    g.add_argument("--levels", type=int, help="number of levels")
    g.add_argument("--epsilon", type=float, help="tolerance (uncaptured energy) for every level's order")
    cp.add_argument("--ratio", choices=["2", "sqrt2"], default="2", help="sigma ratio between levels (default 2)")
    cp.add_argument("--sigma0", type=float, help="sharpest level's sigma in radians (default: pi / height)")
    cp.add_argument("--out", required=True, help="output folder")
    cp.set_defaults(func=cmd_chain)
