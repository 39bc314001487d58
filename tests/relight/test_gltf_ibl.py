"""glTF lighting (relight.gltf_ibl, ``relight export --format gltf``): the Khronos glTF-Validator (npm
``gltf-validator``, a dev dependency of web/) finds no error and no warning in a standalone export or in a model with
the lighting added; the RGBD PNGs decode to the chain within their 8-bit quantum; SH, sun light and node rotation
are the manifest's."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import imagecodecs
import numpy as np
import pytest

from relight.cube_chain import prefilter_chain
from relight.envmap import read_envmap
from relight.gltf_ibl import ENV_BOX, RGBD_GAMMA, quaternion_z_to, rgbd_decode, rgbd_encode
from relight.ktx2 import read_ktx2
from relight.mesh.gltf import read_gltf_bytes, split_glb
from relight.sun import apply_sun

REPO = Path(__file__).resolve().parents[2]
CITY = REPO / "data" / "envmaps" / "city.exr"
VALIDATOR = REPO / "web" / "node_modules" / "gltf-validator" / "index.js"
NODE_VALIDATE = """
const v = require(process.argv[process.argv.length - 2]);
const bytes = new Uint8Array(require('fs').readFileSync(process.argv[process.argv.length - 1]));
v.validateBytes(bytes, {maxIssues: 1000}).then(r => console.log(JSON.stringify({
  errors: r.issues.numErrors, warnings: r.issues.numWarnings,
  messages: r.issues.messages.filter(m => m.severity < 2).map(m => [m.code, m.pointer, m.message])})));
"""


def validate(path: Path) -> dict[str, object]:
    node = shutil.which("node")
    assert node is not None and VALIDATOR.is_file(), "node and web/node_modules (npm ci --prefix web) are needed"
    proc = subprocess.run([node, "-e", NODE_VALIDATE, str(VALIDATOR), str(path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    out: dict[str, object] = json.loads(proc.stdout)
    return out


def _quantum_bound(enc: np.ndarray) -> np.ndarray:
    """Per channel, the decoded value's change if the stored byte moved by half a step up or down: the largest error
    the 8-bit rounding of ``(x D)^(1 / 2.2)`` can cause (D is stored exactly: alpha = floor(255 / m), an integer)."""
    q = enc[..., :3].astype(np.float64)
    d = enc[..., 3:].astype(np.float64) / 255.0
    hi = np.minimum(q + 0.5, 255.0) / 255.0
    lo = np.maximum(q - 0.5, 0.0) / 255.0
    mid = (q / 255.0) ** RGBD_GAMMA
    return np.asarray(np.maximum(hi**RGBD_GAMMA - mid, mid - lo**RGBD_GAMMA) / d)


def test_rgbd_round_trip_within_the_quantum() -> None:
    rng = np.random.default_rng(3)
    x = np.exp(rng.uniform(np.log(1e-3), np.log(250.0), (4096, 3)))
    enc, clamped = rgbd_encode(x)
    assert clamped == 0
    err = np.abs(rgbd_decode(enc) - x)
    assert np.all(err <= _quantum_bound(enc) + 1e-12)
    # closed forms: white 1 is stored as (255, 255, 255, 255); 51 as D = floor(255 / 51) / 255 = 5 / 255, rgb 1
    np.testing.assert_array_equal(rgbd_encode(np.ones((1, 3)))[0], [[255, 255, 255, 255]])
    np.testing.assert_array_equal(rgbd_encode(np.full((1, 3), 51.0))[0], [[255, 255, 255, 5]])
    assert rgbd_encode(np.array([[300.0, 0.0, 0.0]]))[1] == 1  # above the range: clamped and counted


@pytest.mark.parametrize("d", [(0.3, -0.5, 0.8), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)])
def test_quaternion_takes_z_to_the_direction(d: tuple[float, float, float]) -> None:
    x, y, z, w = quaternion_z_to(d)
    # the third column of the rotation matrix of (x, y, z, w) is R (0, 0, 1)
    col = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    np.testing.assert_allclose(col, np.asarray(d) / np.linalg.norm(d), atol=1e-12)


def _export(tmp: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", "export", str(CITY), "--format", "gltf", "--size",
                           "16", *extra], capture_output=True, text=True, timeout=600, cwd=tmp)


def test_standalone_export_validates_and_decodes_to_the_chain(tmp_path: Path) -> None:
    out = tmp_path / "city.glb"
    proc = _export(tmp_path, "--target", "gltf", "--sun", "extract", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = validate(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report
    manifest = json.loads((tmp_path / "city.glb.json").read_text())
    doc, bin_chunk = split_glb(out.read_bytes(), "city.glb")
    assert bin_chunk is not None
    light = doc["extensions"]["EXT_lights_image_based"]["lights"][0]
    assert doc["scenes"][doc["scene"]]["extensions"]["EXT_lights_image_based"] == {"light": 0}
    assert light["irradianceCoefficients"] == manifest["sh9"]["gltf"]["coefficients"]
    assert light["specularImageSize"] == 16 and [len(r) for r in light["specularImages"]] == [6] * 5
    # every face decodes to the chain of the residual (the gltf target's linear mapping) within its 8-bit quantum
    residual = apply_sun(read_envmap(CITY).pixels, "extract").pixels
    chain = prefilter_chain(residual, target="gltf", size=16)
    for lv, row in zip(chain.levels, light["specularImages"], strict=True):
        for face, idx in zip(lv.faces, row, strict=True):
            view = doc["bufferViews"][doc["images"][idx]["bufferView"]]
            png = bin_chunk[view["byteOffset"]: view["byteOffset"] + view["byteLength"]]
            enc = imagecodecs.png_decode(png)
            assert enc.shape == (lv.size, lv.size, 4) and enc.dtype == np.uint8
            err = np.abs(rgbd_decode(enc) - face.astype(np.float64))
            assert np.all(err <= _quantum_bound(enc) * 1.0001 + 1e-6)  # + float32 faces' own rounding
    # the sun: a directional light whose intensity x colour is the extracted irradiance, on a node whose +Z is the
    # sun's direction (the light travels along -Z)
    sun = manifest["sun"]
    punctual = doc["extensions"]["KHR_lights_punctual"]["lights"][0]
    assert punctual["type"] == "directional" and max(punctual["color"]) == 1.0
    np.testing.assert_allclose(np.array(punctual["color"]) * punctual["intensity"], sun["irradiance_rgb"], rtol=1e-12)
    node = doc["nodes"][manifest["gltf"]["sun_node"]]
    assert node["rotation"] == quaternion_z_to(sun["direction"])
    # KHR_lights_environment: the same chain as one embedded KTX2 cube (its images/textures inside the extension,
    # KHR_texture_ktx), the same SH, referenced by the scene; float16 texels within half precision of the chain
    env = doc["extensions"]["KHR_lights_environment"]
    assert doc["scenes"][doc["scene"]]["extensions"]["KHR_lights_environment"] == {"light": 0}
    env_light = env["lights"][0]
    assert env_light["irradianceCoefficients"] == manifest["sh9"]["gltf"]["coefficients"]
    tex = env["textures"][env_light["cubemap"]]["extensions"]["KHR_texture_ktx"]
    image = env["images"][tex["source"]]
    assert image["mimeType"] == "image/ktx2" and tex["layer"] == 0
    assert all(env_light[k] == [s * ENV_BOX] * 3 for k, s in (("boundingBoxMin", -1), ("boundingBoxMax", 1)))
    view = doc["bufferViews"][image["bufferView"]]
    cube = read_ktx2(bin_chunk[view["byteOffset"]: view["byteOffset"] + view["byteLength"]])
    assert cube.size == 16 and len(cube.levels) == 5 and cube.metadata["roughness_mapping"] == "linear"
    for lv, got in zip(chain.levels, cube.levels, strict=True):
        np.testing.assert_allclose(got[..., :3], lv.faces, rtol=2.0**-11, atol=6e-8)  # float16: 11-bit mantissa
    assert sorted(doc["extensionsUsed"]) == ["EXT_lights_image_based", "KHR_lights_environment",
                                             "KHR_lights_punctual", "KHR_texture_ktx"]


def test_into_a_model_keeps_it_and_validates(tmp_path: Path) -> None:
    import trimesh

    model = tmp_path / "bunny.glb"
    model.write_bytes(trimesh.load(REPO / "data" / "meshes" / "bunny.obj", force="mesh").export(file_type="glb"))
    assert validate(model)["errors"] == 0
    before = read_gltf_bytes(model.read_bytes(), name="bunny.glb")
    out = tmp_path / "lit.glb"
    proc = _export(tmp_path, "--target", "gltf", "--into", str(model), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = validate(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report
    after = read_gltf_bytes(out.read_bytes(), name="lit.glb")
    np.testing.assert_array_equal(after.positions, before.positions)
    np.testing.assert_array_equal(after.faces, before.faces)
    doc, _ = split_glb(out.read_bytes(), "lit.glb")
    assert len(doc["extensions"]["EXT_lights_image_based"]["lights"][0]["specularImages"]) == 5
    assert doc["extensions"]["KHR_lights_environment"]["lights"][0]["cubemap"] == 0


def test_gltf_needs_the_gltf_target(tmp_path: Path) -> None:
    proc = _export(tmp_path, "--target", "three", "--out", str(tmp_path / "x.glb"))
    assert proc.returncode == 2 and "--target gltf" in proc.stderr
    assert not (tmp_path / "x.glb").exists()
