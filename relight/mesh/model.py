"""Triangle meshes as relight stores them: welded positions in one canonical vertex order, normals and tangents.

Every per-vertex quantity relight computes (visibility, transfer vectors and matrices, ``relight.visibility``) refers
to the vertices of a :class:`TriangleMesh` in the order fixed here, so the order must not depend on how a file
happened to list them (``docs/conventions.md``, "Meshes"):

1. **Welding.** Positions are quantised to a grid of step ``WELD_FRACTION`` x the bounding-box diagonal and equal
   cells are merged (file vertices split only by normals or texture coordinates become one vertex).
2. **Canonical order.** The welded vertices are sorted lexicographically by their quantised (x, y, z) (what
   ``np.unique(axis=0)`` returns); every face is rotated so that its smallest index comes first (orientation kept)
   and the faces are sorted lexicographically. Re-ordering the vertices or faces of a file leaves the result
   unchanged (tested).
3. **Faces** whose corners weld together (a repeated index) are dropped and counted; vertices no face uses are
   dropped and counted (``relight.mesh.defects``).
4. **Normals** (:func:`vertex_normals`): the sum of the face normals around a vertex weighted by the face area
   (default; the sum of the unnormalised cross products, like ``relight.gl.mesh`` and three.js) or by the corner
   angle (Thürrner & Wüthrich 1998). Normals given in the file are ignored: after welding they are ambiguous at
   seams, and relight's own are what Mitsuba is given as ``vn`` (``relight.mitsuba_mesh``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final, Literal

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.intp]

#: Welding grid step as a fraction of the bounding-box diagonal (float32 files resolve ~1e-7 of their extent, so
#: vertices meant to coincide differ by far less; distinct vertices of a 10^6-triangle mesh are ~1e-3 apart).
WELD_FRACTION: Final = 1e-7

Weighting = Literal["area", "angle"]


@dataclass(frozen=True)
class Caps:
    """Limits checked *before* a file is decoded (``relight.mesh.obj``, ``relight.mesh.gltf``): the file size,
    the declared vertex count and the declared triangle count. Defaults: 64 MiB, 2 x 10^6 vertices, 4 x 10^6
    triangles (20x the largest mesh of the papers, 152K vertices)."""

    max_bytes: int = 64 << 20
    max_vertices: int = 2_000_000
    max_faces: int = 4_000_000

    def check_bytes(self, size: int, what: str) -> None:
        if size > self.max_bytes:
            raise InputError(f"{what}: {size} bytes exceed the mesh size cap of {self.max_bytes} bytes")

    def check_counts(self, vertices: int, faces: int, what: str) -> None:
        if vertices > self.max_vertices:
            raise InputError(f"{what}: {vertices} vertices declared, more than the cap of {self.max_vertices}")
        if faces > self.max_faces:
            raise InputError(f"{what}: {faces} triangles declared, more than the cap of {self.max_faces}")


@dataclass(frozen=True)
class RawMesh:
    """A decoded file before welding: positions (n, 3), triangles (m, 3) and optional per-corner texture
    coordinates (m, 3, 2) and per-vertex glTF tangents (n, 4)."""

    positions: FloatArray
    faces: IndexArray
    corner_uvs: FloatArray | None = None
    tangents: FloatArray | None = None
    source: str = "<memory>"


@dataclass(frozen=True)
class TriangleMesh:
    """A welded mesh in canonical order (module docstring).

    ``positions`` (V, 3) and ``normals`` (V, 3) float64, ``faces`` (F, 3), ``tangents`` (V, 4): xyz a unit vector
    orthogonal to the normal, w = +-1 with the bitangent ``B = w (N x T)`` (glTF 2.0 §3.7.2.1), and ``tangent_source``
    saying where they came from (``relight.mesh.tangents``). ``defects`` is ``relight.mesh.defects.report``.
    """

    positions: FloatArray
    faces: IndexArray
    normals: FloatArray
    tangents: FloatArray
    tangent_source: str
    defects: dict[str, Any] = field(default_factory=dict)
    source: str = "<memory>"

    @property
    def n_vertices(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def centre(self) -> FloatArray:
        """The centre of the bounding box."""
        return np.asarray(0.5 * (self.positions.min(axis=0) + self.positions.max(axis=0)), dtype=np.float64)

    @property
    def radius(self) -> float:
        """The bounding radius about :attr:`centre` (the mesh scale used for ray offsets, ``relight.raycast``)."""
        return float(np.linalg.norm(self.positions - self.centre, axis=1).max())

    def normalised(self) -> TriangleMesh:
        """The same mesh moved to its bounding-box centre and scaled into the unit ball (order and normals kept)."""
        r = self.radius
        pos = (self.positions - self.centre) / (r if r > 0 else 1.0)
        return TriangleMesh(pos, self.faces, self.normals, self.tangents, self.tangent_source, self.defects,
                            self.source)


def check_positions(positions: FloatArray, what: str) -> None:
    """InputError for NaN or infinite coordinates (naming the first offending vertex)."""
    bad = ~np.all(np.isfinite(positions), axis=1)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{what}: vertex {i} has a non-finite coordinate {positions[i].tolist()} "
                         f"({int(bad.sum())} such vertices)")


def face_normals(positions: FloatArray, faces: IndexArray) -> FloatArray:
    """Unnormalised face normals ``(p1 - p0) x (p2 - p0)`` (length = twice the area), (F, 3)."""
    p = positions[faces]
    return np.asarray(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), dtype=np.float64)


def corner_angles(positions: FloatArray, faces: IndexArray) -> FloatArray:
    """Interior angle of every face corner (F, 3), from atan2(|a x b|, a.b) (accurate for thin triangles)."""
    p = positions[faces]
    out = np.empty(faces.shape)
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        out[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    return out


def vertex_normals(positions: FloatArray, faces: IndexArray, weighting: Weighting = "area") -> FloatArray:
    """Unit vertex normals (V, 3): ``normalize(sum_f w_f n_f)`` over the faces around each vertex, with ``n_f`` the
    unit face normal and ``w_f`` its area (``"area"``) or the corner's angle (``"angle"``). A vertex whose faces
    all have zero area gets +Y (counted in the defects report as ``vertices_without_normal``)."""
    fn = face_normals(positions, faces)
    if weighting == "area":
        weighted = np.repeat(fn[:, None, :], 3, axis=1)  # |fn| = 2 area: the factor 2 cancels on normalising
    elif weighting == "angle":
        length = np.linalg.norm(fn, axis=1, keepdims=True)
        unit = fn / np.where(length > 0.0, length, 1.0)
        weighted = unit[:, None, :] * corner_angles(positions, faces)[:, :, None]
    else:
        raise InputError(f"unknown normal weighting {weighting!r}; expected 'area' or 'angle'")
    n = np.zeros_like(positions)
    for k in range(3):
        np.add.at(n, faces[:, k], weighted[:, k])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    up = np.broadcast_to(np.array([0.0, 1.0, 0.0]), n.shape)
    return np.asarray(np.where(norm > 0.0, n / np.where(norm > 0.0, norm, 1.0), up), dtype=np.float64)


@dataclass(frozen=True)
class Welded:
    """The result of :func:`weld`: canonical positions and faces, and the maps back to the input."""

    positions: FloatArray
    faces: IndexArray
    #: canonical vertex of every input vertex (n,), -1 for input vertices no kept face uses
    vertex_of_input: IndexArray
    #: input face of every canonical face (F,)
    face_of_output: IndexArray
    #: input corner (0, 1, 2) of every canonical face corner (F, 3) (faces are rotated, step 2)
    corner_of_output: IndexArray
    input_vertices: int
    merged_vertices: int
    collapsed_faces: int
    unreferenced_vertices: int


def weld(positions: FloatArray, faces: IndexArray) -> Welded:
    """Weld, drop collapsed faces and unused vertices, and put vertices and faces in canonical order (module
    docstring, steps 1-3)."""
    pos = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.intp)
    n_in = pos.shape[0]
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    step = WELD_FRACTION * float(np.linalg.norm(hi - lo))
    q = np.round((pos - lo) / step).astype(np.int64) if step > 0 else np.zeros(pos.shape, dtype=np.int64)
    cells, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    merged = n_in - cells.shape[0]
    wf = inverse[f]
    keep = (wf[:, 0] != wf[:, 1]) & (wf[:, 1] != wf[:, 2]) & (wf[:, 0] != wf[:, 2])
    collapsed = int(np.count_nonzero(~keep))
    wf = wf[keep]
    face_ids = np.flatnonzero(keep)
    # drop cells no kept face uses (the sorted cell order is kept, so the order stays canonical)
    used = np.zeros(cells.shape[0], dtype=bool)
    used[wf.ravel()] = True
    renumber = np.full(cells.shape[0], -1, dtype=np.intp)
    renumber[used] = np.arange(int(used.sum()))
    wf = renumber[wf]
    out_pos = pos[first[used]]
    # canonical faces: smallest index first (a cyclic rotation keeps the orientation), then lexicographic order
    rot = np.argmin(wf, axis=1)
    idx = (rot[:, None] + np.arange(3)[None, :]) % 3
    wf = np.take_along_axis(wf, idx, axis=1)
    order = np.lexsort((wf[:, 2], wf[:, 1], wf[:, 0]))
    return Welded(
        positions=np.asarray(out_pos, dtype=np.float64),
        faces=np.ascontiguousarray(wf[order], dtype=np.intp),
        vertex_of_input=renumber[inverse],
        face_of_output=face_ids[order],
        corner_of_output=np.ascontiguousarray(idx[order], dtype=np.intp),
        input_vertices=n_in,
        merged_vertices=int(merged),
        collapsed_faces=collapsed,
        unreferenced_vertices=int(np.count_nonzero(~used)),
    )
