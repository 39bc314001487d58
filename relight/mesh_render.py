"""CPU images of a Lambertian mesh lit by an environment map: precomputed transfer (SKS02) and brute force.

The camera is ``relight.mitsuba_twin``'s: orthographic along the view V onto the mesh scaled into the unit ball
(``TriangleMesh.normalised``), image right ``normalize(up x V)``, image up ``V x right``, the frame [-1, 1]^2;
pixel (i, j) covers ``x in [2 j / n - 1, 2 (j + 1) / n - 1]``, ``y in [1 - 2 (i + 1) / n, 1 - 2 i / n]``. Each
pixel is ``supersample^2`` primary rays (Embree, ``relight.raycast``) at sub-pixel centres, averaged — the box
filter of Mitsuba's ``hdrfilm``. A sub-pixel that misses is 0 (Mitsuba's ``hide_emitters``).

Radiance at a surface point x with normal n (albedo rho, ``docs/conventions.md`` "Meshes"):

* **SH transfer** (:func:`shade_transfer`): ``rho T(x) . L`` with L the real SH coefficients of the map
  (:func:`lighting_coefficients`, relight's pixel quadrature) and T the transfer vector of ``relight.visibility``
  (shadowed) or the clamped cosine ``max(0, n.w) / pi`` (:func:`unshadowed_transfer`, closed form) — truncated at
  order F;
* **brute force** (:func:`brute_force_radiance`): ``rho sum_p L_p V(x, w_p) max(0, n.w_p) / pi dOmega_p`` over
  every pixel p of the map, V by one ray per pixel (no SH, no truncation).

T is taken either at the vertices and interpolated with the hit's barycentrics (``per="vertex"``: what the viewer
draws) or computed at every sub-pixel's own surface point with its interpolated normal (``per="pixel"``: the
image precomputed transfer converges to, free of interpolation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import NDArray

from relight import sh
from relight.conventions import latlong_dirs, pixel_solid_angles
from relight.mesh.model import TriangleMesh
from relight.raycast import RayCaster, ray_offset
from relight.visibility import sh_basis

FloatArray = NDArray[np.float64]
#: Environment pixels per batch of the brute-force integrator (bounds its (points x pixels) ray arrays).
PIXEL_BATCH: Final = 512


def camera_up(view: FloatArray) -> FloatArray:
    """+Y, or +Z when V = +-Y (``relight.mitsuba_twin.camera_up``)."""
    return np.array([0.0, 1.0, 0.0]) if abs(float(view[1])) < 1.0 - 1e-9 else np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class SurfaceSamples:
    """The primary-ray hits of an image: per sub-pixel (n s, n s) the triangle (-1 = miss), barycentrics, the
    surface point and its interpolated unit normal; ``coverage`` (n, n) the fraction of each pixel's sub-pixels
    that hit."""

    size: int
    supersample: int
    prim: NDArray[np.intp]
    bary: FloatArray
    points: FloatArray
    normals: FloatArray
    coverage: FloatArray

    @property
    def hit(self) -> NDArray[np.bool_]:
        return np.asarray(self.prim >= 0)

    def image(self, values: FloatArray) -> FloatArray:
        """Average per-hit values (H, C) (in the order of ``points[hit]``) into an (n, n, C) image; misses 0."""
        n, s = self.size, self.supersample
        full = np.zeros(self.prim.shape + (values.shape[1],))
        full[self.hit] = values
        return np.asarray(full.reshape(n, s, n, s, -1).mean(axis=(1, 3)), dtype=np.float64)


def surface_samples(mesh: TriangleMesh, view: NDArray[np.floating], size: int, supersample: int = 2,
                    caster: RayCaster | None = None) -> SurfaceSamples:
    """Cast the camera's primary rays (module docstring) at the (already normalised) mesh."""
    v = np.asarray(view, dtype=np.float64) / np.linalg.norm(view)
    up = camera_up(v)
    right = np.cross(up, v)
    right /= np.linalg.norm(right)
    up_img = np.cross(v, right)
    m = size * supersample
    c = (np.arange(m) + 0.5) * 2.0 / m - 1.0
    x, y = np.meshgrid(c, -c)  # rows go down the image
    origins = 3.0 * v + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up_img
    caster = caster or RayCaster(mesh.positions, mesh.faces)
    hits = caster.intersect(origins, np.broadcast_to(-v, origins.shape))
    prim = hits.prim.reshape(m, m)
    hit = hits.prim >= 0
    bary = np.stack([1.0 - hits.u - hits.v, hits.u, hits.v], axis=1)
    tri = mesh.faces[np.where(hit, hits.prim, 0)]
    points = np.einsum("rk,rkj->rj", bary, mesh.positions[tri])
    nrm = np.einsum("rk,rkj->rj", bary, mesh.normals[tri])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    coverage = hit.reshape(size, supersample, size, supersample).mean(axis=(1, 3))
    return SurfaceSamples(size, supersample, prim, bary[hit], points[hit], nrm[hit], coverage)


def lighting_coefficients(pixels: NDArray[np.floating], order: int) -> FloatArray:
    """Real SH coefficients ((order+1)^2, C) of a lat-long map (``relight.sh.project`` + ``to_real``)."""
    p = np.asarray(pixels, dtype=np.float64)
    return np.asarray(sh.to_real(sh.project(p, order), order).T, dtype=np.float64)


def unshadowed_transfer(normals: FloatArray, order: int) -> FloatArray:
    """Transfer of an unoccluded point: the clamped cosine ``max(0, n.w) / pi`` turned to n, (B, (order+1)^2).

    Its zonal coefficients ``A_l = 2 sqrt((2l+1)/4pi) int_0^1 mu P_l(mu) dmu`` (Ramamoorthi & Hanrahan 2001,
    eq. 9 / pi) by exact polynomial integration; rotated by the addition theorem
    ``c_lm = sqrt(4 pi / (2l+1)) A_l Yr_lm(n)``."""
    zonal = np.zeros(order + 1)
    for l in range(order + 1):
        antider = (np.polynomial.Legendre.basis(l) * np.polynomial.Legendre([0.0, 1.0])).integ()
        zonal[l] = 2.0 * np.sqrt((2 * l + 1) / (4 * np.pi)) * float(antider(1.0) - antider(0.0))
    l_of = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    return np.asarray(sh_basis(normals, order) * (np.sqrt(4 * np.pi / (2 * l_of + 1)) * zonal[l_of])[None, :],
                      dtype=np.float64)


def shade_transfer(transfer: FloatArray, lighting: FloatArray, albedo: float = 1.0) -> FloatArray:
    """``rho T . L`` for transfer vectors (B, n) and lighting (n, C) of the same order: (B, C)."""
    n = transfer.shape[1]
    return np.asarray(albedo * (transfer @ lighting[:n]), dtype=np.float64)


def interpolate(samples: SurfaceSamples, mesh: TriangleMesh, vertex_values: FloatArray) -> FloatArray:
    """Per-vertex values (V, C) interpolated at the hits with their barycentrics (the viewer's Gouraud path)."""
    tri = mesh.faces[samples.prim[samples.hit]]
    return np.asarray(np.einsum("rk,rkc->rc", samples.bary, vertex_values[tri]), dtype=np.float64)


def brute_force_radiance(caster: RayCaster, points: FloatArray, normals: FloatArray, pixels: NDArray[np.floating],
                         offset: float, albedo: float = 1.0, shadows: bool = True) -> FloatArray:
    """``rho sum_p L_p V(x, w_p) max(0, n.w_p) / pi dOmega_p`` over every map pixel (module docstring), (B, C)."""
    p = np.asarray(pixels, dtype=np.float64)
    h, w = p.shape[:2]
    dirs = latlong_dirs(h, w).reshape(-1, 3)
    weight = (p * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, p.shape[2]) / np.pi  # L_p dOmega_p / pi
    keep = np.flatnonzero(np.any(weight > 0.0, axis=1))
    out = np.zeros((points.shape[0], p.shape[2]))
    origins = (points + offset * normals).astype(np.float32)
    for s in range(0, keep.size, PIXEL_BATCH):
        idx = keep[s : s + PIXEL_BATCH]
        d = dirs[idx]
        cos = np.maximum(normals @ d.T, 0.0)
        if shadows:
            rows, cols = np.nonzero(cos > 0.0)
            free = ~caster.occluded(origins[rows], d[cols].astype(np.float32))
            vis = np.zeros_like(cos)
            vis[rows, cols] = free
            cos = cos * vis
        out += cos @ weight[idx]
    return np.asarray(albedo * out, dtype=np.float64)


def mesh_offset(mesh: TriangleMesh) -> float:
    """The ray offset of ``relight.raycast`` for this mesh."""
    return ray_offset(mesh.positions)
