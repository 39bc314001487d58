"""``relight bake`` rerun with nothing to do (issue 17, "Numbers": under 3 s for 5 maps x 2 materials).

Bakes the five maps of data/envmaps once with two materials (``--brdf ggx-ld --brdf phong:s=64``, ``--format
ktx2,sh``: a chain per map x material and one SH9 per map, fifteen items; ``--size`` small by default, since a
rerun's cost does not depend on it: it hashes each map's bytes and reads each item's JSON) and then times whole
``relight bake`` reruns of the same command, which must skip every item. Prints a markdown table and writes JSON
(``--json``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The two materials (``--brdf``): the engines' split-sum GGX lobe (each level's roughness) and a fixed Phong lobe.
MATERIALS = ("ggx-ld", "phong:s=64")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=16)
    ap.add_argument("--reruns", type=int, default=3)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    maps = sorted(str(p) for p in (ROOT / "data" / "envmaps").glob("*.exr"))
    relight = str(Path(sys.executable).with_name("relight"))
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [relight, "bake", *maps, "--target", "three", "--format", "ktx2,sh", "--size", str(args.size),
               *[a for m in MATERIALS for a in ("--brdf", m)], "--out", tmp, "--json"]
        t = time.perf_counter()
        first = subprocess.run(cmd, capture_output=True, text=True, check=True)
        t_first = time.perf_counter() - t
        assert json.loads(first.stdout)["failed"] == 0
        reruns = []
        for _ in range(args.reruns):
            t = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
            reruns.append(time.perf_counter() - t)
            rows = json.loads(proc.stdout)["items"]
            assert all(r["status"] == "skipped" for r in rows), "a rerun recomputed an item"
    items = (len(MATERIALS) + 1) * len(maps)
    result = {"maps": len(maps), "materials": list(MATERIALS), "items": items, "size": args.size,
              "first_seconds": t_first, "rerun_seconds": reruns}
    print("| maps | materials | items | first bake s | rerun s (each) | best rerun s |")
    print("|---|---|---|---|---|---|")
    print(f"| {len(maps)} | {len(MATERIALS)} | {items} | {t_first:.1f} | {', '.join(f'{s:.2f}' for s in reruns)} | "
          f"{min(reruns):.2f} |")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
