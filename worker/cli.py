"""``relight worker``: a Dask worker for an existing scheduler (scale-out), registered through the
``relight.commands`` entry point group; ``relight.cli`` loads it.

    relight worker --scheduler tcp://host:8786 [--nthreads N] [--name NAME] [--memory-limit M] [--host H] [--no-nanny]
    relight store check DATA_DIR [--repair]      (scrub the blob store: relight.worker.store_check)

Importing this module costs nothing beyond argparse: Dask loads when the command runs.
"""

from __future__ import annotations

import argparse
from typing import Any


def cmd_worker(args: argparse.Namespace) -> int:
    from relight.worker.run import run_worker

    try:
        run_worker(args.scheduler, nthreads=args.nthreads, name=args.name, memory_limit=args.memory_limit,
                   nanny=not args.no_nanny, host=args.host)
    except KeyboardInterrupt:
        return 130
    return 0


def cmd_store_check(args: argparse.Namespace) -> int:
    from pathlib import Path

    from relight.worker.blobs import BlobStore
    from relight.worker.store_check import scrub

    root = Path(args.data) / "blobs" if (Path(args.data) / "blobs").is_dir() else Path(args.data)
    if not (root / "sha256").is_dir():
        print(f"relight store check: no blob store at {args.data} (expected a 'sha256' folder there or in blobs/)")
        return 2
    report = scrub(BlobStore(root), repair=args.repair)
    print("\n".join(report.lines()))
    return 0 if report.clean or args.repair else 1


def register(sub: Any) -> None:
    """Add ``worker`` and ``store`` to the ``relight`` command's subparsers."""
    st = sub.add_parser("store", help="maintain the service's blob store")
    st_sub = st.add_subparsers(dest="store_command", required=True)
    chk = st_sub.add_parser("check", help="hash every blob, check every ref; exit 1 when something is wrong")
    chk.add_argument("data", help="the server's data directory (or the blob store root)")
    chk.add_argument("--repair", action="store_true",
                     help="remove corrupt blobs, dangling refs and left-over temporary files (the service "
                          "recomputes what it needs)")
    chk.set_defaults(func=cmd_store_check)

    p = sub.add_parser("worker", help="run a Dask worker for the service (scale-out)")
    p.add_argument("--scheduler", required=True, help="tcp://host:8786")
    p.add_argument("--nthreads", type=int, default=1)
    p.add_argument("--name")
    p.add_argument("--memory-limit", default="auto")
    p.add_argument("--host", default=None, help="interface to listen on (default: Dask's choice)")
    p.add_argument("--no-nanny", action="store_true", help="no supervising nanny (the worker is not restarted)")
    p.set_defaults(func=cmd_worker)
