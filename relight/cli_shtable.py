"""SH-table command of the ``relight`` CLI (seed 003 §3; ``relight.sh_table``).

    relight sh-table BRDF_SPEC [--order F] [--resolution R] [--layout parabolic|hemi-octahedral] --out TABLE.npz|.exr

``BRDF_SPEC`` is any spec of ``relight.brdf.spec.parse_frame_brdf`` (isotropic, anisotropic, measured). The
``.npz`` holds ``coefficients`` (R x R x (F+1)^2 x C float32, relight's real basis in the local frame x = tangent,
y = bitangent, z = normal), ``views`` (R x R x 3, the unit local view of each texel), ``valid`` (R x R) and
``manifest`` (JSON); the ``.exr`` holds one float16 RGB layer per coefficient (docs/conventions.md, "SH tables").
Prints one JSON line (the manifest). Errors raise ``InputError`` (exit status 2, one line).

    relight render --table TABLE.npz|.exr --envmap MAP [--cap X,Y,Z,SR,R,G,B ...] [--window hann|lanczos]
                   [--tangent azimuthal[:X,Y,Z]|project:X,Y,Z]
                   [--mesh NAME [--transfer SHADOW.npz | --bounces B [--rays R]]]
                   --view X,Y,Z --size N --out OUT.exr [--png PREVIEW.png]

shades the unit sphere (per pixel) or a mesh (per vertex, interpolated: the GPU path's Gouraud shading) with the
table (seed 003 §4, ``relight.sh_render``): the map's real SH coefficients to the table's order plus circular
lights in closed form, optionally windowed (the relative L2 change of the lighting is printed as its cost), the
lighting rotated into each point's frame (``--tangent``; default the azimuthal field about +Y). ``--transfer``:
shadow matrices from ``relight visibility MESH --kind shadow_matrix`` of the same mesh, folded with the rotation
(PRT, §5, ``relight.sh_prt``). ``--bounces B``: shadows and B interreflection bounces with the table's BRDF
(``relight.sh_prt_bounce``, ``--rays`` per vertex), computed for the mesh here.
"""

from __future__ import annotations

import argparse
import json
from typing import Any


def cmd_sh_table(args: argparse.Namespace) -> int:
    from relight.brdf.spec import parse_frame_brdf
    from relight.sh_table import build_table, write_table

    brdf = parse_frame_brdf(args.brdf)
    table = build_table(brdf, order=args.order, resolution=args.resolution, layout=args.layout)
    man = write_table(args.out, table)
    print(json.dumps({"out": str(args.out), **man}, sort_keys=True))
    return 0


def parse_tangent(text: str) -> dict[str, Any]:
    """``azimuthal`` (axis +Y), ``azimuthal:X,Y,Z`` or ``project:X,Y,Z`` -> a ``relight.sh_render.frames_for`` spec."""
    from relight.cli_shrm import parse_view
    from relight.errors import InputError

    kind, _, rest = text.partition(":")
    if kind == "azimuthal":
        return {"kind": "azimuthal", "axis": list(parse_view(rest)) if rest else [0.0, 1.0, 0.0]}
    if kind == "project" and rest:
        return {"kind": "project", "direction": list(parse_view(rest))}
    raise InputError(f"--tangent must be 'azimuthal', 'azimuthal:X,Y,Z' or 'project:X,Y,Z', got {text!r}")


def parse_cap(text: str) -> tuple[list[float], float, list[float]]:
    """``X,Y,Z,SOLID_ANGLE,R,G,B`` -> (direction, steradians, colour)."""
    from relight.errors import InputError

    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"--cap must be X,Y,Z,SOLID_ANGLE,R,G,B numbers, got {text!r}") from None
    if len(v) != 7:
        raise InputError(f"--cap needs 7 numbers X,Y,Z,SOLID_ANGLE,R,G,B, got {len(v)} in {text!r}")
    return v[:3], v[3], v[4:]


def render_table(args: argparse.Namespace) -> int:
    """``relight render --table``: the sphere or ``--mesh`` shaded with a per-view SH table (module docstring)."""
    import numpy as np

    from relight import validate
    from relight.cli_shrm import parse_view
    from relight.envmap.display import write_png_preview
    from relight.envmap.exr import write_exr
    from relight.errors import InputError
    from relight.sh_render import cap_light, environment_coefficients, frames_for, render_sphere, shade
    from relight.sh_table import read_table

    if args.shrm is not None or args.fit is not None or args.chain is not None or args.local:
        raise InputError("--table renders with an SH table alone: drop the SHRM file, --fit, --chain and --local")
    if args.visibility != "none":
        raise InputError("--visibility is for Gaussian lobes; SH tables take shadows from --transfer")
    validate.int_in_range("--size", args.size, 1, 8192)
    validate.int_in_range("--supersample", args.supersample, 1, 8)
    table = read_table(args.table)
    n = (table.order + 1) ** 2
    light = np.zeros((n, 3))
    if args.envmap is None and not args.cap:
        raise InputError("--table needs lighting: --envmap MAP and/or --cap X,Y,Z,SOLID_ANGLE,R,G,B")
    if args.envmap is not None:
        from relight.envmap.environment import read_envmap

        light += environment_coefficients(read_envmap(args.envmap).pixels, table.order)
    for cap in args.cap or []:
        d, sr, col = parse_cap(cap)
        light += cap_light(d, sr, col, table.order)
    report: dict[str, Any] = {"order": table.order, "layout": table.layout}
    if args.window != "none":
        from relight.sh_render import window_lighting

        light, cost = window_lighting(light, args.window)
        report["window"] = {"kind": args.window, "lighting_l2_change": cost}
    view = np.array(parse_view(args.view), dtype=np.float64)
    view /= np.linalg.norm(view)
    tangent = parse_tangent(args.tangent)
    if args.mesh is None:
        if args.transfer is not None or args.bounces is not None:
            raise InputError("--transfer and --bounces need --mesh (transfer belongs to a mesh's vertices)")
        img = render_sphere(table, light, view, args.size, tangent=tangent, supersample=args.supersample,
                            exact_azimuth=False)
    else:
        from relight.mesh import load_mesh
        from relight.mesh_render import interpolate, surface_samples

        mesh = load_mesh(args.mesh)
        frames = frames_for(mesh.normals, tangent)
        if args.bounces is not None:
            if args.transfer is not None:
                raise InputError("--bounces computes the interreflected transfer itself; drop --transfer")
            from relight.sh_prt import folded_transfer, shade_prt
            from relight.sh_prt_bounce import BounceSettings, vertex_transfer

            settings = BounceSettings(rays=args.rays, bounces=args.bounces)
            total = vertex_transfer(table, mesh, frames, settings).total()
            vertex = shade_prt(table, light, frames, view, folded_transfer(frames, total, table.order),
                               exact_azimuth=False)
            report["shadows"] = "transfer"
            report["interreflections"] = {"bounces": settings.bounces, "rays": settings.rays}
        elif args.transfer is not None:
            from relight.sh_prt import folded_transfer, shade_prt

            with np.load(args.transfer, allow_pickle=False) as z:
                if "shadow_matrix" not in z.files or "positions" not in z.files:
                    raise InputError(f"{args.transfer}: no shadow_matrix (run relight visibility --kind shadow_matrix)")
                shadow, pos = np.asarray(z["shadow_matrix"], np.float64), np.asarray(z["positions"], np.float64)
            if pos.shape != mesh.positions.shape or not np.allclose(pos, mesh.positions, rtol=0, atol=1e-5):
                raise InputError(f"{args.transfer} was computed for another mesh ({pos.shape[0]} vertices, "
                                 f"{args.mesh} has {mesh.n_vertices})")
            if shadow.shape[1] < n:
                raise InputError(f"{args.transfer} has order {int(np.sqrt(shadow.shape[1])) - 1} < the table's "
                                 f"{table.order}")
            vertex = shade_prt(table, light, frames, view, folded_transfer(frames, shadow, table.order),
                               exact_azimuth=False)
            report["shadows"] = "transfer"
        else:
            vertex = shade(table, light, frames, view, exact_azimuth=False)
        norm = mesh.normalised()
        samples = surface_samples(norm, view, args.size, args.supersample)
        img = samples.image(interpolate(samples, norm, vertex))
    write_exr(args.out, img.astype(np.float32), attributes={"relight.render": json.dumps(report, sort_keys=True)})
    if args.png:
        write_png_preview(args.png, img, exposure=args.exposure)
    print(json.dumps({"out": str(args.out), **report}, sort_keys=True))
    return 0


def add_render_arguments(rd: argparse.ArgumentParser) -> None:
    """The seed-003 options of ``relight render`` (``relight.cli_shrm`` owns the command; ``--mesh`` and
    ``--supersample`` come from ``relight.cli_sg``)."""
    rd.add_argument("--table", help="per-view SH table (.npz / .exr from 'relight sh-table'): seed 003 shading")
    rd.add_argument("--envmap", help="lat-long lighting map for --table")
    rd.add_argument("--cap", action="append", help="circular light X,Y,Z,SOLID_ANGLE,R,G,B for --table "
                    "(repeatable; radiance R,G,B over the cap)")
    rd.add_argument("--window", choices=["none", "hann", "lanczos"], default="none",
                    help="window the lighting against ringing (--table; its L2 cost is reported)")
    rd.add_argument("--tangent", default="azimuthal", help="tangent frames for --table: azimuthal[:X,Y,Z] "
                    "(default axis +Y) or project:X,Y,Z (a constant brushing direction)")
    rd.add_argument("--transfer", help="shadow matrices .npz of --mesh ('relight visibility --kind shadow_matrix') "
                    "for --table: PRT shadows")
    rd.add_argument("--bounces", type=int, help="--table --mesh: PRT shadows and this many interreflection "
                    "bounces with the table's BRDF (relight.sh_prt_bounce; computed here with --rays per vertex, "
                    "no --transfer)")


#: ``relight.sh_table``'s defaults, repeated so that registering the command imports nothing numerical
#: (tests/relight/test_cli_shtable.py checks that they agree).
DEFAULT_ORDER, DEFAULT_RESOLUTION, DEFAULT_LAYOUT = 4, 128, "parabolic"


def register(subparsers: Any) -> None:
    """Add ``sh-table`` to the ``relight`` command line."""
    st = subparsers.add_parser("sh-table", help="per-view SH table of a BRDF's product function (seed 003)")
    st.add_argument("brdf", help="BRDF spec, e.g. 'ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0'")
    st.add_argument("--order", type=int, default=DEFAULT_ORDER, help="SH order F: l <= F, (F+1)^2 coefficients")
    st.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION, help="view map size R (R x R)")
    st.add_argument("--layout", default=DEFAULT_LAYOUT, choices=["parabolic", "hemi-octahedral"])
    st.add_argument("--out", required=True, help="TABLE.npz or TABLE.exr")
    st.set_defaults(func=cmd_sh_table)
