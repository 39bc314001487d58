"""Service subcommands of the ``relight`` CLI (registered by ``relight.cli`` through ``register``).

    relight serve [--host H] [--port P] [--data DIR]          server + embedded Dask cluster; prints the URL
    relight upload ENVMAP [--server URL]
    relight submit ENVMAP --brdf SPEC [--epsilon E | --order F] [--size S] [--wait] [--out SHRM.exr]
    relight jobs [--state S]
    relight worker --scheduler tcp://host:8786                a Dask worker (nanny) with relight importable

``--server`` defaults to ``$RELIGHT_SERVER`` or http://127.0.0.1:8000; ``--api-key`` to ``$RELIGHT_API_KEY``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
from pathlib import Path
from typing import Any

from relight.client.errors import RelightError

_DIGEST = re.compile(r"^[0-9a-f]{64}$")


def _default_preload() -> Path | None:
    import relight

    path = Path(relight.__file__).resolve().parent.parent / "data" / "envmaps"
    return path if path.is_dir() else None


def _client(args: argparse.Namespace) -> Any:
    from relight.client.sdk import RelightClient

    return RelightClient(args.server, api_key=args.api_key, timeout=args.timeout)


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--server", default=os.environ.get("RELIGHT_SERVER", "http://127.0.0.1:8000"),
                   help="service URL (default $RELIGHT_SERVER or http://127.0.0.1:8000)")
    p.add_argument("--api-key", default=os.environ.get("RELIGHT_API_KEY"), help="default $RELIGHT_API_KEY")
    p.add_argument("--timeout", type=float, default=120.0, help="seconds per HTTP request")
    p.add_argument("--json", action="store_true", help="print JSON")


# -------------------------------------------------------------------------------------------------- commands
def cmd_serve(args: argparse.Namespace) -> int:
    from relight.server.config import Settings
    from relight.server.run import serve

    overrides: dict[str, Any] = {}
    if args.data is not None:
        overrides["data_dir"] = Path(args.data)
    if args.workers is not None:
        overrides["n_workers"] = args.workers
    if args.scheduler is not None:
        overrides["scheduler"] = args.scheduler
    if args.no_preload:
        overrides["preload_dir"] = None
    elif args.preload is not None:
        overrides["preload_dir"] = Path(args.preload)
    elif "RELIGHT_PRELOAD_DIR" not in os.environ:
        overrides["preload_dir"] = _default_preload()
    serve(Settings(**overrides), args.host, args.port)
    return 0


def cmd_upload(args: argparse.Namespace) -> int:
    with _client(args) as c:
        env = c.upload_envmap(args.envmap, name=args.name)
    if args.json:
        print(env.model_dump_json(indent=2))
    else:
        print(f"{env.id}  {env.width}x{env.height} {env.format}  max {max(env.max):.4g}  "
              f"negatives clamped {env.negatives_clamped}")
    return 0


def _brdf_arg(text: str) -> Any:
    p = Path(text)
    if text.endswith(".json") and p.is_file():
        return json.loads(p.read_text())
    return text


def cmd_submit(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with _client(args) as c:
        envmap = args.envmap if _DIGEST.match(args.envmap) and not Path(args.envmap).exists() else \
            c.upload_envmap(args.envmap).id
        job = c.submit(envmap, _brdf_arg(args.brdf), epsilon=args.epsilon, order=args.order, p_order=args.p_order,
                       size=args.size)
        if not (args.wait or args.out):
            print(job.model_dump_json(indent=2) if args.json else f"{job.id}  {job.state}")
            return 0
        if not job.state.terminal:
            with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                          TimeElapsedColumn(), transient=True) as bar:
                task = bar.add_task(f"job {job.id[:12]} queued", total=1.0)

                def update(j: Any) -> None:
                    bar.update(task, completed=j.progress, description=f"job {j.id[:12]} {j.state}: {j.stage or ''}")

                job = c.wait(job.id, timeout=args.wait_timeout, on_update=update)
        elif job.state != "succeeded":
            from relight.client.errors import JobFailed

            raise JobFailed(job)
        if args.out:
            name = "coefficients.bin" if args.out.endswith(".bin") else "coefficients.exr"
            Path(args.out).write_bytes(c.download(job.id, name))
        if args.json:
            print(job.model_dump_json(indent=2))
        else:
            m = job.measured
            took = f"{m.seconds:.3f} s" if m and m.seconds is not None else "cached"
            rms = f", predicted relative RMS {m.rms_error:.3g}" if m and m.rms_error is not None else ""
            print(f"{job.id}  {job.state} ({took}{rms})" + (f"  -> {args.out}" if args.out else ""))
    return 0


def cmd_jobs(args: argparse.Namespace) -> int:
    with _client(args) as c:
        jobs = c.list_jobs(args.state, args.limit)
    if args.json:
        print(json.dumps([j.model_dump(mode="json") for j in jobs], indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table("id", "state", "stage", "progress", "brdf", "created")
    for j in jobs:
        table.add_row(j.id[:16], j.state.value, j.stage or "", f"{100 * j.progress:.0f}%",
                      str(j.brdf_spec.get("kind", "")), j.created_at.strftime("%Y-%m-%d %H:%M:%S"))
    Console().print(table)
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    from relight.worker.run import run_worker

    run_worker(args.scheduler, nthreads=args.nthreads, name=args.name, memory_limit=args.memory_limit,
               nanny=not args.no_nanny, host=args.host)
    return 0


def _guard(fn: Any) -> Any:
    """Client errors are RelightErrors: relight.cli prints them on one line (exit status 2)."""

    def run(args: argparse.Namespace) -> int:
        try:
            code: int = fn(args)
            return code
        except RelightError:
            raise
        except KeyboardInterrupt:
            return 130

    return run


def register(sub: Any) -> None:
    p = sub.add_parser("serve", help="run the HTTP service with an embedded Dask cluster")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=8000, help="0 picks a free port (the URL is printed)")
    p.add_argument("--data", help="data directory (database, blobs); default $RELIGHT_DATA_DIR or ./relight-data")
    p.add_argument("--workers", type=int, help="embedded cluster worker processes (default 2)")
    p.add_argument("--scheduler", help="connect to this Dask scheduler instead of starting a local cluster")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--preload", help="directory of environment maps to ingest at start-up (default: the samples)")
    g.add_argument("--no-preload", action="store_true", help="do not ingest the sample maps")
    p.set_defaults(func=_guard(cmd_serve))

    p = sub.add_parser("upload", help="upload an environment map to the service")
    p.add_argument("envmap")
    p.add_argument("--name")
    _add_common(p)
    p.set_defaults(func=_guard(cmd_upload))

    p = sub.add_parser("submit", help="submit a prefiltering job to the service")
    p.add_argument("envmap", help="a file (uploaded first) or an environment-map id")
    p.add_argument("--brdf", required=True, help="phong:s=32, a JSON spec file, or a BRDF id")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--epsilon", type=float)
    g.add_argument("--order", type=int)
    p.add_argument("--p-order", type=int, help="view order P for SHRMs (with --order)")
    p.add_argument("--size", type=int)
    p.add_argument("--wait", action="store_true", help="follow progress until the job ends")
    p.add_argument("--wait-timeout", type=float, default=None)
    p.add_argument("--out", help="download the result here (.exr: coefficients.exr, .bin: float16 texture)")
    _add_common(p)
    p.set_defaults(func=_guard(cmd_submit))

    p = sub.add_parser("jobs", help="list jobs on the service")
    p.add_argument("--state", choices=["queued", "running", "succeeded", "failed", "cancelled"])
    p.add_argument("--limit", type=int, default=50)
    _add_common(p)
    p.set_defaults(func=_guard(cmd_jobs))

    p = sub.add_parser("worker", help="run a Dask worker for the service (scale-out)")
    p.add_argument("--scheduler", required=True, help="tcp://host:8786")
    p.add_argument("--nthreads", type=int, default=1)
    p.add_argument("--name")
    p.add_argument("--memory-limit", default="auto")
    p.add_argument("--host", default=None, help="interface to listen on (default: Dask's choice)")
    p.add_argument("--no-nanny", action="store_true", help="no supervising nanny (the worker is not restarted)")
    p.set_defaults(func=_guard(cmd_worker))
