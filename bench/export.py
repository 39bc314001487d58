"""``relight export`` against Filament's ``cmgen`` on the same GGX chain, side by side in one run (issue 17).

The chain: a 1024 x 512 map (default ``data/envmaps/city.exr``, a sun at 3.4e4 x the mean), 256^2 faces, the
5 levels cmgen 1.9.25 writes at that size (256 ... 16, perceptual roughness 0, 0.134, 0.293, 0.5, 1: the
quadratic lod mapping, which is relight's ``--target filament --levels 5``; the roughness cmgen prints per level
is parsed and checked). Both sides are measured against one reference: the angular brute force of the split-sum
GGX lobe (``relight.cap_convolution.brute_force``: the map's bilinear interpolant on a grid finer than the lobe, over
the whole sphere) at ``--texels`` random texels per level, the same directions for both.

cmgen's cube is rotated against relight's frame: its (default, mirrored) texel for OpenGL direction d shows the
map at relight's ``(d_z, d_y, -d_x)`` (a quarter turn about +Y; found by matching level 0 against the map sampled
under the 8 axis-preserving turns and mirrors about +Y, where this one alone is below 100 % error). The reference
is taken there.

Times are whole wall-clock seconds: cmgen's process (decode, equirect -> cube, mirror, filtering, EXR writes; it
has no switch to time the filtering alone, so the chain-only ratio below uses its whole process and flatters
relight by cmgen's decode and write time), relight's ``prefilter_chain`` call in-process (chain only), and the
whole ``relight export`` process (decode, chain, KTX2 + JSON writes). numba's compiled near sum is cached on disk
by a warm-up export before timing. Prints markdown tables and writes JSON (``--json``).

Two comparisons: (1) the issue's: each cmgen setting (its best is its most accurate, ``--ibl-samples=4096``)
against relight's cheapest ``--epsilon`` run at equal or lower error (``at_cmgen_error``; relight's epsilons go
up to 0.1 so that it can be as coarse as cmgen); (2) each relight run against cmgen's cheapest run at equal or
lower error, or, where cmgen never gets there, its most accurate run (a lower bound on cmgen's time).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FACES = ("px", "nx", "py", "ny", "pz", "nz")
#: cmgen's texel for OpenGL direction d shows relight's direction CMGEN_TURN @ d (module docstring).
CMGEN_TURN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
_LEVEL = re.compile(r"Level (\d+), roughness = [0-9.e-]+, roughness \(perceptual\) = ([0-9.e-]+)")


def _rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    from relight.conventions import LUMINANCE_WEIGHTS

    la, lb = a @ LUMINANCE_WEIGHTS, b @ LUMINANCE_WEIGHTS
    return float(np.sqrt(np.mean((la - lb) ** 2) / np.mean(lb**2)))


def _texel_values(faces: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Values of a (6, S, S, 3) OpenGL-ordered cube at texel-centre directions (nearest texel)."""
    from relight.envmap.cubemap import _dirs_to_face_uv

    s = faces.shape[1]
    face, u, v = _dirs_to_face_uv(dirs[:, 0], dirs[:, 1], dirs[:, 2])
    col = np.clip((u * s).astype(int), 0, s - 1)
    row = np.clip((v * s).astype(int), 0, s - 1)
    return np.asarray(faces[face, row, col], dtype=np.float64)


def run_cmgen(src: Path, size: int, samples: int, tmp: Path) -> dict[str, Any]:
    out = tmp / f"cmgen_{samples}"
    t = time.perf_counter()
    proc = subprocess.run(["cmgen", "--format=exr", f"--size={size}", f"--ibl-ld={out}",
                           f"--ibl-samples={samples}", str(src)], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        raise SystemExit(f"cmgen failed: {proc.stderr[-2000:]}")
    rough = {int(m.group(1)): float(m.group(2)) for m in _LEVEL.finditer(proc.stdout)}
    from relight.envmap.exr import read_exr_layers

    levels = []
    for lv in sorted(rough):
        faces = np.stack([read_exr_layers(out / src.stem / f"m{lv}_{f}.exr")[0][""] for f in FACES])
        levels.append({"level": lv, "roughness": rough[lv], "faces": faces})
    return {"seconds": wall, "levels": levels}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", default=str(ROOT / "data" / "envmaps" / "city.exr"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--samples", default="256,1024,4096", help="cmgen --ibl-samples values")
    ap.add_argument("--epsilons", default="2.5e-5,1e-3,1e-2,3e-2,1e-1", help="relight --epsilon values")
    ap.add_argument("--texels", type=int, default=1200, help="random reference texels per level")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    if shutil.which("cmgen") is None:
        raise SystemExit("cmgen is not installed (Debian: apt-get install libfilament-tools)")

    from relight.brdf.splitsum import GGXSplitSum
    from relight.cap_convolution import brute_force
    from relight.cube_chain import prefilter_chain
    from relight.envmap import cube_face_dirs, read_envmap
    from relight.envmap.exr import write_exr

    pixels = np.asarray(read_envmap(args.map).pixels, dtype=np.float64)
    rng = np.random.default_rng(42)
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmpname:
        tmp = Path(tmpname)
        src = tmp / "input.exr"  # cmgen cannot read DWAB: the same pixels as ZIP
        write_exr(src, pixels.astype(np.float32), compression="zip")
        cm_runs = {int(n): run_cmgen(src, args.size, int(n), tmp) for n in args.samples.split(",")}
        first = next(iter(cm_runs.values()))["levels"]
        n_levels = len(first)
        rough = [lv["roughness"] for lv in first]
        # reference directions per level: random texels of cmgen's cube, in relight's frame
        refs = []
        for i in range(1, n_levels):
            s = args.size >> i
            d = cube_face_dirs(s).reshape(-1, 3)
            pick = rng.choice(d.shape[0], size=min(args.texels, d.shape[0]), replace=False)
            cm_dirs = d[pick]
            dirs = cm_dirs @ CMGEN_TURN.T
            lobe = GGXSplitSum(rough[i])
            refs.append({"pick": pick, "dirs": dirs, "ref": brute_force(pixels, lobe, dirs)})

        for n, run in cm_runs.items():
            errs = [_rel_rms(run["levels"][i]["faces"].reshape(-1, 3)[r["pick"]].astype(np.float64), r["ref"])
                    for i, r in zip(range(1, n_levels), refs, strict=True)]
            rows.append({"tool": "cmgen", "setting": f"--ibl-samples={n}", "process_s": run["seconds"],
                         "chain_s": None, "level_rms": errs, "max_rms": max(errs)})

        warm = tmp / "warm.ktx2"
        cmd = [str(Path(sys.executable).with_name("relight")), "export", args.map, "--target", "filament",
               "--levels", str(n_levels), "--size", str(args.size), "--out", str(warm)]
        subprocess.run(cmd, check=True, capture_output=True)  # numba's on-disk cache
        for eps in (float(e) for e in args.epsilons.split(",")):
            t = time.perf_counter()
            chain = prefilter_chain(pixels, target="filament", size=args.size, levels=n_levels, epsilon=eps)
            chain_s = time.perf_counter() - t
            assert np.allclose([lv.roughness for lv in chain.levels], rough, atol=1e-3), "level roughness differs"
            t = time.perf_counter()
            subprocess.run(cmd[:-2] + ["--epsilon", str(eps), "--out", str(tmp / "r.ktx2")], check=True,
                           capture_output=True)
            process_s = time.perf_counter() - t
            errs = [_rel_rms(_texel_values(chain.levels[i].faces, r["dirs"]), r["ref"])
                    for i, r in zip(range(1, n_levels), refs, strict=True)]
            rows.append({"tool": "relight", "setting": f"--epsilon={eps:g}", "process_s": process_s,
                         "chain_s": chain_s, "level_rms": errs, "max_rms": max(errs)})

    rel = [r for r in rows if r["tool"] == "relight"]
    cms = [r for r in rows if r["tool"] == "cmgen"]
    comparisons = []
    for r in rel:
        # cmgen's cheapest run at equal or lower error; none: its most accurate run (a lower bound on its time)
        ok = [c for c in cms if c["max_rms"] <= r["max_rms"]]
        c = min(ok, key=lambda x: x["process_s"]) if ok else min(cms, key=lambda x: x["max_rms"])
        comparisons.append({"relight": r["setting"], "cmgen": c["setting"], "cmgen_reaches_equal_error": bool(ok),
                            "chain_speedup": c["process_s"] / r["chain_s"],
                            "process_speedup": c["process_s"] / r["process_s"]})
    print(f"map {args.map}, {args.size}^2 faces, {n_levels} levels, roughness "
          + ", ".join(f"{x:.3f}" for x in rough) + f"; reference: brute force at {args.texels} texels per level\n")
    print("| tool | setting | process s | chain s | max rel. RMS | per level (1..) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        chain = "-" if r["chain_s"] is None else f"{r['chain_s']:.2f}"
        levels = ", ".join(f"{e:.2%}" for e in r["level_rms"])
        print(f"| {r['tool']} | {r['setting']} | {r['process_s']:.2f} | {chain} | {r['max_rms']:.2%} | {levels} |")
    # the definition: cmgen at each setting (its best: the most accurate) against relight's cheapest run at
    # equal or lower error; none: relight's most accurate run that is still above it (flagged)
    at_cmgen = []
    for c in cms:
        ok = [r for r in rel if r["max_rms"] <= c["max_rms"]]
        r = min(ok, key=lambda x: x["process_s"]) if ok else min(rel, key=lambda x: x["max_rms"])
        at_cmgen.append({"cmgen": c["setting"], "cmgen_max_rms": c["max_rms"], "relight": r["setting"],
                         "relight_max_rms": r["max_rms"], "relight_reaches_equal_error": bool(ok),
                         "chain_speedup": c["process_s"] / r["chain_s"],
                         "process_speedup": c["process_s"] / r["process_s"]})
    print("\n| cmgen | its max RMS | relight at equal or lower error | its max RMS | chain speed-up | "
          "process speed-up |")
    print("|---|---|---|---|---|---|")
    for a in at_cmgen:
        flag = "" if a["relight_reaches_equal_error"] else " (not reached)"
        print(f"| {a['cmgen']} | {a['cmgen_max_rms']:.2%} | {a['relight']}{flag} | {a['relight_max_rms']:.2%} | "
              f"{a['chain_speedup']:.1f}x | {a['process_speedup']:.1f}x |")
    print("\n| relight | cmgen at equal error | reached | chain speed-up | process speed-up |")
    print("|---|---|---|---|---|")
    for c in comparisons:
        print(f"| {c['relight']} | {c['cmgen']} | {'yes' if c['cmgen_reaches_equal_error'] else 'no (lower bound)'}"
              f" | {c['chain_speedup']:.1f}x | {c['process_speedup']:.1f}x |")
    result = {"map": args.map, "size": args.size, "levels": n_levels, "roughness": rough, "texels": args.texels,
              "rows": rows, "comparisons": comparisons, "at_cmgen_error": at_cmgen}
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
