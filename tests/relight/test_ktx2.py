"""KTX2 cube chains (relight.ktx2, `relight export`): the container against npm ktx-parse (the parser three.js'
KTX2Loader embeds; a dev dependency of web/, version 2.0.0), and the CLI.

The copy three r187 vendors (examples/jsm/libs/ktx-parse.module.js) reads these files as well, but its writer
truncates key/value lengths above 255 bytes (its concat copies a Uint32Array element-wise), so the byte-identical
re-serialisation is checked with the current package."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from relight.errors import InputError
from relight.ktx2 import HALF_MAX, VK_FORMAT_R16G16B16A16_SFLOAT, read_ktx2, to_half_rgba, write_ktx2

REPO = Path(__file__).resolve().parents[2]
KTX_PARSE = REPO / "web" / "node_modules" / "ktx-parse" / "dist" / "index.mjs"

#: Node: read with ktx-parse, report the container's fields, re-serialise (keeping our KTXwriter) and compare.
NODE_CHECK = """
import { read, write } from %s;
import { readFileSync } from 'node:fs';
const bytes = new Uint8Array(readFileSync(process.argv[process.argv.length - 1]));
const c = read(bytes);
const again = write(c, { keepWriter: true });
const same = again.length === bytes.length && again.every((v, i) => v === bytes[i]);
const dfd = c.dataFormatDescriptor[0];
console.log(JSON.stringify({
  vkFormat: c.vkFormat, typeSize: c.typeSize, width: c.pixelWidth, height: c.pixelHeight, depth: c.pixelDepth,
  layers: c.layerCount, faces: c.faceCount, levelCount: c.levelCount, scheme: c.supercompressionScheme,
  levels: c.levels.map(l => [l.levelData.byteLength, l.uncompressedByteLength]),
  colorModel: dfd.colorModel, transfer: dfd.transferFunction, bytesPlane0: dfd.bytesPlane[0],
  samples: dfd.samples.map(s => [s.bitOffset, s.bitLength, s.channelType]),
  writer: c.keyValue.KTXwriter, keys: Object.keys(c.keyValue).sort(), identical: same,
}));
"""


def ktx_parse(path: Path) -> dict[str, object]:
    node = shutil.which("node")
    assert node is not None and KTX_PARSE.is_file(), "node and web/node_modules (npm ci --prefix web) are needed"
    script = NODE_CHECK % json.dumps(KTX_PARSE.as_uri())
    proc = subprocess.run([node, "--input-type=module", "-e", script, str(path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    out: dict[str, object] = json.loads(proc.stdout)
    return out


def chain(size: int, rng: np.random.Generator) -> list[np.ndarray]:
    return [rng.uniform(0.0, 4.0, (6, size >> i, size >> i, 3)) for i in range(int(np.log2(size)) + 1)]


def test_ktx_parse_reads_and_reserialises_byte_identically(tmp_path: Path) -> None:
    levels = chain(16, np.random.default_rng(42))
    data = write_ktx2(levels, {"target": "three", "levels": [{"level": 0}]}, writer="relight test")
    path = tmp_path / "chain.ktx2"
    path.write_bytes(data)
    info = ktx_parse(path)
    assert info["identical"] is True
    assert (info["vkFormat"], info["typeSize"], info["width"], info["height"]) == (97, 2, 16, 16)
    assert (info["depth"], info["layers"], info["faces"], info["levelCount"], info["scheme"]) == (0, 0, 6, 5, 0)
    assert info["levels"] == [[6 * s * s * 8] * 2 for s in (16, 8, 4, 2, 1)]
    # RGBSDA, linear, 8 bytes per texel; R, G, B, A as signed 16-bit floats (channel ids 0, 1, 2, 15)
    assert (info["colorModel"], info["transfer"], info["bytesPlane0"]) == (1, 1, 8)
    assert info["samples"] == [[16 * i, 15, ch | 0xC0] for i, ch in enumerate((0, 1, 2, 15))]
    assert info["writer"] == "relight test"
    assert info["keys"] == ["KTXwriter", "relight.levels", "relight.target"]


def test_round_trip_through_our_reader() -> None:
    levels = chain(8, np.random.default_rng(7))
    levels[0][2, 3, 4] = [1.0e6, -2.0, 0.5]  # beyond float16: clamped to the largest finite half
    cube = read_ktx2(write_ktx2(levels, {"note": {"a": 1}}))
    assert cube.vk_format == VK_FORMAT_R16G16B16A16_SFLOAT and cube.size == 8 and len(cube.levels) == 4
    assert cube.metadata == {"note": {"a": 1}}
    for got, want in zip(cube.levels, levels, strict=True):
        np.testing.assert_allclose(got[..., :3], np.clip(want, -HALF_MAX, HALF_MAX), rtol=2.0**-11)
        assert np.all(got[..., 3] == 1.0)
    assert cube.levels[0][2, 3, 4, 0] == HALF_MAX
    assert to_half_rgba(levels[0])[1] == 1


def test_bad_levels_are_refused() -> None:
    with pytest.raises(InputError, match="shape"):
        write_ktx2([np.zeros((6, 8, 8, 3)), np.zeros((6, 3, 3, 3))])
    with pytest.raises(InputError, match="non-finite"):
        write_ktx2([np.full((6, 1, 1, 3), np.nan)])
    with pytest.raises(InputError, match="identifier"):
        read_ktx2(b"\x00" * 100)


def test_cli_export_writes_a_chain_ktx_parse_reads(tmp_path: Path) -> None:
    out = tmp_path / "city.ktx2"
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "export", str(REPO / "data/envmaps/studio.exr"),
                           "--target", "gltf", "--format", "ktx2", "--size", "16", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "level" in proc.stdout
    info = ktx_parse(out)
    assert info["identical"] is True and info["levelCount"] == 5 and info["faces"] == 6
    manifest = json.loads((tmp_path / "city.ktx2.json").read_text())
    assert manifest["target"] == "gltf" and manifest["roughness_mapping"] == "linear"
    rough = [row["roughness"] for row in manifest["levels"]]
    np.testing.assert_allclose(rough, np.linspace(0.0, 1.0, 5))
    cube = read_ktx2(out.read_bytes())
    # the KTX2 carries the table without the seconds (deterministic bytes, relight.engine_export)
    assert cube.metadata["levels"] == [{k: v for k, v in row.items() if k != "seconds"} for row in manifest["levels"]]
    # no temporary file is left beside the output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["city.ktx2", "city.ktx2.json"]


def test_cli_export_bad_input_is_one_line(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "export", str(REPO / "data/envmaps/studio.exr"),
                           "--target", "three", "--size", "48", "--out", str(tmp_path / "x.ktx2")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "power of two" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.ktx2").exists()
