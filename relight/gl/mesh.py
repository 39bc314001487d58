"""Meshes for the renderers: a minimal Wavefront OBJ reader, smooth normals, and the sphere's proxy box.

Objects are centred and scaled into the unit ball so that one camera framing (the orthographic view of
``relight.shrm.sphere_geometry``, or a perspective camera that sees the unit ball) fits every object.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np
from numpy.typing import NDArray

from relight import resources
from relight.errors import InputError
from relight.shapes import SHAPES

#: ``data/meshes`` (bunny.obj, teapot.obj), package data of ``relight.data`` (:mod:`relight.resources`).
MESH_DIR: Final = resources.mesh_dir()
#: The objects the viewer draws (:mod:`relight.shapes`).
OBJECTS: Final = SHAPES


@dataclass(frozen=True)
class Mesh:
    """Triangles as (n, 3) float32 positions and normals of a non-indexed vertex list (3 per triangle)."""

    positions: NDArray[np.float32]
    normals: NDArray[np.float32]
    #: True for the sphere's proxy: the shader intersects the exact unit sphere (``OBJECT_SPHERE``).
    analytic_sphere: bool = False

    def interleaved(self) -> bytes:
        return np.ascontiguousarray(np.concatenate([self.positions, self.normals], axis=1), dtype="<f4").tobytes()


def read_obj(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Vertices (n, 3) and triangles (m, 3) of an OBJ file (``v`` and ``f`` lines; polygons are fanned)."""
    verts: list[list[float]] = []
    faces: list[list[int]] = []
    text = Path(path).read_text(encoding="utf-8", errors="replace")
    for lineno, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(tok.split("/")[0]) for tok in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
        except (ValueError, IndexError):
            raise InputError(f"{path}:{lineno}: cannot parse {line.strip()!r}") from None
    v = np.asarray(verts, dtype=np.float64)
    f = np.asarray(faces, dtype=np.intp)
    if v.size == 0 or f.size == 0 or f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{path}: no usable triangles")
    return v, f


def smooth_normals(v: NDArray[np.float64], f: NDArray[np.intp]) -> NDArray[np.float64]:
    """Area-weighted vertex normals (the sum of the unnormalised face normals around each vertex)."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.asarray(n / np.where(norm > 0.0, norm, 1.0), dtype=np.float64)


def normalised(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Vertices moved to their bounding box's centre and scaled into the unit ball."""
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    c = v - centre
    return np.asarray(c / np.linalg.norm(c, axis=1).max(), dtype=np.float64)


def sphere_proxy() -> Mesh:
    """The box [-1, 1]^3 (12 triangles, outward): its front faces cover the unit sphere from any viewpoint."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, c, d in quads:
        tris += [(a, b, c), (a, c, d)]
    f = np.asarray(tris, dtype=np.intp)
    pos = corners[f].reshape(-1, 3)
    fn = np.cross(pos[1::3] - pos[0::3], pos[2::3] - pos[0::3])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    centre = pos.reshape(-1, 3, 3).mean(axis=1)
    if np.any(np.einsum("ij,ij->i", fn, centre) <= 0):
        raise AssertionError("sphere proxy faces must point outward")
    return Mesh(pos.astype(np.float32), np.repeat(fn, 3, axis=0).astype(np.float32), analytic_sphere=True)


def load_object(name: str) -> Mesh:
    """``sphere`` (analytic, through its proxy) or a mesh of ``data/meshes`` (``bunny``, ``teapot``)."""
    if name == "sphere":
        return sphere_proxy()
    if name not in OBJECTS:
        raise InputError(f"unknown object {name!r}; expected one of {', '.join(OBJECTS)}")
    v, f = read_obj(MESH_DIR / f"{name}.obj")
    v = normalised(v)
    n = smooth_normals(v, f)
    return Mesh(v[f].reshape(-1, 3).astype(np.float32), n[f].reshape(-1, 3).astype(np.float32))
