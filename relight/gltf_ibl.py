"""glTF lighting (issue 17, item 3): a prefiltered chain, its SH9 and the extracted sun as a binary glTF (GLB).

* ``EXT_lights_image_based`` (Khronos vendor extension, Babylon.js reads it): one light at the root with
  ``irradianceCoefficients`` (the 9 x 3 irradiance coefficients, relight.sh9's ``gltf`` convention),
  ``specularImageSize`` and ``specularImages`` (N mips x 6 faces, +X, -X, +Y, -Y, +Z, -Z), every image a 4-channel
  PNG in RGBD, referenced by the scene's ``extensions.EXT_lights_image_based.light``. The extension says the mips
  "evenly map to roughness values from 0 to 1", the ``gltf`` target's linear mapping (``relight.cube_chain``), so
  ``--format gltf`` needs ``--target gltf``.
* **RGBD** (Babylon's ``toRGBD`` / ``fromRGBD``, its helperFunctions shader): ``D = clamp(floor(max(255 / m, 1)) /
  255, 0, 1)`` with ``m = max(r, g, b, 1e-7)``, stored ``(rgb D)^(1 / 2.2)`` in 8 bits and ``D`` as alpha; decoded
  ``rgb^2.2 / D``. Values above 255 are clamped (counted in the manifest). :func:`rgbd_decode` is the inverse.
* ``KHR_lights_environment`` (Khronos draft, the version that depends on ``KHR_texture_ktx``) beside it: the
  same chain as one KTX2 cube file (``relight.ktx2``, RGBA16F, every level, the ``gltf`` target's linear
  mapping the draft asks for) embedded in the binary buffer and declared in the extension's own ``images``
  (``mimeType`` ``image/ktx2``, so that loaders without the extension never see it) and ``textures``
  (``KHR_texture_ktx: {source, layer: 0}``), and one light with the same ``irradianceCoefficients``,
  ``luminanceFactor`` 1, ``cubemap`` and the required local-cubemap box: :data:`ENV_BOX` metres around the
  origin, far beyond any model (the map is a distant environment; the box only localises reflections).
  The scene references it as it references the EXT light.
* The sun (``--sun extract``, ``relight.sun``) as a ``KHR_lights_punctual`` directional light on a node whose -Z
  axis points along the light's travel, ``-direction``: ``color`` = E / max(E) (RGB irradiance E, components in
  [0, 1] as the extension requires) and ``intensity`` = max(E), so ``intensity x color`` = E.
* ``into``: the same added to an existing GLB (its default scene gets the light and the sun node; the images are
  appended to its binary buffer).

Faces are written in the pixel order of the KTX2 export (row 0 = the face's t = 0 edge, the order a GL cube face
upload without a flip expects); the extension's text asks for images "flipped about [their] vertical axis" for
glTF's texture space. Which flip Babylon applies when it uploads them was not checked in a browser here.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError

#: Babylon's ``rgbdMaxRange`` and its gamma approximation (``GammaEncodePowerApprox = 1 / 2.2``).
RGBD_MAX_RANGE = 255.0
RGBD_GAMMA = 2.2
GLB_MAGIC = 0x46546C67
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
EXT_IBL = "EXT_lights_image_based"
KHR_PUNCTUAL = "KHR_lights_punctual"
KHR_ENV = "KHR_lights_environment"
KHR_KTX = "KHR_texture_ktx"
#: Half the edge of KHR_lights_environment's local-cubemap box (metres): a distant environment.
ENV_BOX = 1.0e4


def rgbd_encode(rgb: NDArray[np.floating]) -> tuple[NDArray[np.uint8], int]:
    """(..., 3) linear RGB -> (..., 4) RGBD bytes (module docstring) and the count of texels above the range."""
    x = np.maximum(np.asarray(rgb, dtype=np.float64), 0.0)
    m = np.maximum(x.max(axis=-1), 1e-7)
    clamped = int(np.count_nonzero(m > RGBD_MAX_RANGE))
    d = np.clip(np.floor(np.maximum(RGBD_MAX_RANGE / m, 1.0)) / 255.0, 0.0, 1.0)
    g = np.clip(x * d[..., None], 0.0, 1.0) ** (1.0 / RGBD_GAMMA)
    out = np.empty(x.shape[:-1] + (4,), dtype=np.uint8)
    out[..., :3] = np.round(g * 255.0)
    out[..., 3] = np.round(d * 255.0)
    return out, clamped


def rgbd_decode(rgbd: NDArray[np.uint8]) -> NDArray[np.float64]:
    """Babylon's ``fromRGBD``: ``(rgb / 255)^2.2 / (a / 255)``."""
    v = np.asarray(rgbd, dtype=np.float64) / 255.0
    return np.asarray(v[..., :3] ** RGBD_GAMMA / np.maximum(v[..., 3:], 1.0 / 255.0), dtype=np.float64)


def quaternion_z_to(d: Sequence[float]) -> list[float]:
    """The unit quaternion (x, y, z, w) that rotates +Z onto the unit vector ``d`` (shortest arc)."""
    v = np.asarray(d, dtype=np.float64)
    v = v / np.linalg.norm(v)
    c = float(v[2])  # cos of the angle between +Z and d
    if c < -1.0 + 1e-12:
        return [1.0, 0.0, 0.0, 0.0]  # a half turn about X
    axis = np.cross([0.0, 0.0, 1.0], v)
    w = math.sqrt(0.5 * (1.0 + c))
    q = np.array([*(axis / (2.0 * w)), w])
    return [float(x) for x in q / np.linalg.norm(q)]


def _pad(data: bytes, fill: bytes = b"\x00") -> bytes:
    return data + fill * (-len(data) % 4)


def write_glb(doc: dict[str, Any], bin_data: bytes) -> bytes:
    """A GLB 2.0 file: header, JSON chunk (space-padded), BIN chunk (zero-padded)."""
    js = _pad(json.dumps(doc, separators=(",", ":")).encode("utf-8"), b" ")
    chunks = struct.pack("<II", len(js), CHUNK_JSON) + js
    if bin_data:
        b = _pad(bin_data)
        chunks += struct.pack("<II", len(b), CHUNK_BIN) + b
    return struct.pack("<III", GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def gltf_lighting(levels: Sequence[NDArray[np.floating]], irradiance: Sequence[Sequence[float]],
                  sun: dict[str, Any] | None, *, into: bytes | None = None, ktx2: bytes | None = None,
                  generator: str = "relight") -> tuple[bytes, dict[str, Any]]:
    """The GLB (module docstring) of a chain (levels of (6, s, s, 3) faces) and its 9 x 3 irradiance
    coefficients; ``sun`` a ``relight.sun`` extract report or None; ``ktx2`` the same chain as a KTX2 file for
    ``KHR_lights_environment`` (left out when None). Returns (GLB bytes, summary)."""
    import imagecodecs

    from relight.mesh.gltf import split_glb

    if into is not None:
        doc, old_bin = split_glb(into, "--into")
        if any("uri" in b for b in doc.get("buffers", [])[:1]):
            raise InputError("--into: the GLB's first buffer is an external file (uri); only GLBs whose buffer 0 "
                             "is the embedded BIN chunk are supported")
        bin_parts = [_pad(old_bin or b"")]
    else:
        doc, bin_parts = {"asset": {"version": "2.0", "generator": generator}, "scenes": [{}], "scene": 0}, []
    offset = sum(len(p) for p in bin_parts)
    images, views = doc.setdefault("images", []), doc.setdefault("bufferViews", [])
    buffers = doc.setdefault("buffers", [])
    if not buffers:
        buffers.append({"byteLength": 0})
    clamped = 0
    spec_images: list[list[int]] = []
    for faces in levels:
        row = []
        for face in np.asarray(faces):
            rgbd, n = rgbd_encode(face)
            clamped += n
            png = bytes(imagecodecs.png_encode(np.ascontiguousarray(rgbd)))
            views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(png)})
            images.append({"bufferView": len(views) - 1, "mimeType": "image/png"})
            row.append(len(images) - 1)
            padded = _pad(png)
            bin_parts.append(padded)
            offset += len(padded)
        spec_images.append(row)
    env_view = None
    if ktx2 is not None:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(ktx2)})
        env_view = len(views) - 1
        bin_parts.append(_pad(ktx2))
        offset += len(bin_parts[-1])
    buffers[0]["byteLength"] = offset
    light = {"name": "relight", "intensity": 1.0, "rotation": [0.0, 0.0, 0.0, 1.0],
             "irradianceCoefficients": [[float(c) for c in rgb] for rgb in irradiance],
             "specularImageSize": int(np.asarray(levels[0]).shape[1]), "specularImages": spec_images}
    exts = doc.setdefault("extensions", {})
    ibl = exts.setdefault(EXT_IBL, {}).setdefault("lights", [])
    ibl.append(light)
    used = doc.setdefault("extensionsUsed", [])
    if EXT_IBL not in used:
        used.append(EXT_IBL)
    scenes = doc.setdefault("scenes", [{}])
    scene = scenes[int(doc.get("scene", 0))]
    scene.setdefault("extensions", {})[EXT_IBL] = {"light": len(ibl) - 1}
    summary: dict[str, Any] = {"images": len(levels) * 6, "levels": len(levels), "rgbd_clamped": clamped}
    if env_view is not None:
        env = exts.setdefault(KHR_ENV, {})
        env_images, env_textures = env.setdefault("images", []), env.setdefault("textures", [])
        env_lights = env.setdefault("lights", [])
        env_images.append({"name": "relight cube chain", "bufferView": env_view, "mimeType": "image/ktx2"})
        env_textures.append({"extensions": {KHR_KTX: {"source": len(env_images) - 1, "layer": 0}}})
        env_lights.append({"name": "relight", "luminanceFactor": 1.0,
                           "irradianceCoefficients": light["irradianceCoefficients"],
                           "boundingBoxMin": [-ENV_BOX] * 3, "boundingBoxMax": [ENV_BOX] * 3,
                           "cubemap": len(env_textures) - 1})
        scene["extensions"][KHR_ENV] = {"light": len(env_lights) - 1}
        for name in (KHR_ENV, KHR_KTX):
            if name not in used:
                used.append(name)
        summary["ktx2_bytes"] = len(ktx2 or b"")
    if sun is not None and sun.get("mode") == "extract":
        e = np.asarray(sun["irradiance_rgb"], dtype=np.float64)
        peak = float(e.max())
        if peak <= 0.0:
            raise InputError(f"the sun's irradiance must be positive to write a light, got {e.tolist()}")
        lights = exts.setdefault(KHR_PUNCTUAL, {}).setdefault("lights", [])
        lights.append({"name": "sun", "type": "directional", "color": [float(x) for x in e / peak],
                       "intensity": peak})
        nodes = doc.setdefault("nodes", [])
        # the light travels along the node's -Z: toward -direction, so +Z = direction
        nodes.append({"name": "sun", "rotation": quaternion_z_to(sun["direction"]),
                      "extensions": {KHR_PUNCTUAL: {"light": len(lights) - 1}}})
        scene.setdefault("nodes", []).append(len(nodes) - 1)
        if KHR_PUNCTUAL not in used:
            used.append(KHR_PUNCTUAL)
        summary["sun_node"] = len(nodes) - 1
    return write_glb(doc, b"".join(bin_parts)), summary
