"""``relight serve``: the HTTP service with an embedded Dask cluster (registered through the ``relight.commands``
entry point group; ``relight.cli`` loads it).

    relight serve [--host H] [--port P] [--data DIR] [--workers N] [--scheduler URL] [--preload DIR | --no-preload]

Importing this module costs nothing beyond argparse: FastAPI, uvicorn and Dask load when the command runs.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any


def cmd_serve(args: argparse.Namespace) -> int:
    from relight.resources import sample_envmaps
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
        overrides["preload_dir"] = sample_envmaps()  # the samples installed with relight (package data)
    if not args.no_preload and "RELIGHT_PRELOAD_MESHES" not in os.environ:
        from relight.mesh.load import SAMPLES

        overrides["preload_meshes"] = list(SAMPLES)  # bunny, teapot and the generated bunny-100k
    try:
        serve(Settings(**overrides), args.host, args.port)
    except KeyboardInterrupt:
        return 130
    return 0


def register(sub: Any) -> None:
    """Add ``serve`` to the ``relight`` command's subparsers."""
    p = sub.add_parser("serve", help="run the HTTP service with an embedded Dask cluster")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=8000, help="0 picks a free port (the URL is printed)")
    p.add_argument("--data", help="data directory (database, blobs); default $RELIGHT_DATA_DIR or ./relight-data")
    p.add_argument("--workers", type=int, help="embedded cluster worker processes (default 2)")
    p.add_argument("--scheduler", help="connect to this Dask scheduler instead of starting a local cluster")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--preload", help="directory of environment maps to ingest at start-up (default: the samples)")
    g.add_argument("--no-preload", action="store_true", help="do not ingest the sample maps and meshes")
    p.set_defaults(func=cmd_serve)
