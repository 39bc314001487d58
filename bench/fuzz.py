"""Coverage-guided fuzzing (atheris, libFuzzer) of every parser that sees a client's bytes (issue 12, item 8).

    PYTHONPATH=. python3 bench/fuzz.py [--seconds 600] [--targets exr,rgbe,...] [--out bench/results/fuzz.json]

The targets and their rule (return, or raise what the service answers with a 422) are in
``tests/fuzz/targets.py``. Each target runs in its own process for ``--seconds``, from a corpus seeded with small
valid files and kept between runs under ``bench/results/fuzz-corpus/<target>/`` (so a second run goes on where
the first stopped); the parser modules are instrumented for coverage (``atheris.instrument_imports``). A crash
stops that target's run; its input is copied to ``tests/fuzz/crashes/<target>/``, where the test suite replays it
(``tests/fuzz/test_fuzz.py``) until the parser is fixed. Prints a table (executions, coverage, corpus size,
crashes) and writes JSON; the README's reliability section records the hours fuzzed and the crashes found.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
CRASHES = REPO / "tests" / "fuzz" / "crashes"
#: Modules whose code atheris instruments (coverage feedback): the parsers and what they call.
INSTRUMENTED = ("relight.envmap", "relight.envmap.headers", "relight.envmap.formats", "relight.envmap.exr",
                "relight.envmap.exr_header", "relight.envmap.rgbe", "relight.envmap.ldr",
                "relight.envmap.environment", "relight.envmap.cubemap", "relight.mesh", "relight.mesh.obj",
                "relight.mesh.gltf", "relight.mesh.load", "relight.mesh.model", "relight.mesh.defects",
                "relight.brdf.spec", "relight.brdf.params", "relight.brdf.measured", "relight.worker.specs",
                "relight.contract.scenes", "relight.contract.brdfs")
#: libFuzzer limits: one input may take this long and the process this much memory before it counts as a crash.
PER_INPUT_TIMEOUT_S = 20
RSS_LIMIT_MB = 3072


def worker(target_name: str, seconds: float, corpus: Path, artifacts: Path) -> None:
    """One target under atheris (runs in its own process: libFuzzer exits the process when it is done)."""
    import importlib

    import atheris

    sys.path.insert(0, str(REPO))
    with atheris.instrument_imports(include=["relight"]):
        for mod in INSTRUMENTED:
            try:
                importlib.import_module(mod)
            except ModuleNotFoundError:  # a module of the list that this checkout does not have (renamed)
                continue
    from tests.fuzz.targets import TARGETS

    target = TARGETS[target_name]
    max_len = min(1 << 16, 2 * max(len(s) for s in target.seeds()))

    def one_input(data: bytes) -> None:
        target.run(data)

    args = [sys.argv[0], str(corpus), f"-max_total_time={int(seconds)}", f"-timeout={PER_INPUT_TIMEOUT_S}",
            f"-rss_limit_mb={RSS_LIMIT_MB}", f"-max_len={max_len}", f"-artifact_prefix={artifacts}/",
            "-print_final_stats=1"]
    atheris.Setup(args, one_input)
    atheris.Fuzz()


def seed_corpus(target_name: str, corpus: Path) -> None:
    sys.path.insert(0, str(REPO))
    from tests.fuzz.targets import TARGETS

    corpus.mkdir(parents=True, exist_ok=True)
    for i, seed in enumerate(TARGETS[target_name].seeds()):
        (corpus / f"seed-{i:02d}").write_bytes(seed)


def run_target(name: str, seconds: float, corpus_root: Path) -> dict[str, Any]:
    corpus = corpus_root / name
    seed_corpus(name, corpus)
    with tempfile.TemporaryDirectory() as artifacts:
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, __file__, "--worker", name, "--seconds", str(seconds), "--corpus",
                               str(corpus), "--artifacts", artifacts], capture_output=True, text=True,
                              timeout=seconds + 300, env={**os.environ, "PYTHONPATH": str(REPO)})
        wall = time.monotonic() - t0
        out = proc.stdout + proc.stderr
        found = sorted(Path(artifacts).iterdir())
        kept = []
        for f in found:
            dest = CRASHES / name / f.name
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, dest)
            kept.append(str(dest.relative_to(REPO)))
    stat = {k: int(v) for k, v in re.findall(r"stat::(\w+):\s+(\d+)", out)}
    cov = re.findall(r"cov: (\d+)", out)
    return {
        "target": name, "seconds": round(wall, 1), "executions": stat.get("number_of_executed_units", 0),
        "peak_rss_mb": stat.get("peak_rss_mb", 0), "coverage": int(cov[-1]) if cov else 0,
        "corpus": len(list(corpus.iterdir())), "crashes": kept, "exit_code": proc.returncode,
        "tail": out[-3000:] if (proc.returncode != 0 or kept) else "",
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=600.0, help="fuzzing time per target")
    ap.add_argument("--targets", default="", help="comma-separated (default: all)")
    ap.add_argument("--corpus", type=Path, default=REPO / "bench" / "results" / "fuzz-corpus")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "fuzz.json")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--artifacts", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker, args.seconds, args.corpus, args.artifacts)
        return 0
    sys.path.insert(0, str(REPO))
    from tests.fuzz.targets import TARGETS

    names = [n for n in args.targets.split(",") if n] or list(TARGETS)
    unknown = set(names) - set(TARGETS)
    if unknown:
        ap.error(f"unknown targets {sorted(unknown)} (known: {', '.join(TARGETS)})")
    rows = []
    print("| target | seconds | executions | coverage | corpus | peak RSS MB | crashes |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        r = run_target(name, args.seconds, args.corpus)
        rows.append(r)
        print(f"| {name} | {r['seconds']} | {r['executions']} | {r['coverage']} | {r['corpus']} | "
              f"{r['peak_rss_mb']} | {len(r['crashes'])} |", flush=True)
        if r["tail"]:
            print(r["tail"], file=sys.stderr)
    total_h = sum(r["seconds"] for r in rows) / 3600
    print(f"\n{total_h:.2f} hours fuzzed, {sum(len(r['crashes']) for r in rows)} crashes")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"seconds_per_target": args.seconds, "hours": total_h, "targets": rows},
                                   indent=2))
    failed = [r for r in rows if r["crashes"] or r["exit_code"] != 0 or r["executions"] == 0]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
