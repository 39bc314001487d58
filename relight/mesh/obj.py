"""Wavefront OBJ decoding under caps (``v``, ``vt`` and ``f`` records; everything else is ignored).

Caps (``relight.mesh.model.Caps``) are checked before anything is parsed: the byte count, then the numbers of ``v``
and ``f`` records counted on the raw bytes (a fanned polygon of k corners adds k - 2 triangles; the triangle cap is
checked again once the polygons are known, still before any array is built). Errors name the line: a record with
too few numbers (a truncated file), an unparsable or non-finite number, an index 0 or out of range (OBJ indices
start at 1; negative ones count back from the last vertex read).
"""

from __future__ import annotations

import re

import numpy as np

from relight import validate
from relight.errors import InputError
from relight.mesh.model import Caps, RawMesh, check_positions

_V_RECORD = re.compile(rb"^v[ \t]", re.MULTILINE)
_F_RECORD = re.compile(rb"^f[ \t]", re.MULTILINE)


def _index(token: str, n: int, what: str) -> int:
    i = int(token)
    if i == 0 or i > n or i < -n:
        raise InputError(f"{what}: index {i} out of range (1..{n}, or -{n}..-1)")
    return i - 1 if i > 0 else n + i


def read_obj_bytes(data: bytes, caps: Caps | None = None, name: str = "<obj>") -> RawMesh:
    """Decode an OBJ file's bytes (module docstring) into a :class:`RawMesh`."""
    caps = caps or Caps()
    caps.check_bytes(len(data), name)
    caps.check_counts(len(_V_RECORD.findall(data)), len(_F_RECORD.findall(data)), name)
    verts: list[list[float]] = []
    uvs: list[list[float]] = []
    faces: list[list[int]] = []
    face_uvs: list[list[int]] = []
    every_corner_has_uv = True
    text = data.decode("utf-8", errors="replace")
    for lineno, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] not in ("v", "vt", "f"):
            continue
        where = f"{name}:{lineno}"
        try:
            if parts[0] == "v":
                if len(parts) < 4:
                    raise InputError(f"{where}: a vertex needs 3 coordinates, got {line.strip()!r} (truncated?)")
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "vt":
                if len(parts) < 3:
                    raise InputError(f"{where}: a texture coordinate needs u and v, got {line.strip()!r}")
                uvs.append([float(x) for x in parts[1:3]])
            else:
                if len(parts) < 4:
                    raise InputError(f"{where}: a face needs at least 3 corners, got {line.strip()!r} (truncated?)")
                corners = [tok.split("/") for tok in parts[1:]]
                idx = [_index(c[0], len(verts), where) for c in corners]
                if every_corner_has_uv and all(len(c) > 1 and c[1] for c in corners):
                    t = [_index(c[1], len(uvs), where) for c in corners]
                    face_uvs.extend([t[0], t[k], t[k + 1]] for k in range(1, len(t) - 1))
                else:
                    every_corner_has_uv = False
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
                if len(faces) > caps.max_faces:
                    caps.check_counts(len(verts), len(faces), name)
        except ValueError as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"{where}: cannot parse {line.strip()!r}") from None
    if not verts or not faces:
        raise InputError(f"{name}: no triangles ({len(verts)} vertices, {len(faces)} faces)")
    positions = np.asarray(verts, dtype=np.float64)
    check_positions(positions, name)
    f = np.asarray(faces, dtype=np.intp)
    corner_uvs = None
    if every_corner_has_uv and uvs:
        uv = np.asarray(uvs, dtype=np.float64)
        validate.finite_array(f"{name}: texture coordinates", uv)
        corner_uvs = uv[np.asarray(face_uvs, dtype=np.intp)]
    return RawMesh(positions=positions, faces=f, corner_uvs=corner_uvs, source=name)
