"""Issue 13's timing targets: visibility + diffuse transfer of the ~100K-vertex bunny at 1024 rays, order F = 3.

Measured in one run on this machine:

* ``raycast``: Embree occlusion throughput alone (``relight.visibility.free_rays``: direction-major batches of
  ``RayCaster.occluded``) on the first 4096 vertices' rays (Mrays/s);
* ``serial``: ``relight.visibility.compute_transfer(kind="diffuse_transfer")`` for the whole mesh (visibility,
  ambient occlusion and the transfer vector from one ray pass), one process: seconds and Mrays/s — target < 60 s,
  >= 2 Mrays/s;
* ``blocks x N``: the same blocks (``transfer_block``) fanned out over N worker processes, then ``combine`` — how
  the job scales across Dask workers by vertex blocks; the result must equal the serial one exactly;
* ``frames``: per-frame cost of the viewer's shading on the same mesh through ``relight.gl.prt`` (moderngl on
  EGL; Mesa llvmpipe here, no GPU): SH-transfer shadows (16 float16 values fetched per vertex) against unshadowed
  irradiance (the SH of the normal evaluated per vertex) and AO x irradiance, frames interleaved, each finished
  before the clock stops; the ratio shadowed / unshadowed of the medians (target <= 1.5).

Prints a markdown table and writes JSON (``--json PATH``). ``--quick``: the 1839-vertex bunny. The machine's load
average is recorded: on a shared 2-core machine the seconds scale with it, the ratios much less.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from relight.mesh import TriangleMesh, sample_mesh
from relight.raycast import RayCaster, ray_offset
from relight.visibility import (
    Block,
    TransferSettings,
    block_ranges,
    combine,
    compute_transfer,
    directions,
    free_rays,
    transfer_block,
)

_MESH: TriangleMesh | None = None


def _init(mesh: TriangleMesh) -> None:
    global _MESH
    _MESH = mesh


def _work(args: tuple[int, int, TransferSettings]) -> Block:
    assert _MESH is not None
    return transfer_block(_MESH, args[0], args[1], args[2])


def frame_costs(mesh: TriangleMesh, transfer: np.ndarray, ao: np.ndarray, order: int, size: int,
                frames: int) -> dict[str, Any]:
    """Median seconds per frame of each shading mode (module docstring) and the shadowed / unshadowed ratio."""
    from relight.gl.prt import PrtRenderer
    from relight.mesh_render import lighting_coefficients

    rng = np.random.default_rng(0)
    lighting = lighting_coefficients(1.0 + rng.random((16, 32, 3)), order)
    r = PrtRenderer(mesh, transfer=transfer, ao=ao, order=order)
    try:
        times = r.frame_seconds(["unshadowed", "ao", "transfer"], np.array([0.3, 0.4, 1.0]), lighting, size,
                                frames)
    finally:
        r.release()
    med = {m: float(np.median(t)) for m, t in times.items()}
    info = r.ctx.info
    return {"size": size, "frames": frames, "median_seconds": med,
            "ratio_shadowed_to_unshadowed": med["transfer"] / med["unshadowed"],
            "ratio_ao_to_unshadowed": med["ao"] / med["unshadowed"],
            "renderer": str(info.get("GL_RENDERER")), "target": 1.5}


def run(mesh_name: str, rays: int, order: int, workers: int, size: int = 512, frames: int = 20) -> dict[str, Any]:
    t0 = time.perf_counter()
    mesh = sample_mesh(mesh_name)
    load_s = time.perf_counter() - t0
    settings = TransferSettings(order=order, rays=rays, kind="diffuse_transfer")
    # ray casting alone
    caster = RayCaster(mesh.positions, mesh.faces)
    n = min(mesh.n_vertices, 4096)
    t0 = time.perf_counter()
    free_rays(caster, mesh.positions[:n], mesh.normals[:n], directions(rays), ray_offset(mesh.positions))
    cast_s = time.perf_counter() - t0
    # the whole computation, one process
    res = compute_transfer(mesh, settings)
    serial_s = float(res.manifest["seconds"])
    total_rays = mesh.n_vertices * rays
    # the same blocks over worker processes
    ranges = block_ranges(mesh.n_vertices, settings.block)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers, initializer=_init, initargs=(mesh,)) as pool:
        blocks = list(pool.map(_work, [(a, b, settings) for a, b in ranges]))
    arrays = combine(blocks, mesh.n_vertices)
    parallel_s = time.perf_counter() - t0
    same = all(np.array_equal(arrays[k].astype(np.float32), res.arrays[k]) for k in res.arrays)
    frame = frame_costs(mesh, res.arrays["transfer"], res.arrays["ao"], order, size, frames)
    return {
        "frames": frame,
        "mesh": mesh_name, "vertices": mesh.n_vertices, "faces": mesh.n_faces, "rays_per_vertex": rays,
        "order": order, "load_seconds": load_s,
        "raycast": {"rays": n * rays, "seconds": cast_s, "mrays_per_second": n * rays / cast_s / 1e6},
        "serial": {"seconds": serial_s, "mrays_per_second": total_rays / serial_s / 1e6},
        "parallel": {"workers": workers, "blocks": len(ranges), "seconds": parallel_s,
                     "mrays_per_second": total_rays / parallel_s / 1e6, "speedup": serial_s / parallel_s,
                     "identical_to_serial": same},
        "monte_carlo_error_rms": res.manifest["monte_carlo_error_rms"],
        "target": {"seconds": 60.0, "mrays_per_second": 2.0, "met": serial_s < 60.0},
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "load_average": os.getloadavg()},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the 1839-vertex bunny instead of bunny-100k")
    ap.add_argument("--rays", type=int, default=1024)
    ap.add_argument("--order", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--size", type=int, default=512, help="frame size (pixels) of the shading cost")
    ap.add_argument("--frames", type=int, default=20, help="frames per shading mode")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    r = run("bunny" if args.quick else "bunny-100k", args.rays, args.order, args.workers, args.size, args.frames)
    print(f"{r['mesh']}: {r['vertices']} vertices, {r['faces']} triangles, {r['rays_per_vertex']} rays/vertex, "
          f"F = {r['order']} (load {r['load_seconds']:.1f} s; load average {r['machine']['load_average'][0]:.1f} "
          f"on {r['machine']['cpus']} CPUs)\n")
    print("| stage | rays | seconds | Mrays/s |")
    print("|---|---:|---:|---:|")
    print(f"| Embree occlusion only | {r['raycast']['rays']:,} | {r['raycast']['seconds']:.2f} | "
          f"{r['raycast']['mrays_per_second']:.2f} |")
    total = r["vertices"] * r["rays_per_vertex"]
    print(f"| visibility + AO + diffuse transfer, 1 process | {total:,} | {r['serial']['seconds']:.2f} | "
          f"{r['serial']['mrays_per_second']:.2f} |")
    p = r["parallel"]
    print(f"| same, {p['blocks']} blocks over {p['workers']} processes | {total:,} | {p['seconds']:.2f} | "
          f"{p['mrays_per_second']:.2f} |")
    print(f"\ntarget < 60 s: {'met' if r['target']['met'] else 'NOT met'}; parallel speed-up "
          f"{p['speedup']:.2f}x, identical to serial: {p['identical_to_serial']}")
    print("Monte Carlo error (RMS over vertices): " + ", ".join(
        f"{k} {v:.3g}" for k, v in r["monte_carlo_error_rms"].items()))
    f = r["frames"]
    print(f"\n| shading ({f['size']} x {f['size']}, {f['renderer']}) | ms per frame (median of {f['frames']}) |")
    print("|---|---:|")
    for mode, label in (("unshadowed", "unshadowed irradiance"), ("ao", "AO x irradiance"),
                        ("transfer", "SH-transfer shadows")):
        print(f"| {label} | {1e3 * f['median_seconds'][mode]:.2f} |")
    print(f"\nshadowed / unshadowed: {f['ratio_shadowed_to_unshadowed']:.2f} (target <= {f['target']}); "
          f"AO / unshadowed: {f['ratio_ao_to_unshadowed']:.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(r, fh, indent=2)


if __name__ == "__main__":
    main()
