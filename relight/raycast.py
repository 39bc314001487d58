"""Ray casting against a triangle mesh: Embree (``embreex``) as the fast backend, NumPy Möller–Trumbore as its oracle.

* ``"embree"`` — Intel Embree 4 through the ``embreex`` binding (``rtcIntersect1`` / ``rtcOccluded1`` per ray, in
  float32; 2.4–3.3 Mrays/s on this 2-core machine, ``shared/wave2-design-notes.md`` §2.5).
* ``"numpy"`` — Möller & Trumbore 1997, "Fast, minimum storage ray-triangle intersection", written plainly in
  float64 over every (ray, triangle) pair in chunks: O(rays x triangles), the test oracle only.

Both report, for each ray ``o + t d`` with ``tnear < t < tfar``, the nearest triangle (``prim``, -1 for a miss), its
distance ``t`` and Embree's barycentrics ``(u, v)`` (the hit point is ``(1 - u - v) p0 + u p1 + v p2``).

**Self-intersection** (``docs/conventions.md``, "Meshes"). A ray leaving a vertex hits the triangles around it at
``t ~ 0`` in float32 ("acne"). Rays from surface points start at ``p + offset n`` with n the vertex normal and
``offset = OFFSET_FRACTION x the bounding radius`` (:func:`ray_offset`), so a ray above the tangent plane escapes the
vertex's own fan and a ray below it still hits the surface (tested on a sphere and a plane).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final, Literal

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.intp]
Backend = Literal["embree", "numpy"]

#: Origin offset along the normal as a fraction of the bounding radius: 1e-4 is ~800 float32 ulps of a coordinate
#: of the mesh's size (so float32 acne is cleared) and 1/30 of the sample bunny's mean edge.
OFFSET_FRACTION: Final = 1e-4
#: Rays per Embree call and per NumPy chunk (bounds the temporary memory).
CHUNK: Final = 1 << 20


def ray_offset(positions: FloatArray) -> float:
    """The origin offset (module docstring) for a mesh with these positions."""
    p = np.asarray(positions, dtype=np.float64)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    return OFFSET_FRACTION * float(np.linalg.norm(p - centre, axis=1).max())


@dataclass(frozen=True)
class Hits:
    """Nearest hits of a batch of rays: triangle (-1 = miss), distance (inf on a miss), barycentrics u, v."""

    prim: IndexArray
    t: FloatArray
    u: FloatArray
    v: FloatArray


def _check_rays(origins: NDArray[np.floating], dirs: NDArray[np.floating],
                dtype: type[np.floating] = np.float64) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
    o = np.asarray(origins, dtype=dtype)
    d = np.asarray(dirs, dtype=dtype)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
        raise ValueError(f"origins and directions must both be (n, 3), got {o.shape} and {d.shape}")
    return o, d


class RayCaster:
    """Nearest-hit and occlusion queries against one triangle mesh (module docstring)."""

    def __init__(self, positions: NDArray[np.floating], faces: NDArray[np.integer], backend: Backend = "embree"):
        self.positions = np.ascontiguousarray(positions, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.intp)
        if self.positions.ndim != 2 or self.positions.shape[1] != 3 or self.faces.ndim != 2 or \
                self.faces.shape[1] != 3:
            raise ValueError(f"need (n, 3) positions and (m, 3) faces, got {self.positions.shape}, "
                             f"{self.faces.shape}")
        if backend not in ("embree", "numpy"):
            raise InputError(f"unknown ray-casting backend {backend!r}; expected 'embree' or 'numpy'")
        self.backend: Backend = backend
        self._scene: Any = None
        if backend == "embree":
            from embreex import mesh_construction, rtcore_scene

            self._scene = rtcore_scene.EmbreeScene()
            mesh_construction.TriangleMesh(self._scene, self.positions.astype(np.float32),
                                           self.faces.astype(np.int32))

    # ------------------------------------------------------------------------------------------- queries
    def intersect(self, origins: NDArray[np.floating], dirs: NDArray[np.floating],
                  tfar: float = np.inf) -> Hits:
        """Nearest hit of every ray with ``0 < t < tfar``."""
        if self.backend == "numpy":
            o64, d64 = _check_rays(origins, dirs)
            return _mt_nearest(self.positions, self.faces, o64, d64, tfar)
        o, d = _check_rays(origins, dirs, np.float32)
        n = o.shape[0]
        prim = np.full(n, -1, dtype=np.intp)
        t = np.full(n, np.inf)
        u = np.zeros(n)
        v = np.zeros(n)
        for s in range(0, n, CHUNK):
            sl = slice(s, min(n, s + CHUNK))
            m = sl.stop - sl.start
            res = self._scene.run(o[sl], d[sl], dists=np.full(m, min(tfar, 3.4e38), dtype=np.float32), output=1)
            p = np.asarray(res["primID"], dtype=np.intp)
            hit = p >= 0
            prim[sl] = np.where(hit, p, -1)
            t[sl] = np.where(hit, res["tfar"], np.inf)
            u[sl] = np.where(hit, res["u"], 0.0)
            v[sl] = np.where(hit, res["v"], 0.0)
        return Hits(prim, t, u, v)

    def occluded(self, origins: NDArray[np.floating], dirs: NDArray[np.floating],
                 tfar: float = np.inf) -> NDArray[np.bool_]:
        """True for every ray that hits any triangle with ``0 < t < tfar`` (cheaper than :meth:`intersect`)."""
        if self.backend == "numpy":
            o64, d64 = _check_rays(origins, dirs)
            return np.asarray(_mt_nearest(self.positions, self.faces, o64, d64, tfar).prim >= 0)
        o, d = _check_rays(origins, dirs, np.float32)  # Embree works in float32: convert once
        out = np.empty(o.shape[0], dtype=bool)
        for s in range(0, o.shape[0], CHUNK):
            sl = slice(s, min(o.shape[0], s + CHUNK))
            m = sl.stop - sl.start
            # embreex's OCCLUDED query returns 0 for an occluded ray and -1 for a free one
            res = self._scene.run(o[sl], d[sl], dists=np.full(m, min(tfar, 3.4e38), dtype=np.float32),
                                  query="OCCLUDED")
            out[sl] = np.asarray(res) == 0
        return out


def moller_trumbore(p0: FloatArray, p1: FloatArray, p2: FloatArray, o: NDArray[np.floating],
                    d: NDArray[np.floating]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Möller–Trumbore (1997, §2) for broadcast rays and triangles: ``(t, u, v)`` with NaN t where the ray's line
    misses the triangle (parallel, or a barycentric outside [0, 1]).

    Notes: ``E1 = p1 - p0``, ``E2 = p2 - p0``, ``P = d x E2``, ``det = E1 . P``, ``T = o - p0``,
    ``u = T . P / det``, ``Q = T x E1``, ``v = d . Q / det``, ``t = E2 . Q / det``; inside when ``u >= 0``,
    ``v >= 0``, ``u + v <= 1`` (both faces count: no culling, as Embree's default).
    """
    e1, e2 = p1 - p0, p2 - p0
    pv = np.cross(d, e2)
    det = np.einsum("...k,...k->...", e1, pv)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = o - p0
    u = np.einsum("...k,...k->...", tv, pv) * inv
    q = np.cross(tv, e1)
    v = np.einsum("...k,...k->...", d, q) * inv
    t = np.einsum("...k,...k->...", e2, q) * inv
    inside = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0)
    return np.where(inside, t, np.nan), u, v


def _mt_nearest(positions: FloatArray, faces: IndexArray, o: NDArray[np.floating], d: NDArray[np.floating],
                tfar: float) -> Hits:
    """Nearest hit by brute force over every triangle (chunks of rays x all triangles)."""
    p0, p1, p2 = (positions[faces[:, k]] for k in range(3))
    n, m = o.shape[0], faces.shape[0]
    prim = np.full(n, -1, dtype=np.intp)
    t_out = np.full(n, np.inf)
    u_out = np.zeros(n)
    v_out = np.zeros(n)
    step = max(1, CHUNK // (8 * max(m, 1)))
    for s in range(0, n, step):
        sl = slice(s, min(n, s + step))
        t, u, v = moller_trumbore(p0[None], p1[None], p2[None], o[sl, None], d[sl, None])
        t = np.where((t > 0.0) & (t < tfar), t, np.inf)
        best = np.argmin(t, axis=1)
        tb = t[np.arange(t.shape[0]), best]
        hit = np.isfinite(tb)
        prim[sl] = np.where(hit, best, -1)
        t_out[sl] = tb
        u_out[sl] = np.where(hit, u[np.arange(t.shape[0]), best], 0.0)
        v_out[sl] = np.where(hit, v[np.arange(t.shape[0]), best], 0.0)
    return Hits(prim, t_out, u_out, v_out)
