"""Start-up cost of a small ``relight prefilter`` job, as whole processes (issue 11, item 8).

A small job (Phong s = 8 at epsilon = 0.01 on a 1024 x 512 sample map: F = 6, a 60 x 120 output) computes for a
few milliseconds; the rest of its process is the interpreter and imports. Measured side by side in one run, each
a median of ``--repeat`` interleaved runs (so a load change on the machine hits every variant alike):

* ``python``: the interpreter alone (``python -c pass``);
* ``import floor``: the interpreter importing what the job cannot do without (NumPy, ducc0, OpenEXR);
* ``relight prefilter``: the command of this checkout;
* ``relight prefilter @REV`` (``--baseline REV``): the same command from another commit, run from a temporary
  ``git worktree`` through its own ``tools/pkgview.py`` layout (so it imports that commit's code only).

Then one ``python -X importtime`` run of this checkout's command lists where its import time goes. Prints a
markdown table and writes JSON (``--json``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
JOB = ["prefilter", "{map}", "--brdf", "phong:s=8", "--epsilon", "0.01", "--out", "{out}"]
FLOOR = "import numpy, ducc0, OpenEXR"
_IMPORTTIME = re.compile(r"import time:\s+(\d+) \|\s+(\d+) \| ( *)(\S+)")


def _env(pythonpath: str | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONSTARTUP")}
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    return env


def _wall(cmd: list[str], env: dict[str, str], cwd: Path) -> float:
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return dt


def _baseline(rev: str, tmp: Path) -> str:
    """A worktree of ``rev`` and its installed layout (tools/pkgview.py); the PYTHONPATH that imports it."""
    tree = tmp / "baseline"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(tree), rev], check=True)
    view = tree / "build" / "pkgview"
    subprocess.run([sys.executable, str(tree / "tools" / "pkgview.py"), str(view)], check=True, capture_output=True)
    return str(view)


def import_breakdown(job: list[str], cwd: Path, top: int) -> dict[str, Any]:
    """Total import time of one run and its largest top-level imports (``-X importtime``, microseconds)."""
    proc = subprocess.run([sys.executable, "-X", "importtime", "-m", "relight.cli", *job], env=_env(), cwd=cwd,
                          capture_output=True, text=True, check=True)
    tops: list[tuple[str, int]] = []
    for m in _IMPORTTIME.finditer(proc.stderr):
        if not m.group(3):  # no indent: imported by the top level (the command's own code)
            tops.append((m.group(4), int(m.group(2))))
    total = sum(us for _, us in tops)
    largest = sorted(tops, key=lambda t: -t[1])[:top]
    return {"total_s": total / 1e6, "largest": [{"module": n, "seconds": us / 1e6} for n, us in largest]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", default=str(ROOT / "data" / "envmaps" / "studio.exr"))
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--baseline", metavar="REV", help="also time the command of this commit (e.g. a3c71f0~1)")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "startup.json"))
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="relight-startup-") as tmp_name:
        tmp = Path(tmp_name)
        job = [a.format(map=Path(args.map).resolve(), out=tmp / "out.exr") for a in JOB]
        variants: dict[str, tuple[list[str], dict[str, str]]] = {
            "python": ([sys.executable, "-c", "pass"], _env()),
            "import floor": ([sys.executable, "-c", FLOOR], _env()),
            "relight prefilter": ([sys.executable, "-m", "relight.cli", *job], _env()),
        }
        if args.baseline:
            variants[f"relight prefilter @{args.baseline}"] = ([sys.executable, "-m", "relight.cli", *job],
                                                                 _env(_baseline(args.baseline, tmp)))
        try:
            for cmd, env in variants.values():  # warm the file cache and .pyc files once
                _wall(cmd, env, tmp)
            times: dict[str, list[float]] = {name: [] for name in variants}
            for _ in range(args.repeat):
                for name, (cmd, env) in variants.items():
                    times[name].append(_wall(cmd, env, tmp))
            breakdown = import_breakdown(job, tmp, top=8)
        finally:
            if args.baseline:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tmp / "baseline")],
                               check=False)

    med = {name: statistics.median(ts) for name, ts in times.items()}
    floor = med["import floor"]
    print(f"`relight {' '.join(JOB[:1] + JOB[2:6])}` on {Path(args.map).name}, median of {args.repeat} runs\n")
    print("| process | median s | min s | / import floor |")
    print("|---|---:|---:|---:|")
    for name, ts in times.items():
        print(f"| {name} | {med[name]:.3f} | {min(ts):.3f} | {med[name] / floor:.2f} |")
    if args.baseline:
        base = med[f"relight prefilter @{args.baseline}"]
        print(f"\nspeed-up over {args.baseline}: {base / med['relight prefilter']:.2f}x (same run)")
    print(f"\n`-X importtime` of this checkout's command: {breakdown['total_s']:.3f} s of imports; largest:")
    for row in breakdown["largest"]:
        print(f"  {row['module']:<40} {row['seconds']:.3f} s")

    out = {"job": JOB, "map": Path(args.map).name, "repeat": args.repeat, "median_s": med,
           "all_s": times, "import_floor_s": floor, "imports": breakdown}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
