"""Planning a 16-object scene with planner v2 (issue 16: ``/plan`` for a 16-object scene in under 200 ms).

    .venv/bin/python bench/plan_scene.py [--rows 64] [--repeats 5] [--json OUT.json]

Sixteen objects mixing every rule (Lambert on spheres and meshes, radial and general glossy lobes, an anisotropic
brushed metal, glossy shadows on meshes, edited materials) on a sample map (area-averaged to ``--rows``), planned at
epsilon = 0.01 with the development machine's cost constants. ``cold`` is the first plan in a fresh process (order
searches, Gaussian fits, SH-table band energies and K predictions all computed); ``warm`` the median of the next
``--repeats`` plans of the same scene (what a service answers once a scene's materials are known: every per-material
prediction is cached in-process). Prints a table and writes JSON; times depend on the machine's load.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from relight import costmodel, planning, resources
from relight.envmap import read_envmap, resample_latlong

MATERIALS = ["lambert:albedo=0.7", "phong:s=64", "phong:s=2000", "torrance-sparrow:alpha=0.3,fresnel=none",
             "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0", "lambert:albedo=0.5+phong:s=32", "kajiya-kay:s=16",
             "phong:s=8"]


def scene() -> planning.Scene:
    objs = []
    for k in range(16):
        o = {"name": f"o{k}", "size": 1.0, "distance": 6.0 + k, "material": MATERIALS[k % len(MATERIALS)],
             "view": [0.1 * (k % 4), 0.5, 1.0]}
        if k % 3 == 1:
            o["shape"] = "bunny" if k % 2 else "teapot"
        objs.append(o)
    return planning.scene_from_dict({"environment": "courtyard", "epsilon": 0.01, "objects": objs,
                                     "material_edits": ["o3"], "frame_budget_ms": 100.0})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    folder = resources.sample_envmaps()
    if folder is None:
        raise SystemExit("the sample environment maps (data/envmaps) are not installed")
    px = np.asarray(resample_latlong(read_envmap(folder / "courtyard.exr").pixels, args.rows), dtype=np.float64)
    cal = costmodel.default_calibration()
    sc = scene()
    t0 = time.perf_counter()
    p = planning.plan_scene(sc, px, calibration=cal)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        planning.plan_scene(sc, px, calibration=cal)
        warm.append(time.perf_counter() - t0)
    reps: dict[str, int] = {}
    for o in p.report.objects:
        for r in o.representations:
            reps[r.representation] = reps.get(r.representation, 0) + 1
    print("| objects | map | cold ms | warm ms (median) | representations |")
    print("|---|---|---|---|---|")
    print(f"| 16 | {args.rows} x {2 * args.rows} | {1e3 * cold:.0f} | {1e3 * statistics.median(warm):.0f} | "
          + ", ".join(f"{k} {v}" for k, v in sorted(reps.items())) + " |")
    out = {"cold_s": cold, "warm_s": warm, "representations": reps, "rows": args.rows,
           "jobs": len(p.report.jobs), "frame_ms": p.report.frame.predicted_ms if p.report.frame else None}
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
