"""Loading meshes: files (OBJ, glTF, GLB) and the samples, welded into relight's canonical form.

``load_mesh(path)`` picks the decoder from the first bytes (``glTF`` magic, a JSON object) or the suffix, decodes
under :class:`relight.mesh.model.Caps`, then :func:`build` welds, orders, computes normals and tangents and the
defects report. The samples are ``data/meshes/bunny.obj`` (1839 vertices), ``teapot.obj`` (792) and
``bunny-100k``: the bunny with every triangle split in four three times (``trimesh.remesh.subdivide``, midpoint
subdivision: the surface is unchanged, 1839 -> 116 K vertices), generated on the fly and deterministic, for timing
at the papers' scale (35 K-152 K vertices). :func:`sample_file` gives each sample as the file bytes the service
ingests (the generated one as a GLB); :func:`sniff` tells the formats apart from the first bytes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

import numpy as np

from relight import resources
from relight.errors import InputError
from relight.mesh import defects as defects_mod
from relight.mesh import tangents as tangents_mod
from relight.mesh.gltf import read_gltf_bytes
from relight.mesh.model import Caps, RawMesh, TriangleMesh, Weighting, check_positions, vertex_normals, weld
from relight.mesh.obj import read_obj_bytes

#: ``data/meshes``, package data of ``relight.data`` (:mod:`relight.resources`).
MESH_DIR: Final = resources.mesh_dir()
#: Sample meshes by name: (file, midpoint subdivisions).
SAMPLES: Final = {"bunny": ("bunny.obj", 0), "teapot": ("teapot.obj", 0), "bunny-100k": ("bunny.obj", 3)}


def build(raw: RawMesh, weighting: Weighting = "area") -> TriangleMesh:
    """Weld, order, and compute normals, tangents and the defects report (``relight.mesh.model``)."""
    pos = np.asarray(raw.positions, dtype=np.float64)
    f = np.asarray(raw.faces, dtype=np.intp)
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] == 0:
        raise InputError(f"{raw.source}: positions must be (n, 3), got shape {pos.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] == 0:
        raise InputError(f"{raw.source}: faces must be (m, 3), got shape {f.shape}")
    if f.min() < 0 or f.max() >= pos.shape[0]:
        bad = int(f.max()) if f.max() >= pos.shape[0] else int(f.min())
        raise InputError(f"{raw.source}: vertex index {bad} out of range for {pos.shape[0]} vertices")
    check_positions(pos, raw.source)
    w = weld(pos, f)
    if w.faces.shape[0] == 0:
        raise InputError(f"{raw.source}: every triangle collapses to a line or a point after welding")
    normals = vertex_normals(w.positions, w.faces, weighting)
    fn_len = np.linalg.norm(np.cross(w.positions[w.faces[:, 1]] - w.positions[w.faces[:, 0]],
                                     w.positions[w.faces[:, 2]] - w.positions[w.faces[:, 0]]), axis=1)
    has_area = np.zeros(w.positions.shape[0], dtype=bool)
    for k in range(3):
        has_area[w.faces[fn_len > 0.0, k]] = True
    zero = ~has_area
    if raw.tangents is not None:
        tangents, source = tangents_mod.file_tangents(normals, raw.tangents, w.vertex_of_input), "file"
    elif raw.corner_uvs is not None:
        uvs = np.take_along_axis(raw.corner_uvs[w.face_of_output], w.corner_of_output[:, :, None], axis=1)
        tangents, _ = tangents_mod.uv_tangents(w.positions, w.faces, normals, uvs)
        source = "uv"
    else:
        tangents, source = tangents_mod.field_tangents(normals), "field"
    report = defects_mod.report(w.positions, w.faces, input_vertices=w.input_vertices, input_faces=f.shape[0],
                                merged=w.merged_vertices, collapsed=w.collapsed_faces,
                                unreferenced=w.unreferenced_vertices, without_normal=int(zero.sum()))
    report["tangent_source"] = source
    report["normal_weighting"] = weighting
    return TriangleMesh(positions=w.positions, faces=w.faces, normals=normals, tangents=tangents,
                        tangent_source=source, defects=report, source=raw.source)


#: Bytes :func:`sniff` looks at.
SNIFF_BYTES: Final = 4096


def sniff(head: bytes) -> str | None:
    """The mesh format of a file from its first bytes: ``"glb"`` (magic ``glTF``), ``"gltf"`` (a JSON object),
    ``"obj"`` (text: no NUL byte, UTF-8 apart from a character cut at the end), else None."""
    if head[:4] == b"glTF":
        return "glb"
    text = head.lstrip()
    if text.startswith(b"{"):
        return "gltf"
    if b"\0" in head:
        return None
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 3:  # a multi-byte character cut by the sniff window is fine
            return None
    return "obj"


def decode(data: bytes, name: str, caps: Caps | None = None, base_dir: Path | None = None) -> RawMesh:
    """Decode mesh bytes: GLB by its magic, glTF JSON by a leading ``{`` or a ``.gltf`` name, else OBJ."""
    head = data[:64].lstrip()
    if data[:4] == b"glTF" or head.startswith(b"{") or name.lower().endswith((".gltf", ".glb")):
        return read_gltf_bytes(data, caps, name, base_dir)
    return read_obj_bytes(data, caps, name)


def load_mesh(path: str | Path, caps: Caps | None = None, weighting: Weighting = "area") -> TriangleMesh:
    """A mesh file (OBJ, glTF, GLB) or a sample name (:data:`SAMPLES`) as a :class:`TriangleMesh`."""
    if str(path) in SAMPLES:
        return sample_mesh(str(path), weighting)
    p = Path(path)
    caps = caps or Caps()
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise InputError(f"cannot read mesh {str(path)!r}: {exc.strerror}") from None
    caps.check_bytes(size, str(p))
    return build(decode(p.read_bytes(), str(p), caps, base_dir=p.parent), weighting)


def _subdivided(name: str, weighting: Weighting) -> RawMesh:
    filename, subdivisions = SAMPLES[name]
    raw = read_obj_bytes((MESH_DIR / filename).read_bytes(), name=filename)
    if not subdivisions:
        return raw
    import trimesh.remesh

    mesh = build(raw, weighting)
    v, f = mesh.positions, mesh.faces
    for _ in range(subdivisions):
        v, f = trimesh.remesh.subdivide(v, f)  # type: ignore[no-untyped-call]
    return RawMesh(positions=np.asarray(v, dtype=np.float64), faces=np.asarray(f, dtype=np.intp), source=name)


def sample_mesh(name: str, weighting: Weighting = "area") -> TriangleMesh:
    """A sample mesh (module docstring) by name."""
    if name not in SAMPLES:
        raise InputError(f"unknown sample mesh {name!r}; expected one of {', '.join(SAMPLES)}")
    return build(_subdivided(name, weighting), weighting)


def sample_file(name: str) -> tuple[str, bytes]:
    """A sample as the file the service ingests like any upload: ``(file name, bytes)`` — the OBJ itself, or for
    a subdivided sample a GLB of the subdivided (unwelded, float32) triangles, generated deterministically (the
    same bytes, hence the same id, on every machine with the same NumPy and trimesh)."""
    if name not in SAMPLES:
        raise InputError(f"unknown sample mesh {name!r}; expected one of {', '.join(SAMPLES)}")
    filename, subdivisions = SAMPLES[name]
    if not subdivisions:
        return filename, (MESH_DIR / filename).read_bytes()
    from relight.mesh.gltf import write_glb

    raw = _subdivided(name, "area")
    return f"{name}.glb", write_glb(raw.positions, raw.faces)
