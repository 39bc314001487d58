"""Mesh commands of the ``relight`` CLI (issue 13, item 6).

    relight mesh info MESH [--json]
        counts, bounds and defects of an OBJ / glTF / GLB file (or a sample: bunny, teapot, bunny-100k) after
        welding into relight's canonical vertex order (``relight.mesh``)
    relight visibility MESH --order F --rays R --out FILE.npz
                      [--kind visibility|diffuse_transfer|shadow_matrix] [--bounces B] [--albedo A]
                      [--sampling fibonacci|random] [--seed S] [--block N]
        per-vertex SH visibility and transfer (``relight.visibility``); FILE.npz holds ``positions`` (V x 3,
        canonical order), ``normals`` (V x 3), ``faces``, ``ao`` (V), ``ao_error``, ``visibility`` (V x (F+1)^2),
        ``visibility_error``, for diffuse_transfer ``transfer`` (+ ``transfer_error``, and ``direct_transfer`` with
        bounces), for shadow_matrix ``shadow_matrix`` (V x (F+1)^2 x (F+1)^2, + ``shadow_matrix_error``), and
        ``manifest`` (JSON text: settings, RMS Monte Carlo errors, timing)

``register(subparsers)`` adds them (``relight.cli.COMMAND_PROVIDERS``). Errors: one line on stderr, exit status 2.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np


def cmd_mesh_info(args: argparse.Namespace) -> int:
    from relight.mesh import load_mesh

    mesh = load_mesh(args.mesh)
    d = dict(mesh.defects)
    d["path"] = str(args.mesh)
    if args.json:
        print(json.dumps(d, indent=2))
        return 0
    b = d["bounds"]
    print(f"{args.mesh}: {d['vertices']} vertices, {d['faces']} triangles, {d['edges']} edges "
          f"(input {d['input_vertices']} vertices, {d['input_faces']} triangles; {d['merged_vertices']} welded)")
    print(f"  bounds min {np.round(b['min'], 6).tolist()} max {np.round(b['max'], 6).tolist()}, "
          f"bounding radius {d['bounding_radius']:.6g}, area {d['surface_area']:.6g}")
    print(f"  watertight {d['watertight']}; boundary edges {d['boundary_edges']}, non-manifold edges "
          f"{d['non_manifold_edges']}, inconsistently oriented edges {d['inconsistently_oriented_edges']}")
    print(f"  degenerate faces {d['degenerate_faces']}, collapsed faces {d['collapsed_faces']}, unreferenced "
          f"vertices {d['unreferenced_vertices']}, vertices without a normal {d['vertices_without_normal']}")
    print(f"  tangents from {d['tangent_source']}, normals {d['normal_weighting']}-weighted")
    return 0


def cmd_visibility(args: argparse.Namespace) -> int:
    from relight.mesh import load_mesh
    from relight.visibility import TransferSettings, compute_transfer

    settings = TransferSettings(order=args.order, rays=args.rays, kind=args.kind, bounces=args.bounces,
                                albedo=args.albedo, sampling=args.sampling, seed=args.seed, block=args.block)
    mesh = load_mesh(args.mesh)
    res = compute_transfer(mesh, settings)
    manifest: dict[str, Any] = dict(res.manifest)
    manifest["mesh"] = {"path": str(args.mesh), "defects": mesh.defects}
    out: dict[str, Any] = {"positions": mesh.positions.astype(np.float32),
                           "normals": mesh.normals.astype(np.float32), "faces": mesh.faces.astype(np.int32)}
    out.update(res.arrays)
    out["manifest"] = np.array(json.dumps(manifest))
    with open(args.out, "wb") as fh:
        np.savez_compressed(fh, **out)
    e = manifest["monte_carlo_error_rms"]
    print(f"wrote {args.out}: {mesh.n_vertices} vertices, {settings.kind} order {settings.order} "
          f"({(settings.order + 1) ** 2} coefficients), {settings.rays} rays/vertex, "
          f"{manifest['mrays_per_second']:.2f} Mrays/s, {manifest['seconds']:.2f} s; Monte Carlo error (RMS) "
          + ", ".join(f"{k} {v:.3g}" for k, v in e.items()))
    return 0


#: ``relight.visibility.KINDS``, repeated so that building the parser does not import numba and SciPy
#: (tests/relight/test_cli_export.py checks they agree).
VISIBILITY_KINDS = ("visibility", "diffuse_transfer", "shadow_matrix")


def register(subparsers: Any) -> None:
    """Add ``mesh info`` and ``visibility`` to the ``relight`` command line."""
    me = subparsers.add_parser("mesh", help="mesh commands (info)")
    msub = me.add_subparsers(dest="mesh_command", required=True)
    mi = msub.add_parser("info", help="counts, bounds and defects of a mesh (OBJ, glTF, GLB or a sample name)")
    mi.add_argument("mesh")
    mi.add_argument("--json", action="store_true")
    mi.set_defaults(func=cmd_mesh_info)

    vi = subparsers.add_parser("visibility", help="per-vertex SH visibility / diffuse transfer / shadow matrix")
    vi.add_argument("mesh")
    vi.add_argument("--order", type=int, required=True, help="SH order F (l <= F, (F+1)^2 coefficients)")
    vi.add_argument("--rays", type=int, required=True, help="rays per vertex")
    vi.add_argument("--out", required=True, help="output .npz")
    vi.add_argument("--kind", choices=VISIBILITY_KINDS, default="visibility")
    vi.add_argument("--bounces", type=int, default=0, help="interreflection bounces (diffuse_transfer)")
    vi.add_argument("--albedo", type=float, default=0.8, help="albedo of the interreflections")
    vi.add_argument("--sampling", choices=("fibonacci", "random"), default="fibonacci")
    vi.add_argument("--seed", type=int, default=0)
    vi.add_argument("--block", type=int, default=4096, help="vertices per block")
    vi.set_defaults(func=cmd_visibility)
