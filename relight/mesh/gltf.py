"""glTF 2.0 (``.gltf`` JSON and binary ``.glb``) decoding under caps (Khronos glTF 2.0 specification).

Order of checks, all before any vertex is decoded:

1. the byte count (``Caps.max_bytes``);
2. GLB: magic ``glTF``, version 2, the header's total length equal to the file's (a lying header is refused), chunk
   lengths inside the file, a JSON chunk first (§4.4);
3. ``extensionsRequired`` empty (Draco and meshopt compression are not decoded), triangle primitives only (mode 4);
4. the declared counts: the POSITION accessors' ``count`` summed over every drawn primitive instance against
   ``Caps.max_vertices``, the indices' ``count / 3`` against ``Caps.max_faces`` — a file declaring 10^8 faces is
   refused here, whatever its buffers hold;
5. every accessor's byte range inside its buffer view, every view inside its buffer, every buffer's declared
   ``byteLength`` no longer than the bytes actually present.

Drawn primitives are those of the meshes instanced by the nodes of the default scene (``scene``, else scene 0),
with the nodes' world transforms applied (``matrix`` or TRS, §3.5.2; a mirroring transform flips the triangles'
winding and the tangents' w); a file without scenes draws every mesh once, untransformed. Buffers are the GLB
``BIN`` chunk, base64 ``data:`` URIs, or (only when a ``base_dir`` is given) files inside that directory.
Attributes read: ``POSITION``, ``TEXCOORD_0`` (per-corner texture coordinates for ``relight.mesh.tangents``),
``TANGENT``; ``NORMAL`` is ignored (``relight.mesh.model``).
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError
from relight.mesh.model import Caps, RawMesh, check_positions

FloatArray = NDArray[np.float64]

GLB_MAGIC: Final = 0x46546C67  # b"glTF" little-endian (§4.4.3)
CHUNK_JSON: Final = 0x4E4F534A
CHUNK_BIN: Final = 0x004E4942
#: componentType -> numpy dtype (§3.6.2.2)
COMPONENT: Final = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTH: Final = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
TRIANGLES: Final = 4


def split_glb(data: bytes, name: str) -> tuple[dict[str, Any], bytes | None]:
    """The JSON document and the BIN chunk of a GLB file (checks of step 2)."""
    if len(data) < 20:
        raise InputError(f"{name}: {len(data)} bytes is too short for a GLB file")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != GLB_MAGIC:
        raise InputError(f"{name}: not a GLB file (magic {magic:#010x})")
    if version != 2:
        raise InputError(f"{name}: GLB version {version} is not supported (only 2)")
    if length != len(data):
        raise InputError(f"{name}: the GLB header declares {length} bytes but the file has {len(data)}")
    chunks: list[tuple[int, bytes]] = []
    pos = 12
    while pos < length:
        if pos + 8 > length:
            raise InputError(f"{name}: truncated GLB chunk header at byte {pos}")
        clen, ctype = struct.unpack_from("<II", data, pos)
        if pos + 8 + clen > length:
            raise InputError(f"{name}: GLB chunk at byte {pos} declares {clen} bytes, past the end of the file")
        chunks.append((ctype, data[pos + 8 : pos + 8 + clen]))
        pos += 8 + clen
    if not chunks or chunks[0][0] != CHUNK_JSON:
        raise InputError(f"{name}: the first GLB chunk must be JSON")
    bin_chunk = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == CHUNK_BIN else None
    return _json(chunks[0][1], name), bin_chunk


def _json(raw: bytes, name: str) -> dict[str, Any]:
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{name}: invalid glTF JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{name}: the glTF JSON must be an object")
    return doc


def _item(doc: dict[str, Any], key: str, i: Any, name: str) -> dict[str, Any]:
    items = doc.get(key, [])
    if not isinstance(i, int) or not isinstance(items, list) or not 0 <= i < len(items) or not isinstance(
            items[i], dict):
        raise InputError(f"{name}: {key}[{i}] does not exist")
    item: dict[str, Any] = items[i]
    return item


def _local_matrix(node: dict[str, Any]) -> FloatArray:
    if "matrix" in node:
        m = np.asarray(node["matrix"], dtype=np.float64)
        if m.shape != (16,):
            raise InputError(f"a node matrix needs 16 numbers, got {m.shape}")
        return m.reshape(4, 4).T  # column-major in the file
    t = np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float64)
    x, y, z, w = np.asarray(node.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
    s = np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r * s[None, :]
    m[:3, 3] = t
    return m


def instances(doc: dict[str, Any], name: str) -> list[tuple[int, FloatArray]]:
    """(mesh index, world matrix) of every drawn mesh instance (module docstring)."""
    scenes = doc.get("scenes")
    if not scenes:
        return [(i, np.eye(4)) for i in range(len(doc.get("meshes", [])))]
    scene = _item(doc, "scenes", doc.get("scene", 0), name)
    out: list[tuple[int, FloatArray]] = []
    stack = [(n, np.eye(4), 0) for n in scene.get("nodes", [])]
    n_nodes = len(doc.get("nodes", []))
    while stack:
        i, parent, depth = stack.pop()
        if depth > n_nodes:
            raise InputError(f"{name}: the node hierarchy has a cycle")
        node = _item(doc, "nodes", i, name)
        world = parent @ _local_matrix(node)
        if "mesh" in node:
            _item(doc, "meshes", node["mesh"], name)
            out.append((int(node["mesh"]), world))
        stack.extend((c, world, depth + 1) for c in node.get("children", []))
    return out


class _Accessors:
    """Accessor decoding with the range checks of step 5."""

    def __init__(self, doc: dict[str, Any], buffers: list[bytes], name: str) -> None:
        self.doc, self.buffers, self.name = doc, buffers, name

    def count(self, i: int) -> int:
        acc = _item(self.doc, "accessors", i, self.name)
        c = acc.get("count")
        if not isinstance(c, int) or c < 0:
            raise InputError(f"{self.name}: accessors[{i}] has an invalid count {c!r}")
        return c

    def check(self, i: int) -> None:
        acc = _item(self.doc, "accessors", i, self.name)
        if "sparse" in acc:
            raise InputError(f"{self.name}: sparse accessors (accessors[{i}]) are not supported")
        if acc.get("componentType") not in COMPONENT or acc.get("type") not in WIDTH:
            raise InputError(f"{self.name}: accessors[{i}] has componentType {acc.get('componentType')!r} / type "
                             f"{acc.get('type')!r}")
        view = _item(self.doc, "bufferViews", acc.get("bufferView"), self.name)
        buf = view.get("buffer")
        if not isinstance(buf, int) or not 0 <= buf < len(self.buffers):
            raise InputError(f"{self.name}: bufferView of accessors[{i}] names buffer {buf!r}")
        item = np.dtype(COMPONENT[acc["componentType"]]).itemsize * WIDTH[acc["type"]]
        stride = int(view.get("byteStride", item))
        count = self.count(i)
        end = int(acc.get("byteOffset", 0)) + (stride * (count - 1) + item if count else 0)
        vlen, voff = int(view.get("byteLength", -1)), int(view.get("byteOffset", 0))
        if stride < item or end > vlen or vlen < 0 or voff < 0 or voff + vlen > len(self.buffers[buf]):
            raise InputError(f"{self.name}: accessors[{i}] ({count} x {acc['type']}) does not fit its buffer view "
                             f"(needs {end} bytes of {vlen}; view at {voff} in a buffer of "
                             f"{len(self.buffers[buf])} bytes)")

    def read(self, i: int) -> FloatArray:
        self.check(i)
        acc = _item(self.doc, "accessors", i, self.name)
        view = _item(self.doc, "bufferViews", acc["bufferView"], self.name)
        dtype = np.dtype(COMPONENT[acc["componentType"]])
        width = WIDTH[acc["type"]]
        stride = int(view.get("byteStride", dtype.itemsize * width))
        count = self.count(i)
        raw = self.buffers[view["buffer"]]
        start = int(view.get("byteOffset", 0)) + int(acc.get("byteOffset", 0))
        arr = np.ndarray((count, width), dtype=dtype, buffer=raw, offset=start, strides=(stride, dtype.itemsize))
        out = arr.astype(np.float64)
        if acc.get("normalized") and dtype.kind in "iu":
            out /= float(np.iinfo(dtype).max)
        return out


def _buffers(doc: dict[str, Any], bin_chunk: bytes | None, base_dir: Path | None, name: str) -> list[bytes]:
    out = []
    for k, b in enumerate(doc.get("buffers", [])):
        uri = b.get("uri") if isinstance(b, dict) else None
        if uri is not None and not isinstance(uri, str):
            raise InputError(f"{name}: buffers[{k}].uri must be a string, not {type(uri).__name__}")
        if uri is None:
            if bin_chunk is None:
                raise InputError(f"{name}: buffers[{k}] has no uri and there is no GLB BIN chunk")
            raw = bin_chunk
        elif uri.startswith("data:"):
            try:
                raw = base64.b64decode(uri.split(",", 1)[1], validate=True)
            except (IndexError, ValueError):
                raise InputError(f"{name}: buffers[{k}] has an invalid data URI") from None
        elif base_dir is not None and "/" not in uri and "\\" not in uri and not uri.startswith("."):
            raw = (base_dir / uri).read_bytes()
        else:
            raise InputError(f"{name}: buffers[{k}] refers to an external file {uri!r} (only embedded data)")
        declared = b.get("byteLength")
        if not isinstance(declared, int) or declared > len(raw):
            raise InputError(f"{name}: buffers[{k}] declares {declared!r} bytes but holds {len(raw)}")
        out.append(raw)
    return out


def read_gltf_bytes(data: bytes, caps: Caps | None = None, name: str = "<gltf>",
                    base_dir: Path | None = None) -> RawMesh:
    """Decode a ``.glb`` or ``.gltf`` file's bytes (module docstring) into a :class:`RawMesh`."""
    caps = caps or Caps()
    caps.check_bytes(len(data), name)
    if data[:4] == b"glTF":
        doc, bin_chunk = split_glb(data, name)
    else:
        doc, bin_chunk = _json(data, name), None
    required = doc.get("extensionsRequired") or []
    if required:
        raise InputError(f"{name}: required glTF extensions {required} are not supported")
    prims: list[tuple[dict[str, Any], FloatArray]] = []
    for mesh_id, world in instances(doc, name):
        primitives = _item(doc, "meshes", mesh_id, name).get("primitives", [])
        if not isinstance(primitives, list) or not all(isinstance(p, dict) and isinstance(p.get("attributes", {}),
                                                                                      dict) for p in primitives):
            raise InputError(f"{name}: meshes[{mesh_id}].primitives must be a list of objects with attributes")
        for p in primitives:
            if p.get("mode", TRIANGLES) != TRIANGLES:
                raise InputError(f"{name}: meshes[{mesh_id}] has a primitive of mode {p.get('mode')} (only "
                                 f"triangles, mode 4)")
            if "POSITION" not in p.get("attributes", {}):
                raise InputError(f"{name}: meshes[{mesh_id}] has a primitive without POSITION")
            prims.append((p, world))
    if not prims:
        raise InputError(f"{name}: no triangle primitives")
    # step 4: declared counts, before any buffer is decoded
    acc = _Accessors(doc, [], name)
    n_vert = sum(acc.count(p["attributes"]["POSITION"]) for p, _ in prims)
    n_face = sum((acc.count(p["indices"]) if "indices" in p else acc.count(p["attributes"]["POSITION"])) // 3
                 for p, _ in prims)
    caps.check_counts(n_vert, n_face, name)
    acc = _Accessors(doc, _buffers(doc, bin_chunk, base_dir, name), name)
    positions, faces, uvs, tangents = [], [], [], []
    have_uv = all("TEXCOORD_0" in p["attributes"] for p, _ in prims)
    have_tan = all("TANGENT" in p["attributes"] for p, _ in prims)
    offset = 0
    for p, world in prims:
        attrs = p["attributes"]
        pos = acc.read(attrs["POSITION"])[:, :3]
        m3 = world[:3, :3]
        mirror = float(np.linalg.det(m3)) < 0.0
        pos = pos @ m3.T + world[:3, 3]
        n = pos.shape[0]
        idx = acc.read(p["indices"])[:, 0].astype(np.int64) if "indices" in p else np.arange(n - n % 3)
        if idx.size % 3:
            raise InputError(f"{name}: a triangle primitive has {idx.size} indices (not a multiple of 3)")
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise InputError(f"{name}: index {int(idx.max())} out of range for a primitive of {n} vertices")
        tri = idx.reshape(-1, 3)
        if mirror:
            tri = tri[:, ::-1]
        if have_uv:
            uvs.append(acc.read(attrs["TEXCOORD_0"])[:, :2][tri])
        if have_tan:
            t = acc.read(attrs["TANGENT"])
            if t.shape[1] != 4:
                raise InputError(f"{name}: TANGENT must be VEC4, got {t.shape[1]} components")
            t[:, :3] = t[:, :3] @ m3.T
            t[:, 3] *= -1.0 if mirror else 1.0
            tangents.append(t)
        positions.append(pos)
        faces.append(tri + offset)
        offset += n
    all_pos = np.concatenate(positions)
    check_positions(all_pos, name)
    return RawMesh(positions=all_pos, faces=np.concatenate(faces).astype(np.intp),
                   corner_uvs=np.concatenate(uvs) if have_uv else None,
                   tangents=np.concatenate(tangents) if have_tan else None, source=name)


def write_glb(positions: NDArray[np.floating], faces: NDArray[np.integer]) -> bytes:
    """A minimal GLB 2.0 file (one mesh, one node, one triangle primitive: float32 ``POSITION`` with its min/max,
    uint32 indices) — how the generated sample meshes are stored as uploads, and a writer for tests."""
    pos = np.ascontiguousarray(positions, dtype="<f4")
    idx = np.ascontiguousarray(faces, dtype="<u4")
    pos_bytes, idx_bytes = pos.tobytes(), idx.tobytes()
    binary = pos_bytes + idx_bytes
    doc = {
        "asset": {"version": "2.0", "generator": "relight"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": TRIANGLES}]}],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos_bytes)},
                        {"buffer": 0, "byteOffset": len(pos_bytes), "byteLength": len(idx_bytes)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": int(pos.shape[0]), "type": "VEC3",
             "min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()},
            {"bufferView": 1, "componentType": 5125, "count": int(idx.size), "type": "SCALAR"}],
    }
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)  # chunks are 4-byte aligned (§4.4.3.1): JSON padded with spaces, BIN with zeros
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<III", GLB_MAGIC, 2, total) + struct.pack("<II", len(js), CHUNK_JSON) + js
            + struct.pack("<II", len(binary), CHUNK_BIN) + binary)
