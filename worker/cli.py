"""``relight worker``: a Dask worker for an existing scheduler (scale-out), registered through the
``relight.commands`` entry point group; ``relight.cli`` loads it.

    relight worker --scheduler tls://host:8786 [--nthreads N] [--name NAME] [--memory-limit M] [--host H] [--no-nanny]
                   [--tls-ca-file F --tls-cert F --tls-key F]
    relight scheduler [--host H] [--port P] [--tls-ca-file F --tls-cert F --tls-key F]
    relight tls init DIR                         (a self-signed cluster certificate: relight.worker.tls)
    relight store check DATA_DIR [--repair]      (scrub the blob store: relight.worker.store_check)

The TLS flags default to ``RELIGHT_TLS_CA_FILE``, ``RELIGHT_TLS_CERT`` and ``RELIGHT_TLS_KEY``; given, the node
speaks only TLS (``tls://`` addresses) and accepts only peers with a certificate of that CA.

Importing this module costs nothing beyond argparse: Dask loads when the command runs.
"""

from __future__ import annotations

import argparse
from typing import Any


def _tls(args: argparse.Namespace) -> Any:
    from relight.worker.tls import TlsFiles

    try:
        return TlsFiles.of(args.tls_ca_file, args.tls_cert, args.tls_key)
    except ValueError as exc:
        raise SystemExit(f"relight {args.command}: {exc}") from None


def cmd_worker(args: argparse.Namespace) -> int:
    from relight.worker.run import run_worker

    tls = _tls(args)
    try:
        run_worker(args.scheduler, nthreads=args.nthreads, name=args.name, memory_limit=args.memory_limit,
                   nanny=not args.no_nanny, host=args.host, tls=tls)
    except KeyboardInterrupt:
        return 130
    return 0


def cmd_scheduler(args: argparse.Namespace) -> int:
    from relight.worker.run import run_scheduler

    tls = _tls(args)
    try:
        run_scheduler(args.host, args.port, tls)
    except KeyboardInterrupt:
        return 130
    return 0


def cmd_tls_init(args: argparse.Namespace) -> int:
    from pathlib import Path

    from relight.worker.tls import write_certificates

    files = write_certificates(Path(args.dir), days=args.days)
    print(f"RELIGHT_TLS_CA_FILE={files.ca_file}\nRELIGHT_TLS_CERT={files.cert}\nRELIGHT_TLS_KEY={files.key}")
    return 0


def _tls_flags(p: Any) -> None:
    import os

    p.add_argument("--tls-ca-file", default=os.environ.get("RELIGHT_TLS_CA_FILE"),
                   help="CA certificate peers must be signed by (default: $RELIGHT_TLS_CA_FILE)")
    p.add_argument("--tls-cert", default=os.environ.get("RELIGHT_TLS_CERT"),
                   help="this node's certificate (default: $RELIGHT_TLS_CERT)")
    p.add_argument("--tls-key", default=os.environ.get("RELIGHT_TLS_KEY"),
                   help="this node's private key (default: $RELIGHT_TLS_KEY)")


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

    tls = sub.add_parser("tls", help="TLS certificates of a scaled-out cluster")
    tls_sub = tls.add_subparsers(dest="tls_command", required=True)
    init = tls_sub.add_parser("init", help="write a self-signed cluster certificate and key into DIR (kept if "
                                           "present)")
    init.add_argument("dir")
    init.add_argument("--days", type=int, default=3650)
    init.set_defaults(func=cmd_tls_init)

    sc = sub.add_parser("scheduler", help="run a Dask scheduler for the service (scale-out; no HTTP endpoint)")
    sc.add_argument("--host", default="0.0.0.0", help="interface to listen on")  # noqa: S104
    sc.add_argument("--port", type=int, default=8786)
    _tls_flags(sc)
    sc.set_defaults(func=cmd_scheduler)

    p = sub.add_parser("worker", help="run a Dask worker for the service (scale-out; no HTTP endpoint)")
    p.add_argument("--scheduler", required=True, help="tls://host:8786 (tcp://host:8786 without TLS files)")
    p.add_argument("--nthreads", type=int, default=1,
                   help="jobs run at once (job slots); the worker has one thread more, for interactive requests")
    p.add_argument("--name")
    p.add_argument("--memory-limit", default="auto")
    p.add_argument("--host", default=None, help="interface to listen on (default: Dask's choice)")
    p.add_argument("--no-nanny", action="store_true", help="no supervising nanny (the worker is not restarted)")
    _tls_flags(p)
    p.set_defaults(func=cmd_worker)
