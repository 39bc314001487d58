"""Maps as users download them (issue 17, item 8): a 16384 x 8192 EXR ingested by streaming, its peak memory, and
its streamed SH to l = 256 against the full-resolution map's.

1. Writes a ``--width`` x ``--width / 2`` half-float EXR (ZIP): a smooth sky, a horizon band, random texture and a
   0.5-degree sun at 5e4 (held as three float16 planes while writing: 0.8 GB at 16k; this step is not measured).
2. A fresh process ingests it the way ``relight export`` / ``prefilter`` / ``bake`` do (``read_envmap``: streamed
   into its area-exact 2048-row downsample) and then streams its SH to ``--lmax`` from the full-resolution rows
   (``relight.envmap.stream.stream_latlong``); it reports its peak resident memory (``ru_maxrss``, the whole
   process: interpreter, libraries and OpenEXR's decode buffers included) and seconds.
3. A second fresh process decodes the whole map and projects it with ``relight.sh.project`` (the in-memory
   reference; several GB at 16k) and the two coefficient sets are compared: max |difference| / max |a_lm|.

Prints a markdown table and writes JSON (``--json``). The numbers the issue asks: peak < 2 GiB, SH within 1e-6.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

INGEST = """
import json, resource, sys, time
import numpy as np
from relight.envmap import read_envmap
from relight.envmap.stream import memory_bound, stream_latlong
path, lmax, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
t = time.perf_counter()
env = read_envmap(path)
t_read = time.perf_counter() - t
t = time.perf_counter()
s = stream_latlong(path, 64, lmax=lmax)
t_sh = time.perf_counter() - t
np.save(out, s.alm)
w = s.source_width
print(json.dumps({"rows": env.pixels.shape[0], "read_seconds": t_read, "sh_seconds": t_sh,
                  "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                  "memory_bound_bytes": max(memory_bound(w, 2048, max(1, (1 << 20) // w)),
                                            memory_bound(w, 64, max(1, (1 << 20) // w), lmax))}))
"""

REFERENCE = """
import json, resource, sys, time
import numpy as np
from relight import sh
from relight.envmap.exr import read_exr_layers
path, lmax, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
t = time.perf_counter()
px = np.maximum(read_exr_layers(path)[0][""], 0.0)
alm = sh.project(px, lmax)
np.save(out, alm)
print(json.dumps({"seconds": time.perf_counter() - t,
                  "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""


def write_map(path: Path, width: int) -> None:
    """The synthetic map of the module docstring, computed in row blocks into float16 planes."""
    import OpenEXR

    h = width // 2
    planes = [np.empty((h, width), dtype=np.float16) for _ in range(3)]
    rng = np.random.default_rng(7)
    phi = (np.arange(width) + 0.5) * 2 * np.pi / width
    sun_t, sun_p, sun_r = 0.9, 2.0, np.deg2rad(0.25)
    for y0 in range(0, h, 512):
        y1 = min(h, y0 + 512)
        theta = ((np.arange(y0, y1) + 0.5) * np.pi / h)[:, None]
        sky = 1.0 + 2.0 * np.cos(theta) ** 2 + 0.3 * np.sin(3 * phi)[None, :] * np.sin(theta)
        band = 4.0 * np.exp(-(((theta - np.pi / 2) / 0.05) ** 2))
        tex = rng.random((y1 - y0, width)) ** 4
        cosd = np.cos(theta) * np.cos(sun_t) + np.sin(theta) * np.sin(sun_t) * np.cos(phi[None, :] - sun_p)
        sun = np.where(np.arccos(np.clip(cosd, -1, 1)) < sun_r, 5.0e4, 0.0)
        base = np.where(theta < np.pi / 2, sky, 0.3 + tex) + band + sun
        for c, tint in enumerate((1.0, 0.9, 0.8)):
            planes[c][y0:y1] = (base * tint).astype(np.float16)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"R": planes[0], "G": planes[1], "B": planes[2]}) as exr:
        exr.write(str(path))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=16384)
    ap.add_argument("--lmax", type=int, default=256)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.exr"
        t = time.perf_counter()
        write_map(path, args.width)
        t_write = time.perf_counter() - t
        ing = subprocess.run([sys.executable, "-c", INGEST, str(path), str(args.lmax), str(Path(tmp) / "s.npy")],
                             capture_output=True, text=True, check=True, cwd=ROOT)
        ingest = json.loads(ing.stdout)
        ref = subprocess.run([sys.executable, "-c", REFERENCE, str(path), str(args.lmax), str(Path(tmp) / "r.npy")],
                             capture_output=True, text=True, check=True, cwd=ROOT)
        reference = json.loads(ref.stdout)
        a, b = np.load(Path(tmp) / "s.npy"), np.load(Path(tmp) / "r.npy")
        rel = float(np.max(np.abs(a - b)) / np.max(np.abs(b)))
        result = {"width": args.width, "height": args.width // 2, "lmax": args.lmax, "file_bytes": path.stat().st_size,
                  "write_seconds": t_write, "ingest": ingest, "reference": reference, "sh_max_rel_diff": rel}
    gib = 2.0**30
    print(f"| map | file | ingest peak RSS | bound (streaming buffers) | read s | SH l<={args.lmax} s | "
          "in-memory peak RSS | SH max rel diff |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| {args.width} x {args.width // 2} | {result['file_bytes'] / gib:.2f} GiB | "
          f"{ingest['peak_rss_bytes'] / gib:.2f} GiB | {ingest['memory_bound_bytes'] / gib:.2f} GiB | "
          f"{ingest['read_seconds']:.1f} | {ingest['sh_seconds']:.1f} | {reference['peak_rss_bytes'] / gib:.2f} GiB | "
          f"{rel:.1e} |")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
