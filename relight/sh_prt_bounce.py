"""Interreflected transfer for SH-table shading (Kautz, Sloan & Snyder 2002, §5: "To include interreflections, the
desired BRDF must be fixed and accounted for in the global illumination simulation"; the simulation is Sloan,
Kautz & Snyder 2002's glossy transfer, §6, with the BRDF applied through the table).

At a surface point x with frame F_x (rows t, b, n) the transferred incident radiance is a linear function of the
world lighting L' (real SH, order F): ``L_x = T_x L'``, ``T_x = sum_b T_x^b`` (``b = 0 .. B``). Direction-wise,

* ``T^0_x = int V_x(w) Yr(w) Yr(w)^T dw`` (the shadow matrix, ``relight.visibility``'s ``shadow_matrix``);
* ``T^b_x = int (1 - V_x(w)) Yr(w) e^{b-1}_{q(w)}(-w)^T dw`` for b >= 1, where q(w) is the first surface point hit
  along w (front faces only; back faces and misses give 0) and ``e^{b-1}_q(u)^T L'`` is the radiance q reflects
  toward u from its bounce-(b-1) incident radiance: by the table (§4 steps 1–4),
  ``e^{b-1}_q(u) = [c(F_q u)^T M_q T^{b-1}_q]^T`` with ``M_q`` the local rotation (``relight.sh_rotation.
  local_rotations``) and ``c`` the table's coefficients at the local view ``F_q u`` (0 when it lies below q's
  shading horizon). The exit row at the hit is the barycentric blend of its three corner vertices' rows, so
  ``T^{b-1}`` is needed at the mesh vertices only.

Every integral is the ray sum ``(4 pi / R) sum_s`` over one direction set shared by all points
(``relight.visibility.directions``); one nearest-hit cast per point and direction serves every bounce. The exit
radiance of a point toward the view v is then ``c(F_x v)^T M_x T_x L'`` (``relight.sh_prt.shade_prt`` with the
folded ``M_x T_x``). ``T^0`` is colourless; the bounces carry the table's channels, (n, n, C).

Cost per bounce: one table lookup and one (n x n) row product per vertex and direction, ``V R n^2 C`` (for the
529-vertex teapot at F = 4, R = 512: 7 M multiply-adds), plus the scatter ``P R n^2 C`` into the points'
matrices. Memory is bounded by processing the directions in chunks of :data:`DIRECTION_CHUNK`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.mesh.model import TriangleMesh
from relight.raycast import RayCaster, ray_offset
from relight.sh_rotation import block_diagonal, local_rotations
from relight.sh_table import SHTable
from relight.visibility import Sampling, directions, sh_basis

FloatArray = NDArray[np.float64]
#: Directions per chunk: bounds the temporaries at ~ V x chunk x n x C doubles (529 x 64 x 25 x 3: 20 MB).
DIRECTION_CHUNK: Final = 64
#: Points per block of the gather (bounds it at ~ chunk x DIRECTION_CHUNK x 3 x n x C doubles: 90 MB at C = 3).
POINT_CHUNK: Final = 512
#: Most bounces accepted (each adds a factor of the surface's albedo times the occluded fraction; SKS02 used 1-2).
MAX_BOUNCES: Final = 8


@dataclass(frozen=True)
class BounceSettings:
    """Rays per point, their sampling and seed (``relight.visibility.directions``), and the bounces B."""

    rays: int = 1024
    bounces: int = 2
    sampling: Sampling = "fibonacci"
    seed: int = 0

    def __post_init__(self) -> None:
        if not 16 <= self.rays <= 1 << 16:
            raise InputError(f"rays per point must lie in 16..65536, got {self.rays}")
        validate.int_in_range("bounces", self.bounces, 0, MAX_BOUNCES)


@dataclass(frozen=True)
class RayHits:
    """Per point and direction (P, R): the hit triangle (-1: none), its barycentrics (P, R, 3) and whether the hit
    is a front face (the ray meets the triangle against its geometric normal)."""

    prim: NDArray[np.intp]
    bary: FloatArray
    front: NDArray[np.bool_]

    @property
    def free(self) -> NDArray[np.bool_]:
        return np.asarray(self.prim < 0)


def cast(caster: RayCaster, mesh: TriangleMesh, points: FloatArray, normals: FloatArray,
         dirs: FloatArray) -> RayHits:
    """Nearest hits of the rays from ``x + offset n`` (``relight.raycast.ray_offset``) along every direction."""
    p, r = points.shape[0], dirs.shape[0]
    origins = np.tile(points + ray_offset(mesh.positions) * normals, (r, 1))  # direction-major (visibility.free_rays)
    hits = caster.intersect(origins, np.repeat(dirs, p, axis=0))
    prim = np.ascontiguousarray(hits.prim.reshape(r, p).T)
    u, v = hits.u.reshape(r, p).T, hits.v.reshape(r, p).T
    bary = np.stack([1.0 - u - v, u, v], axis=-1)
    pos = mesh.positions
    fn = np.cross(pos[mesh.faces[:, 1]] - pos[mesh.faces[:, 0]], pos[mesh.faces[:, 2]] - pos[mesh.faces[:, 0]])
    front = (prim >= 0) & (np.einsum("psk,sk->ps", fn[np.maximum(prim, 0)], dirs) < 0.0)
    return RayHits(prim, np.asarray(bary, dtype=np.float64), np.asarray(front))


def shadow_matrices(hits: RayHits, basis: FloatArray) -> FloatArray:
    """``T^0 = (4 pi / R) sum_s V(w_s) Yr(w_s) Yr(w_s)^T`` per point, (P, n, n)."""
    r = basis.shape[0]
    free = hits.free.astype(np.float64)
    return np.asarray((4.0 * np.pi / r) * np.einsum("ps,si,sj->pij", free, basis, basis, optimize=True))


def _rotated(frames: FloatArray, transfer: FloatArray, order: int) -> FloatArray:
    """``M_q T_q`` per vertex with a channel axis: (V, n, n, C') for transfer (V, n, n) (C' = 1) or (V, n, n, C)."""
    rot = block_diagonal(local_rotations(frames, order))
    t = transfer if transfer.ndim == 4 else transfer[..., None]
    return np.asarray(np.einsum("vij,vjkc->vikc", rot, t, optimize=True))


def bounce_matrices(table: SHTable, mesh: TriangleMesh, frames: FloatArray, previous: FloatArray, hits: RayHits,
                    dirs: FloatArray, basis: FloatArray) -> FloatArray:
    """``T^b`` (P, n, n, C) at the points of ``hits`` from the vertices' ``T^{b-1}`` (``previous``, (V, n, n) or
    (V, n, n, C)) and frames (V, 3, 3) (module docstring)."""
    n = (table.order + 1) ** 2
    a = _rotated(frames, previous[:, :n, :n], table.order)  # (V, n, n, C')
    ch = max(a.shape[-1], int(table.coefficients.shape[-1]))
    p, r = hits.prim.shape
    out = np.zeros((p, n, n, ch))
    faces = mesh.faces
    for s0 in range(0, r, DIRECTION_CHUNK):
        sl = slice(s0, min(r, s0 + DIRECTION_CHUNK))
        # exit rows of every vertex toward -w_s: the table at the local view F_q (-w_s), times M_q T_q^{b-1}
        local = -np.einsum("vij,sj->vsi", frames, dirs[sl])  # (V, S, 3)
        c = table.lookup(local)  # (V, S, n, C)
        c = np.where((local[..., 2] > 0.0)[..., None, None], c, 0.0)
        rows = np.einsum("vsic,vijc->vsjc", np.broadcast_to(c, c.shape[:3] + (ch,)),
                         np.broadcast_to(a, a.shape[:3] + (ch,)), optimize=True)  # (V, S, n, C)
        for p0 in range(0, p, POINT_CHUNK):
            ps = slice(p0, min(p, p0 + POINT_CHUNK))
            prim, front = hits.prim[ps, sl], hits.front[ps, sl]
            corners = faces[np.maximum(prim, 0)]  # (P', S, 3)
            w = hits.bary[ps, sl] * front[..., None]  # (P', S, 3); 0 for misses and back faces
            s_idx = np.broadcast_to(np.arange(sl.stop - sl.start)[None, :, None], corners.shape)
            gathered = np.einsum("psk,psknc->psnc", w, rows[corners, s_idx], optimize=True)  # (P', S, n, C)
            out[ps] += np.einsum("si,psjc->pijc", basis[sl], gathered, optimize=True)
    return np.asarray((4.0 * np.pi / r) * out)


@dataclass(frozen=True)
class InterreflectedTransfer:
    """``T^0`` (P, n, n) and ``T^b`` (P, n, n, C) for b = 1..B at some points (vertices or image samples)."""

    direct: FloatArray
    bounces: list[FloatArray]

    def total(self, up_to: int | None = None) -> FloatArray:
        """``sum_{b <= up_to} T^b`` (P, n, n, C) (all bounces by default); C = 1 when there are none."""
        out = self.direct[..., None]
        for t in self.bounces[: len(self.bounces) if up_to is None else up_to]:
            out = out + t
        return np.asarray(out)


def _check(table: SHTable, mesh: TriangleMesh, frames: ArrayLike) -> FloatArray:
    f = np.asarray(frames, dtype=np.float64)
    if f.shape != (mesh.n_vertices, 3, 3):
        raise InputError(f"frames must be ({mesh.n_vertices}, 3, 3) (one per vertex), got shape {f.shape}")
    return f


def vertex_transfer(table: SHTable, mesh: TriangleMesh, frames: ArrayLike, settings: BounceSettings, *,
                    caster: RayCaster | None = None) -> InterreflectedTransfer:
    """``T^0 .. T^B`` at the mesh's vertices (module docstring), the BRDF being the table's."""
    f = _check(table, mesh, frames)
    caster = caster or RayCaster(mesh.positions, mesh.faces)
    dirs = directions(settings.rays, settings.sampling, settings.seed)
    basis = sh_basis(dirs, table.order)
    hits = cast(caster, mesh, mesh.positions, mesh.normals, dirs)
    direct = shadow_matrices(hits, basis)
    bounces: list[FloatArray] = []
    previous: FloatArray = direct
    for _ in range(settings.bounces):
        previous = bounce_matrices(table, mesh, f, previous, hits, dirs, basis)
        bounces.append(previous)
    return InterreflectedTransfer(direct, bounces)


def point_transfer(table: SHTable, mesh: TriangleMesh, frames: ArrayLike, vertex: InterreflectedTransfer,
                   points: ArrayLike, normals: ArrayLike, settings: BounceSettings, *,
                   caster: RayCaster | None = None) -> InterreflectedTransfer:
    """``T^0 .. T^B`` at arbitrary surface points (P, 3) with unit normals (P, 3) (an image's samples), each bounce
    gathered from the vertices' previous one (``vertex``, from :func:`vertex_transfer` with the same settings)."""
    f = _check(table, mesh, frames)
    pts, nrm = np.asarray(points, dtype=np.float64), np.asarray(normals, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or nrm.shape != pts.shape:
        raise InputError(f"points and normals must both be (P, 3), got {pts.shape} and {nrm.shape}")
    if len(vertex.bounces) < settings.bounces:
        raise InputError(f"the vertex transfer has {len(vertex.bounces)} bounces, {settings.bounces} asked for")
    caster = caster or RayCaster(mesh.positions, mesh.faces)
    dirs = directions(settings.rays, settings.sampling, settings.seed)
    basis = sh_basis(dirs, table.order)
    hits = cast(caster, mesh, pts, nrm, dirs)
    previous = [vertex.direct, *vertex.bounces]
    bounces = [bounce_matrices(table, mesh, f, previous[b], hits, dirs, basis) for b in range(settings.bounces)]
    return InterreflectedTransfer(shadow_matrices(hits, basis), bounces)
