"""Engine export commands of the ``relight`` CLI (engine-ready outputs issue, item 1).

    relight export ENVMAP --target three|filament|gltf|babylon --format ktx2 [--size 256] [--levels L]
                   [--brdf SPEC] [--pixel-format rgba16f|b10g11r11|e5b9g9r9]
                   [--epsilon E] [--sun extract|clamp=V|keep] --out FILE.ktx2 [--server URL] [--json]
        the target engine's prefiltered GGX cube chain (``relight.cube_chain``): one mip per roughness in the
        engine's own lod mapping, RGBA16F, OpenGL face order; FILE.ktx2 carries the per-level table under the
        ``relight.levels`` key and ``FILE.ktx2.json`` beside it holds the same table (roughness, method, orders,
        predicted error and App. B bound per level, seconds) for tools that do not read KTX2, and the map's SH9
        in every engine convention (``relight.sh9``; also in the KTX2 under ``relight.sh9``). ``--sun``
        (``relight.sun``): ``extract`` prefilters the map without its sun and records the sun as a directional
        light (direction, RGB irradiance, illuminance, angular radius) under ``sun``; ``clamp=V`` limits every
        pixel's luminance to V and records the removed energy fraction; ``keep`` (default) does neither.
        ``--server URL`` computes it on the service (``GET /envmaps/{id}/ibl``): the same KTX2 bytes.
        ``--brdf SPEC`` (``relight.brdf.normal_view``, docs/conventions.md "Chains of other lobes"): each level
        holds that BRDF's lobe at view = normal instead of the engine's split-sum GGX lobe; a ``ggx-ld`` or
        ``gltf-pbr`` term without ``roughness`` takes the level's roughness, every other parameter is kept.
        ``--format gltf [--into MODEL.glb]`` (``--target gltf``): a GLB with the chain as EXT_lights_image_based
        (RGBD PNG faces, SH9 irradiance) and KHR_lights_environment (the chain as one KTX2 via KHR_texture_ktx,
        SH9), and an extracted sun as a KHR_lights_punctual light (``relight.gltf_ibl``).

    relight dfg [--size 128] [--multiscatter] --out FILE.exr|FILE.png|FILE.ktx2
        the split-sum DFG table (``relight.dfg``; docs/conventions.md "DFG"): R, G = (A, B) or, multiscatter,
        (B, A + B); EXR float32 (B channel 0), 16-bit PNG (linear, values x 65535, B channel 0) or a 2-D KTX2
        (``relight.ktx2``, RGBA16F, B 0, A 1, one level, the table's layout under ``relight.dfg``).

    relight sh ENVMAP [--convention three|gltf|filament|babylon|unity|raw] [--out FILE.json]
        the map's order-2 SH lighting (9 RGB coefficients) in that engine's order, sign and scaling
        (``relight.sh9``, docs/conventions.md "SH9"), as JSON on stdout or in FILE.

``register(subparsers)`` adds it (``relight.cli.COMMAND_PROVIDERS``). Errors: one line on stderr, exit status 2.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path
from typing import Any

#: ``relight.sh9.CONVENTIONS``, repeated so that registering the command imports nothing numerical
#: (tests/relight/test_cli_export.py checks they agree).
SH_CONVENTIONS = ("three", "gltf", "filament", "babylon", "unity", "raw")


def _write_atomic(path: Path, data: bytes) -> None:
    """Write through a temporary file in the same folder and rename: an interrupted export leaves no partial file."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def export_chain(pixels: Any, source: dict[str, Any], out: Path, *, target: str, size: int, levels: int | None,
                 epsilon: float, sun_spec: str, pixel_format: str = "rgba16f",
                 extra: dict[str, Any] | None = None, brdf: str | None = None) -> dict[str, Any]:
    """The chain, SH9 and sun step of one map (``relight.engine_export.chain_export``) written to ``out``
    (+ ``out.json``) atomically; the manifest."""
    from relight.engine_export import chain_export

    files = chain_export(pixels, source, target=target, size=size, levels=levels, epsilon=epsilon,
                         sun_spec=sun_spec, pixel_format=pixel_format, extra=extra, brdf=brdf)
    _write_atomic(out, files.data)
    _write_atomic(out.with_name(out.name + ".json"), json.dumps(files.manifest, indent=2).encode("utf-8"))
    return files.manifest


def cmd_export(args: argparse.Namespace) -> int:
    from relight.envmap import read_envmap
    from relight.errors import InputError
    from relight.sun import parse_sun

    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"the folder of --out does not exist: {out.parent}")
    parse_sun(args.sun)
    if args.brdf is not None:  # every spec error now, before the map is read or the service asked
        from relight.brdf.normal_view import ChainBrdf

        ChainBrdf(args.brdf)
    if args.format == "gltf":
        return _export_gltf(args, out)
    if args.into:
        raise InputError("--into needs --format gltf")
    if args.server:  # the same export from the service (relight.cli_bake.remote_exporter): identical bytes
        from relight.cli_bake import remote_exporter

        data, manifest = remote_exporter()(args.server, Path(args.envmap), fmt="ktx2", target=args.target,
                                           size=args.size, levels=args.levels, epsilon=args.epsilon, sun=args.sun,
                                           pixel_format=args.pixel_format, api_key=args.api_key,
                                           **({"brdf": args.brdf} if args.brdf is not None else {}))
        _write_atomic(out, data)
        _write_atomic(out.with_name(out.name + ".json"), json.dumps(manifest, indent=2).encode("utf-8"))
    else:
        env = read_envmap(args.envmap)
        source = {"path": str(args.envmap), "height": int(env.pixels.shape[0]),
                  "width": int(env.pixels.shape[1])}
        manifest = export_chain(env.pixels, source, out, target=args.target, size=args.size, levels=args.levels,
                                epsilon=args.epsilon, sun_spec=args.sun, pixel_format=args.pixel_format,
                                brdf=args.brdf)
    table = manifest["levels"]
    if args.json:
        print(json.dumps(manifest, indent=2))
        return 0
    lobe = f"--brdf {args.brdf}" if args.brdf is not None else "GGX"
    print(f"{out}: {manifest['target']} {lobe} chain, {len(table)} levels from {args.size}^2 faces, "
          f"{manifest['seconds']['total']:.2f} s")
    print(" level  size  roughness  method  order  predicted  bound     seconds")
    for row in table:
        order = "-" if row["order"] is None else str(row["order"])
        print(f" {row['level']:>5}  {row['size']:>4}  {row['roughness']:>9.4f}  {row['method']:<6}  {order:>5}  "
              f"{row['predicted_rms']:>9.2e}  {row['bound_rms']:>8.2e}  {row['seconds']:>7.3f}")
    return 0


def _export_gltf(args: argparse.Namespace, out: Path) -> int:
    """``--format gltf``: EXT_lights_image_based + the sun as KHR_lights_punctual, a GLB (``relight.gltf_ibl``)."""
    from relight.engine_export import gltf_export
    from relight.envmap import read_envmap
    from relight.errors import InputError

    if args.target != "gltf":
        raise InputError(f"--format gltf writes EXT_lights_image_based, whose mips map linearly to roughness: use "
                         f"--target gltf (got {args.target!r})")
    if args.server:  # GET /envmaps/{id}/ibl?format=gltf: the same GLB
        if args.into:
            raise InputError("--into is local only (the service writes the lighting alone): drop --server")
        from relight.cli_bake import remote_exporter

        data, manifest = remote_exporter()(args.server, Path(args.envmap), fmt="gltf", target="gltf",
                                           size=args.size, levels=args.levels, epsilon=args.epsilon, sun=args.sun,
                                           api_key=args.api_key,
                                           **({"brdf": args.brdf} if args.brdf is not None else {}))
        _write_atomic(out, data)
        _write_atomic(out.with_name(out.name + ".json"), json.dumps(manifest, indent=2).encode("utf-8"))
        print(json.dumps(manifest, indent=2) if args.json else f"{out}: EXT_lights_image_based from {args.server}")
        return 0
    into = None
    if args.into:
        into_path = Path(args.into)
        if not into_path.is_file():
            raise InputError(f"--into: no such file: {into_path}")
        into = into_path.read_bytes()
    env = read_envmap(args.envmap)
    source = {"path": str(args.envmap), "height": int(env.pixels.shape[0]), "width": int(env.pixels.shape[1])}
    files = gltf_export(env.pixels, source, size=args.size, levels=args.levels, epsilon=args.epsilon,
                        sun_spec=args.sun, into=into, extra={"into": args.into} if args.into else None,
                        brdf=args.brdf)
    _write_atomic(out, files.data)
    _write_atomic(out.with_name(out.name + ".json"), json.dumps(files.manifest, indent=2).encode("utf-8"))
    g = files.manifest["gltf"]
    print(json.dumps(files.manifest, indent=2) if args.json else
          f"{out}: EXT_lights_image_based, {g['levels']} levels x 6 RGBD PNGs ({g['rgbd_clamped']} texels above "
          f"255 clamped){', sun as KHR_lights_punctual' if 'sun_node' in g else ''}, "
          f"{files.manifest['seconds']['total']:.2f} s")
    return 0


def cmd_sh(args: argparse.Namespace) -> int:
    from relight.envmap import read_envmap
    from relight.errors import InputError
    from relight.sh9 import sh9

    out = Path(args.out) if args.out else None
    if out is not None and not out.parent.is_dir():
        raise InputError(f"the folder of --out does not exist: {out.parent}")
    env = read_envmap(args.envmap)
    doc = sh9(env.pixels, args.convention)
    doc["source"] = {"path": str(args.envmap), "height": int(env.pixels.shape[0]), "width": int(env.pixels.shape[1])}
    text = json.dumps(doc, indent=2)
    if out is not None:
        _write_atomic(out, text.encode("utf-8"))
    else:
        print(text)
    return 0


def cmd_dfg(args: argparse.Namespace) -> int:
    from relight.dfg import dfg_file
    from relight.errors import InputError

    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"the folder of --out does not exist: {out.parent}")
    suffix = out.suffix.lower()
    if suffix not in (".exr", ".png", ".ktx2"):
        raise InputError(f"--out must end in .exr, .png or .ktx2, got {out.name!r}")
    _write_atomic(out, dfg_file(args.size, multiscatter=args.multiscatter, fmt=suffix[1:]))
    print(f"{out}: {args.size} x {args.size} DFG table ({'multiscatter' if args.multiscatter else 'A, B'})")
    return 0


def register(sub: Any) -> None:
    ex = sub.add_parser("export", help="engine-ready prefiltered cube chain (KTX2) of an environment map")
    ex.add_argument("envmap")
    ex.add_argument("--target", required=True, choices=["three", "filament", "gltf", "babylon"],
                    help="engine whose roughness-to-mip mapping and split-sum lobe the chain follows")
    ex.add_argument("--format", default="ktx2", choices=["ktx2", "gltf"],
                    help="ktx2: the cube chain; gltf: a GLB with EXT_lights_image_based (+ the sun as a light)")
    ex.add_argument("--pixel-format", default="rgba16f", choices=["rgba16f", "b10g11r11", "e5b9g9r9"],
                    help="KTX2 texels: RGBA16F (default) or a 4-byte packed unsigned float (relight.packed_float)")
    ex.add_argument("--into", default=None, help="--format gltf: add the lighting to this GLB model")
    ex.add_argument("--size", type=int, default=256, help="face size of level 0 (a power of two)")
    ex.add_argument("--levels", type=int, default=None, help="mip levels (default: down to 1 x 1)")
    ex.add_argument("--brdf", default=None, metavar="SPEC", help="another lobe family per level: the BRDF's lobe at "
                    "view = normal (e.g. gltf-pbr:base=0.9/0.6/0.2,metallic=1; a ggx-ld or gltf-pbr term without "
                    "roughness takes each level's); default the target's split-sum GGX lobe")
    ex.add_argument("--epsilon", type=float, default=2.5e-5,
                    help="uncaptured lobe energy per level (seed 000 §5.1); the default predicts 0.5 %% RMS")
    ex.add_argument("--sun", default="keep", help="extract (a directional light + the residual), clamp=V (pixel "
                    "luminance <= V, removed energy recorded) or keep (default)")
    ex.add_argument("--out", required=True)
    ex.add_argument("--server", default=None, help="compute on the relight service at this URL (GET "
                    "/envmaps/{id}/ibl; the same bytes)")
    ex.add_argument("--api-key", default=os.environ.get("RELIGHT_API_KEY"), help="default $RELIGHT_API_KEY")
    ex.add_argument("--json", action="store_true", help="print the manifest as JSON")
    ex.set_defaults(func=cmd_export)

    dp = sub.add_parser("dfg", help="the split-sum DFG lookup table (GGX, height-correlated Smith, Schlick)")
    dp.add_argument("--size", type=int, default=128)
    dp.add_argument("--multiscatter", action="store_true", help="Filament's (B, A + B) layout")
    dp.add_argument("--out", required=True, help="FILE.exr (float32), FILE.png (16-bit) or FILE.ktx2 (RGBA16F)")
    dp.set_defaults(func=cmd_dfg)

    sp = sub.add_parser("sh", help="order-2 SH lighting (9 RGB coefficients) in an engine's convention")
    sp.add_argument("envmap")
    sp.add_argument("--convention", default="three", choices=list(SH_CONVENTIONS),
                    help="order, sign and scaling of the coefficients (docs/conventions.md, SH9)")
    sp.add_argument("--out", default=None, help="write the JSON here instead of stdout")
    sp.set_defaults(func=cmd_sh)
