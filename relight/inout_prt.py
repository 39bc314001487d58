"""In-out factorized PRT with SH lighting (Mahajan, Tseng & Ramamoorthi 2008, eqs. 2–4; the CPU reference).

Per surface point x with normal n and a local frame F_x (rows t, b, n; ``relight.tangent_frames``), for each term
k of the factorization (``relight.inout_factors``) the view-independent transport (eq. 3) in relight's real SH
basis of the *world* frame, order F:

    T_kj(x) = int V(x, w) g_k(F_x w) c(w) Yr_j(w) dw,   c = 1 (factored f_r cos, relight's default) or max(0, n.w)

estimated with the rays of ``relight.visibility`` (one shared set of R Fibonacci directions, turned by the seed;
``(4 pi / R) sum_s``; Embree through ``relight.raycast``). Per frame (eq. 4) with world lighting coefficients L:

    B(x, w_o) = sum_k sigma_k h_k(F_x w_o) (T_k(x) . L)

so a lighting change costs K dot products of length (F+1)^2 per point and a view change K profile lookups; shadows
(V), the view and the lighting are all free at run time. For lighting band-limited to F the transport's projection
is exact (only bands <= F of ``V g_k c`` meet L), so the result is the K-term BRDF's reflection integral up to the
rays' Monte Carlo error (reported per coefficient as ``relight.visibility`` does). g_k and h_k are 0 below the
horizon (the factorization is over the visible hemisphere), and points seen from below (``n . w_o <= 0``) are 0.

Costs (:func:`frame_operations`, for the planner): per frame ``3 V K (F+1)^2`` multiply-adds for the dot products
and ``V K`` profile lookups; storage ``V K (F+1)^2`` numbers. The GPU twin is ``web/shaders/inout.vert.glsl``
(``relight.gl.inout``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.errors import InputError
from relight.inout_factors import InOutFactors
from relight.mesh.model import TriangleMesh
from relight.raycast import RayCaster, ray_offset
from relight.tangent_frames import azimuthal_frames
from relight.visibility import directions, free_rays, sh_basis

FloatArray = NDArray[np.float64]

#: Largest lighting order (the per-point transport is K x (F+1)^2).
MAX_ORDER = 16
#: Points per block of the transport (bounds the (B, R, K) intermediate to ~100 MB at R = 4096, K = 80).
BLOCK_POINTS = 64


def _check_order(order: int) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= order <= MAX_ORDER:
        raise InputError(f"order must be an integer in 0..{MAX_ORDER}, got {order!r}")
    return int(order)


def transport(factors: InOutFactors, frames: ArrayLike, dirs: ArrayLike, visible: ArrayLike,
              order: int) -> tuple[FloatArray, FloatArray]:
    """``T`` (P, K, (F+1)^2) and its Monte Carlo standard error (same shape, i.i.d. bound as
    ``relight.visibility``) for points with frames (P, 3, 3), ray directions (R, 3) and visibility (P, R)."""
    f = np.asarray(frames, dtype=np.float64)
    d = np.asarray(dirs, dtype=np.float64)
    vis = np.asarray(visible)
    order = _check_order(order)
    if f.ndim != 3 or f.shape[1:] != (3, 3) or d.ndim != 2 or d.shape[1] != 3 or vis.shape != (f.shape[0], d.shape[0]):
        raise InputError(f"frames (P, 3, 3), dirs (R, 3) and visible (P, R) expected, got {f.shape}, {d.shape}, "
                         f"{vis.shape}")
    p, r, k = f.shape[0], d.shape[0], factors.terms
    basis = sh_basis(d, order).astype(np.float32)  # (R, n)
    n = basis.shape[1]
    out = np.empty((p, k, n))
    err = np.empty((p, k, n))
    scale = 4.0 * np.pi / r
    for a in range(0, p, BLOCK_POINTS):
        b = min(p, a + BLOCK_POINTS)
        local = np.einsum("pij,rj->pri", f[a:b], d)  # (B, R, 3)
        w = factors.evaluate("g", local)  # (B, R, K)
        weight = vis[a:b].astype(np.float64)
        if not factors.include_cosine:
            weight = weight * np.maximum(local[..., 2], 0.0)
        w = (w * weight[..., None]).astype(np.float32)
        wk = np.ascontiguousarray(np.moveaxis(w, 2, 1)).reshape(-1, r)  # (B K, R)
        mean = scale * (wk @ basis)
        second = scale * scale * r * ((wk * wk) @ (basis * basis))
        out[a:b] = mean.reshape(b - a, k, n)
        err[a:b] = np.sqrt(np.maximum(second - mean * mean, 0.0) / r).reshape(b - a, k, n)
    return out, err


def point_transport(caster: RayCaster, points: ArrayLike, normals: ArrayLike, factors: InOutFactors, order: int, *,
                    rays: int = 1024, seed: int = 0, offset: float, shadows: bool = True,
                    frames: ArrayLike | None = None) -> dict[str, FloatArray]:
    """:func:`transport` at surface points (P, 3) with normals (P, 3): the rays of ``relight.visibility``
    (:func:`relight.visibility.directions`, Fibonacci turned by ``seed``), occlusion by Embree from
    ``x + offset n``; ``shadows=False`` takes V = 1. Frames default to the azimuthal field (+Y axis)."""
    pts = np.asarray(points, dtype=np.float64)
    nrm = np.asarray(normals, dtype=np.float64)
    fr = azimuthal_frames(nrm) if frames is None else np.asarray(frames, dtype=np.float64)
    dirs = directions(rays, "fibonacci", seed)
    if shadows:
        vis = free_rays(caster, pts, nrm, dirs, offset)
    else:
        vis = np.ones((pts.shape[0], rays), dtype=bool)
    t, e = transport(factors, fr, dirs, vis, order)
    return {"transport": t, "transport_error": e, "frames": fr}


def mesh_transport(mesh: TriangleMesh, factors: InOutFactors, order: int, *, rays: int = 1024, seed: int = 0,
                   shadows: bool = True) -> dict[str, FloatArray]:
    """Per-vertex transport of a mesh (canonical vertex order; frames from the vertex normals)."""
    caster = RayCaster(mesh.positions, mesh.faces)
    return point_transport(caster, mesh.positions, mesh.normals, factors, order, rays=rays, seed=seed,
                           offset=ray_offset(mesh.positions), shadows=shadows)


def shade(factors: InOutFactors, transport_: ArrayLike, lighting: ArrayLike, frames: ArrayLike,
          view: ArrayLike) -> FloatArray:
    """Eq. 4: radiance (P, 3) toward the view (3,) or per point (P, 3), for world lighting ((F'+1)^2, 3) with F' >=
    the transport's order (higher bands ignored)."""
    t = np.asarray(transport_, dtype=np.float64)
    f = np.asarray(frames, dtype=np.float64)
    light = np.asarray(lighting, dtype=np.float64)
    if t.ndim != 3 or t.shape[:2] != (f.shape[0], factors.terms):
        raise InputError(f"transport must be (P, {factors.terms}, n) for {f.shape[0]} frames, got shape {t.shape}")
    n = t.shape[2]
    if light.ndim != 2 or light.shape[0] < n or light.shape[1] != 3:
        raise InputError(f"lighting must be (>= {n}, 3) real coefficients, got shape {light.shape}")
    v = np.broadcast_to(np.asarray(view, dtype=np.float64), (f.shape[0], 3))
    vl = np.einsum("pij,pj->pi", f, v)
    h = factors.sigma * factors.evaluate("h", vl)  # (P, K)
    q = np.einsum("pkj,jc->pkc", t, light[:n])  # (P, K, 3): T_k . L
    out = np.einsum("pk,pkc->pc", h, q)
    return np.where((vl[:, 2] > 0.0)[:, None], out, 0.0)


def frame_operations(vertices: int, terms: int, order: int) -> dict[str, Any]:
    """Per-frame work and storage of in-out PRT (module docstring): what the planner's cost model multiplies by
    its calibrated seconds per operation. ``dot_madds`` = 3 V K (F+1)^2 (RGB lighting), ``lookups`` = V K profile
    lookups (2 texel fetches each on the GPU), ``stored`` = V K (F+1)^2 transport numbers."""
    for name, v in (("vertices", vertices), ("terms", terms), ("order", order)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise InputError(f"{name} must be a non-negative integer, got {v!r}")
    n = (int(order) + 1) ** 2
    return {"dot_madds": 3 * vertices * terms * n, "lookups": vertices * terms, "stored": vertices * terms * n,
            "per_term": {"dot_madds": 3 * vertices * n, "lookups": vertices, "stored": vertices * n}}


def truncation_error(factors: InOutFactors) -> float:
    """The predicted relative error of the K-term BRDF: sqrt(uncaptured singular energy) (eq. 2's Frobenius
    residual over the hemispheres; the image error under a given lighting is usually smaller, never checked
    against a bound)."""
    return math.sqrt(max(0.0, 1.0 - factors.captured))
