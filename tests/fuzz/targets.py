"""Fuzz targets: every parser that sees a client's bytes, called the way the service calls it, with the one rule
the service relies on (issue 12, item 8): **a parser either returns or raises an error the service answers
with a 422**. Anything else (an ``IndexError`` out of a decoder, a ``struct.error``, a ``MemoryError``, a
recursion overflow) is a crash: the upload would become a 500 or a failed job with a Python message.

* ``exr``, ``rgbe``, ``png``, ``jpeg`` — the upload path of ``POST /envmaps``: the header probe
  (``relight.envmap.probe``, in the server), the pixel limit on every part and level (``check_max_pixels``), then
  the worker's decode (``read_envmap``); only :class:`relight.errors.InputError` is a 422.
* ``obj``, ``gltf`` — ``POST /meshes``: ``relight.mesh.decode`` under caps and ``build`` (weld, normals); the
  worker maps ``InputError`` and the malformed-file errors in :data:`MESH_ERRORS` to a 422
  (:func:`relight.worker.meshes.analyze_mesh`).
* ``brdf`` — a BRDF spec string from a client: ``check_client_string`` (no file-naming specs), then
  ``parse_brdf``; ``InputError``.
* ``merl`` — ``POST /brdfs/measured``: ``read_merl`` on a file of the exact MERL size whose first 12 bytes and
  sample values come from the input (the values repeat to fill the 35 MB).
* ``scene`` — ``POST /scenes``: the JSON body through ``SceneCreate`` (pydantic's ``ValidationError`` is the 422).

Each target has a seed corpus of small valid files made here (no binary test data in the repository).
"""

from __future__ import annotations

import io
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from relight.errors import InputError

#: The pixel limit the targets decode under: a mutated header may declare anything; the probe must refuse what is
#: over the limit before the decoder allocates (the service's limit is larger; small keeps a fuzz run fast).
MAX_PIXELS: Final = 64 * 128
#: Mesh caps of the targets (small for the same reason).
MESH_BYTES, MESH_VERTICES, MESH_FACES = 1 << 16, 4096, 8192
#: What the mesh worker maps to a 422 besides InputError (relight.worker.meshes.analyze_mesh).
MESH_ERRORS: Final = (ValueError, KeyError, IndexError, TypeError, AttributeError, OverflowError, RecursionError,
                      MemoryError, struct.error)


class Crash(AssertionError):
    """A parser raised something the service would not answer with a 422."""


@dataclass(frozen=True)
class Target:
    name: str
    call: Callable[[bytes], Any]
    allowed: tuple[type[BaseException], ...]
    seeds: Callable[[], list[bytes]]

    def run(self, data: bytes) -> None:
        """Call the parser on ``data``; raise :class:`Crash` (chained to the cause) unless it returns or raises an
        allowed error."""
        try:
            self.call(data)
        except self.allowed:
            return
        except Exception as exc:  # noqa: BLE001 - that is the finding
            raise Crash(f"{self.name}: {type(exc).__name__}: {exc}"[:2000]) from exc


# ------------------------------------------------------------------------------------------------ images
def decode_image(data: bytes) -> None:
    from relight.envmap import probe
    from relight.envmap.environment import read_envmap
    from relight.envmap.formats import check_max_pixels

    header = probe(data)
    check_max_pixels(header, MAX_PIXELS)
    read_envmap(data, max_pixels=MAX_PIXELS)


def _image(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.asarray(rng.random((h, w, 3)) * np.array([1.0, 4.0, 50.0]), dtype=np.float32)


def _written(write: Callable[[Path], None], suffix: str) -> bytes:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"seed{suffix}"
        write(p)
        return p.read_bytes()


def exr_seeds() -> list[bytes]:
    from relight.envmap import write_exr, write_exr_layers

    img = _image(8, 16, 1)
    seeds = [_written(lambda p, c=c: write_exr(p, img, compression=c), ".exr")
             for c in ("none", "zip", "zips", "rle", "piz", "pxr24", "b44", "dwaa")]
    seeds.append(_written(lambda p: write_exr(p, img, half=True), ".exr"))
    seeds.append(_written(lambda p: write_exr_layers(p, {"sky": img}), ".exr"))  # one named RGB layer
    return seeds


def rgbe_seeds() -> list[bytes]:
    from relight.envmap import write_hdr

    # 16 x 32: scanlines of width >= 8 are run-length encoded, so the RLE decoder is in the corpus
    return [_written(lambda p: write_hdr(p, _image(16, 32, 2)), ".hdr"),
            _written(lambda p: write_hdr(p, _image(4, 8, 3)), ".hdr")]


def _pillow(fmt: str, mode: str) -> bytes:
    from PIL import Image

    arr = (np.linspace(0, 255, 16 * 32 * 3).reshape(16, 32, 3)).astype(np.uint8)
    img = Image.fromarray(arr, "RGB").convert(mode)
    buf = io.BytesIO()
    img.save(buf, format=fmt)
    return buf.getvalue()


def png_seeds() -> list[bytes]:
    import imagecodecs

    sixteen = (np.linspace(0, 65535, 8 * 16 * 3).reshape(8, 16, 3)).astype(np.uint16)
    return [_pillow("PNG", "RGB"), _pillow("PNG", "L"), _pillow("PNG", "RGBA"), bytes(imagecodecs.png_encode(sixteen))]


def jpeg_seeds() -> list[bytes]:
    return [_pillow("JPEG", "RGB"), _pillow("JPEG", "L")]


# ------------------------------------------------------------------------------------------------ meshes
def decode_mesh(name: str) -> Callable[[bytes], None]:
    def call(data: bytes) -> None:
        from relight.mesh import Caps, build, decode

        build(decode(data, name, Caps(max_bytes=MESH_BYTES, max_vertices=MESH_VERTICES, max_faces=MESH_FACES)))

    return call


def decode_any_mesh(data: bytes) -> None:
    from relight.mesh import sniff

    fmt = sniff(data[:4096])
    decode_mesh("mesh.glb" if fmt == "glb" else "mesh.gltf")(data)


OBJ_SEED = b"""# a tetrahedron with normals and texture coordinates
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vt 0 0
vt 1 0
vt 0 1
vn 0 0 1
f 1/1/1 3/3/1 2/2/1
f 1//1 2//1 4//1
f 1 4 3
f -3 -2 -1
o second
v 2 2 2
v 3 2 2
v 2 3 2
f 5 6 7
"""


def obj_seeds() -> list[bytes]:
    return [OBJ_SEED, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4\n"]


def gltf_seeds() -> list[bytes]:
    import base64
    import json

    from relight.mesh.gltf import write_glb

    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.uint32)
    glb = write_glb(pos, faces)
    blob = pos.tobytes() + faces.astype(np.uint16).tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [1, 0, 0], "scale": [2, 2, 2]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 24}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 1]},
                      {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}],
    }
    return [glb, json.dumps(doc).encode()]


# ------------------------------------------------------------------------------------------------ BRDFs, scenes
def parse_brdf_string(data: bytes) -> None:
    from relight.brdf.spec import parse_brdf
    from relight.worker.specs import check_client_string

    text = data.decode("utf-8", errors="replace")
    parse_brdf(check_client_string(text))


def brdf_seeds() -> list[bytes]:
    return [s.encode() for s in (
        "lambert", "phong:s=32", "microfacet:sigma=0.2", "torrance-sparrow:alpha=0.2,fresnel=none", "ggx:alpha=0.3",
        "blinn-phong:s=64", "lafortune:preset=skin", "oren-nayar:sigma=0.3", "kajiya-kay:s=32",
        "lambert:albedo=0.5+phong:s=200", "ward:alpha=0.2,rho_d=0.5,rho_s=0.1",
    )]


def read_merl_bytes(data: bytes) -> None:
    from relight.brdf.measured import MERL_FILE_BYTES, read_merl

    head, body = data[:12], data[12:]
    body = body[: len(body) - len(body) % 8] or b"\0" * 8
    reps = -(-(MERL_FILE_BYTES - len(head)) // len(body))
    content = (head + body * reps)[:MERL_FILE_BYTES]
    with tempfile.NamedTemporaryFile(suffix=".binary", dir=_fast_tmp()) as fh:
        fh.write(content)
        fh.flush()
        read_merl(fh.name)


def _fast_tmp() -> str | None:
    return "/dev/shm" if Path("/dev/shm").is_dir() else None


def merl_seeds() -> list[bytes]:
    return [struct.pack("<3i", 90, 90, 180) + struct.pack("<4d", 0.1, 0.2, 0.05, 0.3),
            struct.pack("<3i", 90, 90, 180) + struct.pack("<2d", -1.0, 0.5)]


def validate_scene(data: bytes) -> None:
    from relight.contract.scenes import SceneCreate

    SceneCreate.model_validate_json(data)


def scene_seeds() -> list[bytes]:
    import json

    env = "a" * 64
    return [json.dumps(doc).encode() for doc in (
        {"environment": env, "epsilon": 0.05, "size": 16, "objects": [
            {"name": "chalk", "size": 1, "distance": 10, "material": "lambert:albedo=0.7"},
            {"shape": "bunny", "size": 0.5, "distance": 3, "material": {"kind": "phong", "s": 32},
             "view": [0, 0, 1]}]},
        {"environment": env, "time_budget_s": 2, "objects": [{"size": 1, "distance": 2, "material": "ggx:alpha=0.3"}]},
    )]


def _validation_error() -> type[BaseException]:
    from pydantic import ValidationError

    return ValidationError


TARGETS: Final[dict[str, Target]] = {
    "exr": Target("exr", decode_image, (InputError,), exr_seeds),
    "rgbe": Target("rgbe", decode_image, (InputError,), rgbe_seeds),
    "png": Target("png", decode_image, (InputError,), png_seeds),
    "jpeg": Target("jpeg", decode_image, (InputError,), jpeg_seeds),
    "obj": Target("obj", decode_mesh("mesh.obj"), MESH_ERRORS, obj_seeds),
    "gltf": Target("gltf", decode_any_mesh, MESH_ERRORS, gltf_seeds),
    "brdf": Target("brdf", parse_brdf_string, (InputError,), brdf_seeds),
    "merl": Target("merl", read_merl_bytes, (InputError,), merl_seeds),
    "scene": Target("scene", validate_scene, (_validation_error(),), scene_seeds),
}


# ------------------------------------------------------------------------------------------------ replay
def mutations(seed: bytes, n: int, rng: np.random.Generator) -> list[bytes]:
    """``n`` deterministic mutants of ``seed``: byte flips, interesting values (0, 0xff, 0x7f, 0x80) written over
    bytes, truncations, duplicated and deleted spans (what a fuzzer tries first)."""
    out = []
    size = len(seed)
    for _ in range(n):
        buf = bytearray(seed)
        op = rng.integers(5)
        i = int(rng.integers(size)) if size else 0
        if op == 0 and size:
            buf[i] ^= 1 << int(rng.integers(8))
        elif op == 1 and size:
            for k in range(int(rng.integers(1, 5))):
                if i + k < size:
                    buf[i + k] = int(rng.choice([0, 0xFF, 0x7F, 0x80]))
        elif op == 2:
            buf = buf[:i]
        elif op == 3:
            j = min(size, i + int(rng.integers(1, 64)))
            buf[i:i] = buf[i:j]
        else:
            del buf[i:i + int(rng.integers(1, 64))]
        out.append(bytes(buf))
    return out
