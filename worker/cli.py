"""``relight worker``: a Dask worker for an existing scheduler (scale-out), registered through the
``relight.commands`` entry point group; ``relight.cli`` loads it.

    relight worker --scheduler tcp://host:8786 [--nthreads N] [--name NAME] [--memory-limit M] [--host H] [--no-nanny]

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


def register(sub: Any) -> None:
    """Add ``worker`` to the ``relight`` command's subparsers."""
    p = sub.add_parser("worker", help="run a Dask worker for the service (scale-out)")
    p.add_argument("--scheduler", required=True, help="tcp://host:8786")
    p.add_argument("--nthreads", type=int, default=1)
    p.add_argument("--name")
    p.add_argument("--memory-limit", default="auto")
    p.add_argument("--host", default=None, help="interface to listen on (default: Dask's choice)")
    p.add_argument("--no-nanny", action="store_true", help="no supervising nanny (the worker is not restarted)")
    p.set_defaults(func=cmd_worker)
