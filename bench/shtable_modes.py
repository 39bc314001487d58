"""Seed 003's Table 1 on this machine: frame times of the three SH-table rendering modes in one run.

Kautz, Sloan & Snyder 2002, Table 1 (Radeon 8500, host-side rotation): fixed light 3.8–4.8x and fixed view
21–31x faster than the general mode (view and lighting both changing). Here the rotation runs per vertex on the GPU
(``web/shaders/sh_rotation.glsl``, ``relight.gl.sh_table``); the issue asks the general mode to cost at most 3x
the fixed-view mode in the same run. Measured with moderngl on whatever EGL device is present (Mesa llvmpipe on
the CI machine: absolute numbers are CPU-bound and only the ratios mean anything).

Mesh: ``bunny-100k`` (the sample bunny subdivided three times, 117,570 vertices; ``relight.mesh.load``), frames from
the projected brushing direction (Kautz §6), Ashikhmin–Shirley (48, 16) table 128 x 128 x 25 (float16 texture
array), random RGB lighting; each mode draws ``--frames`` frames (the view turning 1 degree per frame; general:
lighting uniforms re-sent too) into a ``--size`` squared float target, then one read-back; the first frame of each
mode (shader compilation) is not timed. Also reported: the fixed modes' per-vertex preparation (one GPU pass each
time the lighting or the view changes), and the paper's "transfer" column (PRT, §5: a folded 25 x 25 transfer
matrix per vertex, float16; timed with T_p = I, i.e. T'_p = S M(R_p) from ``relight.sh_prt.folded_transfer`` — the
cost does not depend on the values — whose image must equal the general mode's: its largest difference is
printed as a check).

Prints a markdown table and JSON (``--json PATH``). ``--quick``: the 1,839-vertex bunny, 64 x 64 table.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from relight.brdf.spec import parse_frame_brdf
from relight.gl.sh_table import MODES, TableRenderer
from relight.mesh.load import sample_mesh
from relight.sh_prt import folded_transfer
from relight.sh_table import build_table
from relight.tangent_frames import projected_frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    name = "bunny" if args.quick else "bunny-100k"
    mesh = sample_mesh(name).normalised()
    frames = projected_frames(mesh.normals, (1.0, 0.3, 0.2))
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0"),
                        resolution=64 if args.quick else 128)
    rng = np.random.default_rng(0)
    light = rng.normal(size=(25, 3)) * 0.2
    light[0] += 2.0
    view = np.array([0.3, 0.4, 0.87])
    r = TableRenderer(table.coefficients, "parabolic")
    geo = r.geometry(mesh.positions, mesh.normals, frames, mesh.faces)
    out: dict[str, Any] = {"machine": platform.platform(), "renderer": r.ctx.info.get("GL_RENDERER", "?"),
                           "mesh": name, "vertices": mesh.n_vertices, "faces": mesh.n_faces, "size": args.size,
                           "frames": args.frames}
    for mode in MODES:
        t0 = time.perf_counter()
        r.prepare(mode, geo, view=view, lighting=light)
        prep = time.perf_counter() - t0
        r.draw(mode, geo, view, light, args.size)  # compile + warm up
        t0 = time.perf_counter()
        r.draw(mode, geo, view, light, args.size, frames=args.frames)
        per = (time.perf_counter() - t0) / args.frames
        out[mode] = {"frame_ms": 1e3 * per, "fps": 1.0 / per, "prepare_s": prep}
    t0 = time.perf_counter()
    eye = np.broadcast_to(np.eye(25), (mesh.n_vertices, 25, 25))
    r.set_transfer(folded_transfer(frames, eye, 4))
    prep = time.perf_counter() - t0
    ref = r.draw("general", geo, view, light, args.size)
    img = r.draw("transfer", geo, view, light, args.size)
    t0 = time.perf_counter()
    r.draw("transfer", geo, view, light, args.size, frames=args.frames)
    per = (time.perf_counter() - t0) / args.frames
    out["transfer"] = {"frame_ms": 1e3 * per, "fps": 1.0 / per, "prepare_s": prep,
                       "max_diff_vs_general": float(np.abs(img - ref).max() / np.abs(ref).max())}
    base = out["general"]["frame_ms"]
    for mode in (*MODES, "transfer"):
        out[mode]["speed_vs_general"] = base / out[mode]["frame_ms"]
    out["general_over_fixed_view"] = base / out["fixed-view"]["frame_ms"]
    print(f"{name}: {mesh.n_vertices} vertices, {mesh.n_faces} faces, {args.size}^2 pixels, {out['renderer']}")
    print("| mode | frame (ms) | fps | x general | prepare (s) |\n|---|---|---|---|---|")
    for mode in (*MODES, "transfer"):
        o = out[mode]
        print(f"| {mode} | {o['frame_ms']:.1f} | {o['fps']:.2f} | {o['speed_vs_general']:.2f} | {o['prepare_s']:.2f} |")
    print(f"general / fixed-view = {out['general_over_fixed_view']:.2f} (issue target <= 3; paper 21-31)")
    print(f"transfer (T = I) vs general image: {out['transfer']['max_diff_vs_general']:.1e} of the largest value")
    print(json.dumps(out, sort_keys=True))
    if args.json:
        args.json.write_text(json.dumps(out, indent=2, sort_keys=True))


if __name__ == "__main__":
    main()
