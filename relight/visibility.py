"""Per-vertex visibility and precomputed radiance transfer by ray casting (issue 13; Sloan, Kautz & Snyder 2002).

Orders count bands as everywhere in relight: order F means l <= F, ``(F+1)^2`` coefficients in the real basis of
``docs/conventions.md`` (``relight.shrm.real_harmonics``, index ``l^2 + l + m``), in the *world* frame (so a
lighting vector ``L`` from ``relight.sh.to_real`` of the map's coefficients applies directly). For a vertex x with
normal n and binary visibility ``V(x, w)`` (1 where a ray from x escapes the mesh):

* ``visibility``: ``v_k = int V Yr_k dw`` (seed 002 eq. 7's 16 coefficients are F = 3) and the ambient occlusion
  ``ao = int V max(0, n.w) / pi dw`` (1 for an unoccluded vertex);
* ``diffuse_transfer``: ``T_k = int V max(0, n.w) / pi Yr_k dw`` (SKS02 §4 "shadowed diffuse transfer"); the exit
  radiance of a Lambertian vertex of albedo rho is ``rho sum_k T_k L_k``. With ``bounces = B`` the interreflected
  terms of SKS02 §4 are added: ``T^b(x) = rho int (1 - V) T^{b-1}(q) max(0, n.w) / pi dw`` with q the first hit
  along w (``T^{b-1}`` interpolated with the hit's barycentrics; back-facing hits give 0), ``T = sum_b T^b``;
* ``shadow_matrix``: ``M_ij = int V Yr_i Yr_j dw``, the transfer matrix of a shadow-only transport (seed 003 §5
  without the BRDF). It equals the Gaunt contraction of V's coefficients to order 2F exactly (``relight.gaunt``),
  and is symmetric.

**Directions.** One set of R directions shared by every vertex: spherical Fibonacci points (Swinbank & Purser 2006;
each owns 4 pi / R of the sphere: stratified) turned by a random rotation drawn from ``seed`` (so each estimate is
unbiased over the seed), or R independent uniform directions (``sampling="random"``). Every estimate is
``(4 pi / R) sum_s f(w_s)``.

**Monte Carlo error.** For each output, ``sqrt((mean f^2 - (mean f)^2) / R)`` per vertex: the standard error of the
estimate under independent uniform sampling (exact in expectation for ``"random"``; an upper bound for the
stratified Fibonacci set, whose error falls faster — both tested). Summaries are RMS over vertices.

**Blocks.** :func:`transfer_block` computes one block of vertices (the unit a Dask worker would get);
:func:`combine` concatenates blocks in vertex order. Outputs are float32; ``relight.vertex_texture`` packs them as
float16 textures.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final, Literal

import numpy as np
import scipy.sparse
from numpy.typing import NDArray

from relight import validate
from relight.conventions import dirs_to_angles
from relight.errors import InputError
from relight.mesh.model import TriangleMesh
from relight.raycast import RayCaster, ray_offset
from relight.shrm import real_harmonics

FloatArray = NDArray[np.float64]
Kind = Literal["visibility", "diffuse_transfer", "shadow_matrix"]
Sampling = Literal["fibonacci", "random"]
KINDS: Final = ("visibility", "diffuse_transfer", "shadow_matrix")
#: Golden angle 2 pi (1 - 1/phi) of the spherical Fibonacci lattice (Swinbank & Purser 2006, eq. 4).
GOLDEN_ANGLE: Final = np.pi * (3.0 - np.sqrt(5.0))
#: Largest order accepted (a (F+1)^2 x (F+1)^2 matrix per vertex at F = 8 is 6561 floats).
MAX_ORDER: Final = 8
MAX_RAYS: Final = 1 << 16
#: Occlusion rays per second assumed by :func:`predict` (Embree on this 2-core machine: 2.4-3.3 Mrays/s,
#: ``shared/wave2-design-notes.md`` §2.5; the lower end, since SH accumulation adds to the ray cost).
PREDICTED_RAYS_PER_SECOND: Final = 2.0e6


@dataclass(frozen=True)
class TransferSettings:
    """What to compute: order F, rays per vertex, kind, bounces and albedo (for ``diffuse_transfer``), sampling,
    seed, and vertices per block."""

    order: int = 3
    rays: int = 1024
    kind: Kind = "visibility"
    bounces: int = 0
    albedo: float = 0.8
    sampling: Sampling = "fibonacci"
    seed: int = 0
    block: int = 4096

    def __post_init__(self) -> None:
        validate.int_in_range("order", self.order, 0, MAX_ORDER)
        validate.int_in_range("rays per vertex", self.rays, 16, MAX_RAYS)
        if self.kind not in KINDS:
            raise InputError(f"unknown kind {self.kind!r}; expected one of {', '.join(KINDS)}")
        if self.bounces < 0 or self.bounces > 8 or (self.bounces and self.kind != "diffuse_transfer"):
            raise InputError(f"bounces must be 0..8 and only with kind diffuse_transfer, got {self.bounces}")
        validate.in_range("albedo", self.albedo, 0.0, 1.0)
        if self.sampling not in ("fibonacci", "random"):
            raise InputError(f"unknown sampling {self.sampling!r}; expected 'fibonacci' or 'random'")
        validate.positive_int("block", self.block)


def fibonacci_sphere(n: int) -> FloatArray:
    """The spherical Fibonacci lattice of n points: ``y_i = 1 - (2 i + 1) / n``, azimuth ``i x GOLDEN_ANGLE``."""
    i = np.arange(n)
    y = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = i * GOLDEN_ANGLE
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1)


def random_rotation(rng: np.random.Generator) -> FloatArray:
    """A uniformly distributed rotation matrix (QR of a Gaussian matrix with the sign fix; Mezzadri 2007)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))[None, :]
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return np.asarray(q, dtype=np.float64)


def directions(rays: int, sampling: Sampling = "fibonacci", seed: int | None = 0) -> FloatArray:
    """The shared ray directions (module docstring), (rays, 3); ``seed=None`` leaves the lattice unrotated."""
    if sampling == "random":
        d = np.random.default_rng(seed).standard_normal((rays, 3))
        return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), dtype=np.float64)
    pts = fibonacci_sphere(rays)
    if seed is None:
        return pts
    return np.asarray(pts @ random_rotation(np.random.default_rng(seed)).T, dtype=np.float64)


def sh_basis(dirs: FloatArray, order: int) -> FloatArray:
    """Real harmonics ``Yr_k(w_s)`` of the world directions, (n, (order+1)^2)."""
    theta, phi = dirs_to_angles(dirs)
    return real_harmonics(order, theta, phi)


def free_rays(caster: RayCaster, points: FloatArray, normals: FloatArray, dirs: FloatArray,
              offset: float) -> NDArray[np.bool_]:
    """``V(x, w_s)`` for points x (B, 3) with normals (B, 3) and directions (R, 3): True where the ray from
    ``x + offset n`` (``relight.raycast``) escapes the mesh, (B, R)."""
    b, r = points.shape[0], dirs.shape[0]
    # direction-major: the B rays of one direction are parallel, so consecutive queries walk the same BVH nodes
    # (measured 1.4-1.5x faster than vertex-major on the 117K-vertex bunny, bench/visibility.py)
    origins = np.tile((points + offset * normals).astype(np.float32), (r, 1))
    occluded = caster.occluded(origins, np.repeat(dirs.astype(np.float32), b, axis=0)).reshape(r, b)
    return np.ascontiguousarray(~occluded.T)


@dataclass
class Block:
    """Outputs for vertices ``start:stop`` (float64 until :func:`combine`)."""

    start: int
    stop: int
    arrays: dict[str, FloatArray] = field(default_factory=dict)


def _estimate(weights: NDArray[np.floating], basis: NDArray[np.floating], rays: int,
              binary: bool = False) -> tuple[FloatArray, FloatArray]:
    """``(4 pi / R) weights @ basis`` and its standard error (module docstring) for weights (B, R), in float64.

    Float64 on purpose: BLAS picks its kernel (and so its order of summation) by the matrix's shape, so a float32
    product of a block of 100 vertices and of the whole mesh differed in the last bit of about 3 % of the values.
    Summed in float64 and rounded once to the float32 outputs, a vertex's values do not depend on the block it was
    computed in (a fan-out over any number of workers gives the same bytes as a serial run, so a recomputed result
    keeps its digest). ``binary``: the weights are 0 or 1 (w^2 = w)."""
    weights, basis = np.asarray(weights, dtype=np.float64), np.asarray(basis, dtype=np.float64)
    scale = 4.0 * np.pi / rays
    mean = scale * (weights @ basis)
    w2 = weights if binary else weights * weights
    second = scale * scale * rays * (w2 @ (basis * basis))  # the mean of f^2 for f = 4 pi w y
    var = np.maximum(second - mean * mean, 0.0) / rays
    return np.asarray(mean, dtype=np.float64), np.asarray(np.sqrt(var), dtype=np.float64)


def _row_estimate(weights: NDArray[np.floating], rays: int) -> tuple[FloatArray, FloatArray]:
    """:func:`_estimate` with the basis 1: ``(4 pi / R) sum_s w_s`` per row and its standard error."""
    w = np.asarray(weights, dtype=np.float64)
    mean = 4.0 * np.pi * w.mean(axis=1)
    second = (4.0 * np.pi) ** 2 * (w * w).mean(axis=1)
    return mean, np.sqrt(np.maximum(second - mean * mean, 0.0) / rays)


def point_transfer(caster: RayCaster, points: FloatArray, normals: FloatArray, settings: TransferSettings,
                   offset: float) -> dict[str, FloatArray]:
    """The direct outputs (module docstring) at any surface points (B, 3) with normals (B, 3): the vertices of a
    block, or the surface points under an image's pixels (``relight.mesh_render``)."""
    s = settings
    dirs = directions(s.rays, s.sampling, s.seed)
    basis = sh_basis(dirs, s.order)
    b, r = points.shape[0], s.rays
    cosine = np.maximum(normals @ dirs.T, 0.0)  # (B, R)
    out: dict[str, FloatArray] = {}
    free_mask = free_rays(caster, points, normals, dirs, offset)
    free = free_mask.astype(np.float64)
    vis, vis_err = _estimate(free, basis, r, binary=True)
    shaded = free * (cosine / np.pi)
    ao, ao_err = _row_estimate(shaded, r)
    out.update(visibility=vis, visibility_error=vis_err, ao=ao, ao_error=ao_err)
    if s.kind == "diffuse_transfer":
        t, t_err = _estimate(shaded, basis, r)
        out.update(transfer=t, transfer_error=t_err)
    elif s.kind == "shadow_matrix":
        n = basis.shape[1]
        pair = (basis[:, :, None] * basis[:, None, :]).reshape(r, n * n)
        m, m_err = _estimate(free, pair, r, binary=True)
        out.update(shadow_matrix=m.reshape(b, n, n), shadow_matrix_error=m_err.reshape(b, n, n))
    return out


def transfer_block(mesh: TriangleMesh, start: int, stop: int, settings: TransferSettings, *,
                   caster: RayCaster | None = None, previous: FloatArray | None = None) -> Block:
    """One block of vertices (module docstring). With ``previous`` (the whole mesh's ``T^{b-1}``, (V, n)) it
    computes the bounce ``T^b`` of the block instead (``diffuse_transfer`` only)."""
    s = settings
    caster = caster or RayCaster(mesh.positions, mesh.faces)
    pts, nrm = mesh.positions[start:stop], mesh.normals[start:stop]
    out = Block(start, stop)
    if previous is None:
        out.arrays.update(point_transfer(caster, pts, nrm, s, ray_offset(mesh.positions)))
        return out
    dirs = directions(s.rays, s.sampling, s.seed)
    b, r = pts.shape[0], s.rays
    cosine = np.maximum(nrm @ dirs.T, 0.0)  # (B, R)
    origins = np.tile(pts + ray_offset(mesh.positions) * nrm, (r, 1))  # direction-major, as free_rays
    hits = caster.intersect(origins, np.repeat(dirs, b, axis=0))
    prim = np.ascontiguousarray(hits.prim.reshape(r, b).T)
    fn = np.cross(mesh.positions[mesh.faces[:, 1]] - mesh.positions[mesh.faces[:, 0]],
                  mesh.positions[mesh.faces[:, 2]] - mesh.positions[mesh.faces[:, 0]])
    hit = prim >= 0
    front = np.zeros_like(hit)
    front[hit] = np.einsum("ij,ij->i", fn[prim[hit]], np.broadcast_to(dirs, (b, r, 3))[hit]) < 0.0
    # T^b = rho (4 pi / R) sum_s front_s cos_s / pi sum_c bary_c T^{b-1}(corner c): a sparse (B x V) gather
    w = (s.albedo * 4.0 * np.pi / r / np.pi) * np.where(front, cosine, 0.0)
    rows, cols = np.nonzero(front)
    tri = mesh.faces[prim[rows, cols]]
    u, v = hits.u.reshape(r, b).T[rows, cols], hits.v.reshape(r, b).T[rows, cols]
    bary = np.stack([1.0 - u - v, u, v], axis=1) * w[rows, cols][:, None]
    gather = scipy.sparse.csr_matrix((bary.ravel(), (np.repeat(rows, 3), tri.ravel())),
                                     shape=(b, mesh.n_vertices))
    out.arrays["transfer"] = np.asarray(gather @ previous, dtype=np.float64)
    return out


def combine(blocks: list[Block], n_vertices: int) -> dict[str, FloatArray]:
    """Concatenate blocks (any order) covering ``0:n_vertices`` exactly into float64 arrays."""
    blocks = sorted(blocks, key=lambda blk: blk.start)
    edges = [blk.start for blk in blocks] + [n_vertices]
    if not blocks or edges[0] != 0 or any(blk.stop != edges[k + 1] for k, blk in enumerate(blocks)):
        raise InputError(f"blocks {[(blk.start, blk.stop) for blk in blocks]} do not tile 0..{n_vertices}")
    return {key: np.concatenate([blk.arrays[key] for blk in blocks]) for key in blocks[0].arrays}


def block_ranges(n_vertices: int, block: int) -> list[tuple[int, int]]:
    """The vertex ranges of the blocks, in order."""
    return [(a, min(n_vertices, a + block)) for a in range(0, n_vertices, block)]


@dataclass(frozen=True)
class TransferResult:
    """Per-vertex outputs (float32, canonical vertex order) and the manifest (settings, errors, timings)."""

    arrays: dict[str, NDArray[np.float32]]
    manifest: dict[str, Any]


def run_manifest(mesh: TriangleMesh, settings: TransferSettings, arrays: dict[str, FloatArray], blocks: int,
                 passes: int) -> dict[str, Any]:
    """What a result was computed with and its RMS Monte Carlo errors (over vertices, of each ``*_error`` array's
    per-vertex norm): the reproducible part of a manifest (no timings)."""
    s = settings

    def rms(key: str) -> float:
        e = arrays[key].reshape(mesh.n_vertices, -1)
        return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))

    return {
        "kind": s.kind, "order": s.order, "coefficients": (s.order + 1) ** 2, "rays": s.rays,
        "sampling": s.sampling, "seed": s.seed, "bounces": s.bounces, "albedo": s.albedo if s.bounces else None,
        "vertices": mesh.n_vertices, "faces": mesh.n_faces, "blocks": blocks, "block": s.block, "passes": passes,
        "ray_offset": ray_offset(mesh.positions), "basis": "relight real SH, world frame, index l^2 + l + m",
        "monte_carlo_error_rms": {key: rms(key) for key in sorted(arrays) if key.endswith("_error")},
    }


def predict(settings: TransferSettings, vertices: int) -> dict[str, Any]:
    """Before computing: the rays cast, the seconds (at :data:`PREDICTED_RAYS_PER_SECOND`) and an upper bound on
    the per-vertex RMS Monte Carlo error of each output under i.i.d. sampling (the stratified Fibonacci set does
    better). With the addition theorem ``sum_k Yr_k^2 = (F+1)^2 / (4 pi)`` the summed variances of
    ``f_k = 4 pi g Yr_k`` are at most ``(F+1)^2 int g^2``: for visibility (``g = V <= 1``) ``(F+1) sqrt(4 pi / R)``,
    for the transfer (``g = V max(0, n.w) / pi``, ``int g^2 <= 2 / (3 pi)``) ``(F+1) sqrt(2 / (3 pi R))``, for AO
    (``var = 4 pi int g^2 - ao^2 <= 8/3``) ``sqrt(8 / (3 R))``, for the shadow matrix ``(F+1)^2 / sqrt(R)``."""
    s = settings
    r, n = s.rays, s.order + 1
    passes = 1 + s.bounces
    errors = {"visibility_error": n * np.sqrt(4.0 * np.pi / r), "ao_error": np.sqrt(8.0 / (3.0 * r))}
    if s.kind == "diffuse_transfer":
        errors["transfer_error"] = n * np.sqrt(2.0 / (3.0 * np.pi * r))
    elif s.kind == "shadow_matrix":  # 4 pi int V (sum_i Yr_i^2)^2 <= 4 pi 4 pi ((F+1)^2 / (4 pi))^2 = (F+1)^4
        errors["shadow_matrix_error"] = n * n * np.sqrt(1.0 / r)
    rays = vertices * r * passes
    return {"rays_cast": rays, "seconds": rays / PREDICTED_RAYS_PER_SECOND,
            "monte_carlo_error_bound": {k: float(v) for k, v in errors.items()}}


def compute_transfer(mesh: TriangleMesh, settings: TransferSettings | None = None) -> TransferResult:
    """Every block of the mesh, combined (module docstring); bounces run one pass over the blocks each."""
    import time

    s = settings or TransferSettings()
    t0 = time.perf_counter()
    caster = RayCaster(mesh.positions, mesh.faces)
    ranges = block_ranges(mesh.n_vertices, s.block)
    arrays = combine([transfer_block(mesh, a, b, s, caster=caster) for a, b in ranges], mesh.n_vertices)
    passes = 1
    if s.kind == "diffuse_transfer" and s.bounces:
        arrays["direct_transfer"] = arrays["transfer"].copy()
        previous = arrays["transfer"]
        for _ in range(s.bounces):
            bounce = combine([transfer_block(mesh, a, b, s, caster=caster, previous=previous) for a, b in ranges],
                             mesh.n_vertices)["transfer"]
            arrays["transfer"] = arrays["transfer"] + bounce
            previous = bounce
            passes += 1
    seconds = time.perf_counter() - t0
    rays = mesh.n_vertices * s.rays * passes
    manifest = run_manifest(mesh, s, arrays, len(ranges), passes)
    manifest.update(seconds=seconds, rays_cast=rays, mrays_per_second=rays / seconds / 1e6 if seconds > 0 else None)
    return TransferResult({k: np.asarray(v, dtype=np.float32) for k, v in arrays.items()}, manifest)
