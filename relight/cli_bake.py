"""``relight bake``: engine outputs for a whole set of maps in one command (issue 17, item 7), locally.

    relight bake MAPS... --target three|filament|gltf|babylon [--format ktx2,sh] [--size 256] [--levels L]
                 [--epsilon E] [--sun extract|clamp=V|keep] --out DIR [--json]

Items: per map, ``ktx2`` writes ``DIR/<stem>.<target>.ktx2`` (+ ``.json``, ``relight export``'s files) and ``sh``
writes ``DIR/<stem>.sh.json`` (every convention of ``relight.sh9``). One progress row per item (``done``,
``skipped`` or ``FAILED: <one-line error>``), then a summary; ``--json`` prints the rows as JSON instead.

* **Content-addressed skip.** An item's key is the SHA-256 of the map file's bytes, the item's parameters and
  ``relight.ALGORITHM_VERSION``; it is written into the item's JSON (``bake_key``). An item whose JSON holds the
  same key (and whose files all exist) is skipped, so a rerun with nothing to do reads only the maps' bytes.
* **Atomic, interrupt-safe.** Every file goes through a temporary file in DIR and a rename, removed on any
  exception including Ctrl-C, and an item's JSON (with the key) is written last: an interrupted bake leaves no
  partial file, and a rerun completes only what is missing.
* **One failure fails alone.** An item that raises records its one-line error and the bake goes on; the exit
  status is 1 if any item failed (2 for bad arguments, as every command).

``--server`` (the same bake through the API) is not implemented; items run one at a time.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from pathlib import Path
from typing import Any

#: Output formats an item can have.
FORMATS = ("ktx2", "sh")


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _key(digest: str, fmt: str, params: dict[str, Any]) -> str:
    from relight import ALGORITHM_VERSION

    doc = {"map": digest, "format": fmt, "params": params, "algorithm_version": ALGORITHM_VERSION}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode("utf-8")).hexdigest()


def _done(manifest: Path, key: str, files: list[Path]) -> bool:
    if not all(f.is_file() for f in files):
        return False
    try:
        return bool(json.loads(manifest.read_text()).get("bake_key") == key)
    except (OSError, ValueError):
        return False


def _bake_item(path: Path, fmt: str, out: Path, args: argparse.Namespace, key: str) -> None:
    from relight.cli_export import _write_atomic, export_chain
    from relight.envmap import read_envmap
    from relight.sh9 import all_conventions
    from relight.sun import apply_sun

    env = read_envmap(path)
    source = {"path": str(path), "height": int(env.pixels.shape[0]), "width": int(env.pixels.shape[1])}
    if fmt == "ktx2":
        export_chain(env.pixels, source, out, target=args.target, size=args.size, levels=args.levels,
                     epsilon=args.epsilon, sun_spec=args.sun, extra={"bake_key": key})
    else:
        sun = apply_sun(env.pixels, args.sun)
        doc = {"source": source, "sun": sun.report, "sh9": all_conventions(sun.pixels), "bake_key": key}
        _write_atomic(out, json.dumps(doc, indent=2).encode("utf-8"))


def cmd_bake(args: argparse.Namespace) -> int:
    from relight.errors import InputError
    from relight.sun import parse_sun

    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise InputError(f"--format takes a comma list of {', '.join(FORMATS)}, got {args.format!r}")
    parse_sun(args.sun)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    params = {"target": args.target, "size": args.size, "levels": args.levels, "epsilon": args.epsilon,
              "sun": args.sun}
    rows: list[dict[str, Any]] = []
    items = [(Path(m), fmt) for m in args.maps for fmt in formats]
    for i, (path, fmt) in enumerate(items, 1):
        stem = path.name.split(".")[0]
        out = out_dir / (f"{stem}.{args.target}.ktx2" if fmt == "ktx2" else f"{stem}.sh.json")
        manifest = out.with_name(out.name + ".json") if fmt == "ktx2" else out
        row: dict[str, Any] = {"item": i, "map": str(path), "format": fmt, "out": str(out)}
        t0 = time.perf_counter()
        try:
            item_params = params if fmt == "ktx2" else {"sun": args.sun}
            key = _key(_file_digest(path), fmt, item_params)
            if _done(manifest, key, [out, manifest]):
                row["status"] = "skipped"
            else:
                _bake_item(path, fmt, out, args, key)
                row["status"] = "done"
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # one item fails alone, with its one-line error
            row["status"] = "failed"
            row["error"] = " ".join(str(exc).split()) or type(exc).__name__
        row["seconds"] = time.perf_counter() - t0
        rows.append(row)
        if not args.json:
            status = row["status"] if row["status"] != "failed" else f"FAILED: {row['error']}"
            print(f"[{i}/{len(items)}] {path.name} {fmt}: {status} ({row['seconds']:.2f} s)", flush=True)
    failed = sum(r["status"] == "failed" for r in rows)
    if args.json:
        print(json.dumps({"items": rows, "failed": failed}, indent=2))
    else:
        done = sum(r["status"] == "done" for r in rows)
        print(f"{done} done, {sum(r['status'] == 'skipped' for r in rows)} skipped, {failed} failed")
    return 1 if failed else 0


def register(sub: Any) -> None:
    bp = sub.add_parser("bake", help="engine outputs (KTX2 chains, SH9) for many maps, resumable")
    bp.add_argument("maps", nargs="+")
    bp.add_argument("--target", required=True, choices=["three", "filament", "gltf", "babylon"])
    bp.add_argument("--format", default="ktx2,sh", help="comma list of ktx2, sh")
    bp.add_argument("--size", type=int, default=256)
    bp.add_argument("--levels", type=int, default=None)
    bp.add_argument("--epsilon", type=float, default=2.5e-5)
    bp.add_argument("--sun", default="keep")
    bp.add_argument("--out", required=True, help="output folder (created)")
    bp.add_argument("--json", action="store_true")
    bp.set_defaults(func=cmd_bake)
