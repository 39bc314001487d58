"""``relight bake``: engine outputs for a whole set of maps in one command (issue 17, item 7).

    relight bake MAPS... [--brdf SPEC [--brdf SPEC...]] --target three|filament|gltf|babylon
                 [--format ktx2,sh,gltf] [--size 256] [--levels L] [--epsilon E] [--sun extract|clamp=V|keep]
                 [--pixel-format F] --out DIR [-j N] [--local | --server URL] [--json]

Items: per map, ``ktx2`` writes ``DIR/<stem>.<target>.ktx2`` (+ ``.json``, ``relight export``'s files), ``gltf``
``DIR/<stem>.glb`` (+ ``.json``; ``relight export --format gltf``, ``--target gltf`` only) and
``sh`` writes ``DIR/<stem>.sh.json`` (every convention of ``relight.sh9``). Each ``--brdf SPEC`` is one material:
the chain items (ktx2, gltf) are made once per map x material, named ``DIR/<stem>.<material>.<target>.ktx2`` and
``DIR/<stem>.<material>.glb`` with ``<material>`` = :func:`material_tag` (the spec's safe characters and a hash);
no ``--brdf`` is the target's split-sum GGX lobe, the names above. SH9 is the lighting's alone: one per map.
One progress row per item (``done``,
``skipped`` or ``FAILED: <one-line error>``), then a summary; ``--json`` prints the rows as JSON instead.

* **Content-addressed skip.** An item's key is the SHA-256 of the map file's bytes, the item's parameters and
  ``relight.ALGORITHM_VERSION``; it is written into the item's JSON (``bake_key``). An item whose JSON holds the
  same key (and whose files all exist) is skipped, so a rerun with nothing to do reads only the maps' bytes.
* **Atomic, interrupt-safe.** Every file goes through a temporary file in DIR and a rename, removed on any
  exception including Ctrl-C, and an item's JSON (with the key) is written last: an interrupted bake leaves no
  partial file, and a rerun completes only what is missing.
* **One failure fails alone.** An item that raises records its one-line error and the bake goes on; the exit
  status is 1 if any item failed (2 for bad arguments, as every command).
* **Local or served.** ``--server URL`` (``--local``, the default, computes here) uploads each map and reads its
  export from the service's ``GET /envmaps/{id}/ibl`` (the client's ``relight.remote`` entry point): the KTX2,
  GLB and SH files are byte-identical to a local bake's, and so are the sidecars apart from their ``seconds``. Every
  item's ``source`` is the map's file name, SHA-256 and size, whichever computed it; JSON keys are sorted.
* **Parallel.** ``-j N`` runs N items at a time: worker processes locally (each item is CPU work), threads with
  ``--server`` (each item waits on the service). Rows are printed as items finish.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

#: Output formats an item can have (``relight.engine_export.FORMATS``).
FORMATS = ("ktx2", "sh", "gltf")
#: Largest -j.
MAX_JOBS = 64


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


def remote_exporter() -> Any:
    """The client's ``remote_export`` (entry point group ``relight.remote``, name ``export``)."""
    from importlib.metadata import entry_points

    from relight.errors import InputError

    found = list(entry_points(group="relight.remote", name="export"))
    if not found:
        raise InputError("--server needs the relight client (entry point relight.remote:export) installed")
    return found[0].load()


def export_item(path: Path, fmt: str, opts: dict[str, Any]) -> tuple[bytes, dict[str, Any]]:
    """(file bytes, manifest) of one export, computed here or by ``opts["server"]`` (module docstring)."""
    from relight.errors import InputError

    if fmt == "gltf" and opts["target"] != "gltf":
        raise InputError(f"gltf (EXT_lights_image_based) needs --target gltf, got {opts['target']!r}")
    pixel_format = opts.get("pixel_format", "rgba16f")
    brdf = opts.get("brdf") if fmt != "sh" else None
    if opts.get("server"):
        return remote_exporter()(opts["server"], path, fmt=fmt, target=opts["target"], size=opts["size"],  # type: ignore[no-any-return]
                                 levels=opts["levels"], epsilon=opts["epsilon"], sun=opts["sun"],
                                 pixel_format=pixel_format, api_key=opts.get("api_key"),
                                 **({"brdf": brdf} if brdf is not None else {}))
    from relight.engine_export import chain_export, gltf_export, sh_export
    from relight.envmap import read_envmap

    env = read_envmap(path)
    source = {"path": str(path), "height": int(env.pixels.shape[0]), "width": int(env.pixels.shape[1])}
    if fmt == "ktx2":
        files = chain_export(env.pixels, source, target=opts["target"], size=opts["size"], levels=opts["levels"],
                             epsilon=opts["epsilon"], sun_spec=opts["sun"], pixel_format=pixel_format, brdf=brdf)
    elif fmt == "gltf":
        files = gltf_export(env.pixels, source, size=opts["size"], levels=opts["levels"], epsilon=opts["epsilon"],
                            sun_spec=opts["sun"], brdf=brdf)
    else:
        files = sh_export(env.pixels, source, sun_spec=opts["sun"])
    return files.data, files.manifest


def _bake_item(path: Path, fmt: str, out: Path, opts: dict[str, Any], digest: str, key: str) -> None:
    from relight.cli_export import _write_atomic

    data, manifest = export_item(path, fmt, opts)
    src = manifest.get("source") or {}
    manifest = {**manifest, "source": {"name": path.name, "sha256": digest, "height": src.get("height"),
                                       "width": src.get("width")}, "bake_key": key}
    text = json.dumps(manifest, indent=2, sort_keys=True).encode("utf-8")
    if fmt in ("ktx2", "gltf"):
        _write_atomic(out, data)
        _write_atomic(out.with_name(out.name + ".json"), text)
    else:
        _write_atomic(out, text)


def material_tag(spec: str) -> str:
    """A file-name part for a ``--brdf`` spec: its characters outside ``[A-Za-z0-9.=-]`` as ``_`` (at most 40),
    a dash and the first 8 hex digits of the spec's SHA-256 (two specs never share a name)."""
    import re

    safe = re.sub(r"[^A-Za-z0-9.=-]+", "_", spec.strip())[:40].strip("_.")
    return f"{safe}-{hashlib.sha256(spec.strip().encode('utf-8')).hexdigest()[:8]}"


def run_item(i: int, path_text: str, fmt: str, out_dir: str, opts: dict[str, Any]) -> dict[str, Any]:
    """One item: skipped, done or failed (its one-line error); a top-level function so a process pool runs it.
    ``opts["brdf"]``: the item's material (a spec string, None for the target's lobe; ignored by ``sh``)."""
    path = Path(path_text)
    stem = path.name.split(".")[0]
    brdf = opts.get("brdf") if fmt != "sh" else None
    mat = "" if brdf is None else f".{material_tag(brdf)}"
    name = {"ktx2": f"{stem}{mat}.{opts['target']}.ktx2", "gltf": f"{stem}{mat}.glb", "sh": f"{stem}.sh.json"}[fmt]
    out = Path(out_dir) / name
    manifest = out if fmt == "sh" else out.with_name(out.name + ".json")
    row: dict[str, Any] = {"item": i, "map": path_text, "format": fmt, "out": str(out)}
    if brdf is not None:
        row["brdf"] = brdf
    t0 = time.perf_counter()
    try:
        params = ({k: opts[k] for k in ("target", "size", "levels", "epsilon", "sun")} if fmt != "sh"
                  else {"sun": opts["sun"]})
        if fmt == "ktx2" and opts.get("pixel_format", "rgba16f") != "rgba16f":  # absent: earlier keys stay valid
            params["pixel_format"] = opts["pixel_format"]
        if brdf is not None:
            params["brdf"] = brdf.strip()
        digest = _file_digest(path)
        key = _key(digest, fmt, params)
        if _done(manifest, key, [out, manifest]):
            row["status"] = "skipped"
        else:
            _bake_item(path, fmt, out, opts, digest, key)
            row["status"] = "done"
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # one item fails alone, with its one-line error
        row["status"] = "failed"
        row["error"] = " ".join(str(exc).split()) or type(exc).__name__
    row["seconds"] = time.perf_counter() - t0
    return row


def cmd_bake(args: argparse.Namespace) -> int:
    from relight import validate
    from relight.errors import InputError
    from relight.sun import parse_sun

    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise InputError(f"--format takes a comma list of {', '.join(FORMATS)}, got {args.format!r}")
    validate.int_in_range("-j", args.jobs, 1, MAX_JOBS)
    parse_sun(args.sun)
    if args.server:
        remote_exporter()  # a missing client is an argument error, before any item runs
    materials: list[str | None] = list(dict.fromkeys(b.strip() for b in args.brdf)) if args.brdf else [None]
    for spec in materials:  # a bad spec is an argument error too
        if spec is not None:
            from relight.brdf.normal_view import ChainBrdf

            ChainBrdf(spec)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    base = {"target": args.target, "size": args.size, "levels": args.levels, "epsilon": args.epsilon,
            "sun": args.sun, "server": args.server, "api_key": args.api_key, "pixel_format": args.pixel_format}
    # one item per map x format x material; sh depends on the map alone (one per map)
    items = [(m, fmt, {**base, "brdf": b}) for m in args.maps for fmt in formats
             for b in (materials if fmt != "sh" else [None])]
    rows: list[dict[str, Any]] = []

    def report(row: dict[str, Any]) -> None:
        rows.append(row)
        if not args.json:
            status = row["status"] if row["status"] != "failed" else f"FAILED: {row['error']}"
            what = row["format"] if "brdf" not in row else f"{row['format']} --brdf {row['brdf']}"
            print(f"[{row['item']}/{len(items)}] {Path(row['map']).name} {what}: {status} "
                  f"({row['seconds']:.2f} s)", flush=True)

    if args.jobs == 1:
        for i, (m, fmt, opts) in enumerate(items, 1):
            report(run_item(i, m, fmt, str(out_dir), opts))
    else:
        pool: Executor = ThreadPoolExecutor(args.jobs) if args.server else ProcessPoolExecutor(args.jobs)
        try:
            futures: list[Future[dict[str, Any]]] = [pool.submit(run_item, i, m, fmt, str(out_dir), opts)
                                                     for i, (m, fmt, opts) in enumerate(items, 1)]
            for fut in as_completed(futures):
                report(fut.result())
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # running items finish or clean up their own files
            raise
        pool.shutdown()
    rows.sort(key=lambda r: int(r["item"]))
    failed = sum(r["status"] == "failed" for r in rows)
    if args.json:
        print(json.dumps({"items": rows, "failed": failed}, indent=2))
    else:
        done = sum(r["status"] == "done" for r in rows)
        print(f"{done} done, {sum(r['status'] == 'skipped' for r in rows)} skipped, {failed} failed")
    return 1 if failed else 0


def register(sub: Any) -> None:
    import os

    bp = sub.add_parser("bake", help="engine outputs (KTX2 chains, SH9) for many maps, resumable")
    bp.add_argument("maps", nargs="+")
    bp.add_argument("--target", required=True, choices=["three", "filament", "gltf", "babylon"])
    bp.add_argument("--format", default="ktx2,sh", help="comma list of ktx2, sh, gltf (gltf: --target gltf)")
    bp.add_argument("--brdf", action="append", default=None, metavar="SPEC", help="a material (repeatable): its "
                    "lobe at view = normal per level (relight export --brdf); one chain per map x material")
    bp.add_argument("--size", type=int, default=256)
    bp.add_argument("--levels", type=int, default=None)
    bp.add_argument("--epsilon", type=float, default=2.5e-5)
    bp.add_argument("--sun", default="keep")
    bp.add_argument("--pixel-format", default="rgba16f", choices=["rgba16f", "b10g11r11", "e5b9g9r9"],
                    help="KTX2 texels")
    bp.add_argument("--out", required=True, help="output folder (created)")
    bp.add_argument("-j", "--jobs", type=int, default=1, help="items at a time (processes locally, threads with "
                    "--server)")
    where = bp.add_mutually_exclusive_group()
    where.add_argument("--local", dest="server", action="store_const", const=None,
                       help="compute here (the default)")
    where.add_argument("--server", default=None, help="compute on the relight service at this URL")
    bp.add_argument("--api-key", default=os.environ.get("RELIGHT_API_KEY"), help="default $RELIGHT_API_KEY")
    bp.add_argument("--json", action="store_true")
    bp.set_defaults(func=cmd_bake)
