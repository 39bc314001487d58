"""Per-vertex tangent frames of a welded mesh (``docs/conventions.md``, "Meshes").

A tangent is ``(t_x, t_y, t_z, w)``: ``t`` a unit vector orthogonal to the vertex normal N, ``w = +-1`` the
handedness, with the bitangent ``B = w (N x T)`` (glTF 2.0 §3.7.2.1, the MikkTSpace convention). Three sources, in
this order of preference (``TriangleMesh.tangent_source`` records which one was used):

1. ``"file"`` — glTF ``TANGENT`` attributes: the xyz of the file vertices welded into one vertex are summed, then
   Gram–Schmidt-orthogonalised against N; ``w`` is the sign of the summed file ``w`` (the file's handedness; +1 on
   a tie).
2. ``"uv"`` — texture coordinates (OBJ ``vt`` or glTF ``TEXCOORD_0``), per face corner: each face's ``dP/du`` and
   ``dP/dv`` (Lengyel 2001, "Computing tangent space basis vectors for an arbitrary mesh") weighted by the face
   area are summed at its vertices, ``T = normalize(S - (N.S) N)``, ``w = sign((N x T) . B_uv)``. Faces with a
   degenerate UV triangle contribute nothing.
3. ``"field"`` — neither (or a vertex that got no usable UV contribution): ``T = normalize(+Y x N)``, +X where
   N = +-Y, ``w = +1`` — ``relight.shrm.tangent_field``, the field of Kajiya–Kay lobes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from relight.shrm import tangent_field

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.intp]


def _orthonormal(t: FloatArray, normals: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Gram–Schmidt of ``t`` against N, normalised; the mask says where the result is usable."""
    t = t - np.einsum("ij,ij->i", t, normals)[:, None] * normals
    norm = np.linalg.norm(t, axis=1)
    ok = norm > 1e-12
    return t / np.where(ok, norm, 1.0)[:, None], ok


def field_tangents(normals: FloatArray) -> FloatArray:
    """Source 3: ``(normalize(+Y x N), +1)`` (module docstring), (V, 4)."""
    t = tangent_field(normals)
    return np.concatenate([t, np.ones((t.shape[0], 1))], axis=1)


def file_tangents(normals: FloatArray, tangents_in: FloatArray, vertex_of_input: IndexArray) -> FloatArray:
    """Source 1: welded glTF tangents (module docstring); vertices left without one fall back to the field."""
    v = normals.shape[0]
    keep = vertex_of_input >= 0
    s = np.zeros((v, 3))
    w = np.zeros(v)
    np.add.at(s, vertex_of_input[keep], tangents_in[keep, :3])
    np.add.at(w, vertex_of_input[keep], tangents_in[keep, 3])
    t, ok = _orthonormal(s, normals)
    out = field_tangents(normals)
    out[ok, :3] = t[ok]
    out[ok, 3] = np.where(w[ok] < 0.0, -1.0, 1.0)
    return out


def uv_tangents(positions: FloatArray, faces: IndexArray, normals: FloatArray,
                corner_uvs: FloatArray) -> tuple[FloatArray, int]:
    """Source 2 (module docstring): tangents from per-corner texture coordinates (F, 3, 2) of the canonical faces,
    and the number of vertices that fell back to the field."""
    p = positions[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = corner_uvs[:, 1] - corner_uvs[:, 0], corner_uvs[:, 2] - corner_uvs[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    good = np.abs(det) > 1e-20
    r = np.where(good, 1.0 / np.where(good, det, 1.0), 0.0)[:, None]
    # Lengyel: [T; B] = 1/det [dv2 -dv1; -du2 du1] [E1; E2]; weight by the area = |e1 x e2| / 2
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)[:, None]
    tu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    tv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r
    tu_n = tu / np.maximum(np.linalg.norm(tu, axis=1, keepdims=True), 1e-300) * area
    tv_n = tv / np.maximum(np.linalg.norm(tv, axis=1, keepdims=True), 1e-300) * area
    s = np.zeros_like(normals)
    b = np.zeros_like(normals)
    for k in range(3):
        np.add.at(s, faces[:, k], tu_n)
        np.add.at(b, faces[:, k], tv_n)
    t, ok = _orthonormal(s, normals)
    out = field_tangents(normals)
    out[ok, :3] = t[ok]
    handed = np.einsum("ij,ij->i", np.cross(normals[ok], t[ok]), b[ok])
    out[ok, 3] = np.where(handed < 0.0, -1.0, 1.0)
    return out, int(np.count_nonzero(~ok))
