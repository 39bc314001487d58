"""Angular-domain reference for view-dependent BRDFs (seed 000 eqs. 1–2; the "angular-space" columns of Table 5).

For a distant view V and a surface normal N the reflected radiance is (eq. 1)::

    B(N, V) = int L(w) f(w, V, N) max(N . w, 0) dw          (N . V > 0)

computed here by brute force over the environment's pixels k with their exact solid angles:
``B = sum_k L_k rho_hat_k dOmega_k``. For a general isotropic BRDF (``relight.brdf.base.IsotropicBRDF``) the
integrand is ``f(w_k, V, N) max(N . w_k, 0)`` from the model's own ``f`` in world coordinates — independent of the
reparameterisation and of every SH routine. Other lobes are evaluated through their ``rho_hat(theta_i, theta_o,
phi)`` with the angles measured about the lobe's centre C (R, N, or the tangent field's T, §3.1):
``cos theta_i = C . w``, ``cos theta_o = C . V``, phi the angle between the projections of w and V on the plane
normal to C. (A radially symmetric lobe only needs ``u(C . w)``.)

Output layouts: :func:`reference_view` gives the map indexed by R (``docs/conventions.md``: pixel R holds the
radiance reflected toward V by a surface with reflection vector R, i.e. normal ``N = normalize(R + V)``) on an
S x 2S lat-long grid; :func:`reference_sphere` the orthographic sphere image of ``relight.shrm.render_sphere``.

Lobe truncation (App. D): each lobe is dropped outside the cone ``theta_i <= theta*(theta_o)`` about its centre
that holds ``1 - truncation`` of ``int |rho_hat| dw_i`` (found on a (theta_i, phi) grid for 32 bins of theta_o,
taking the largest angle over each bin's edges and midpoint; the default 1e-4 changes results by about that
fraction of the lobe's integral). The cone depends on theta_o: near grazing (theta_o -> pi for R-centred lobes,
i.e. N.V -> 0) a microfacet lobe spreads over most of the hemisphere. Outputs are processed in groups sorted by
the polar angle of their centre, and only the environment rows that can meet a group's cones are visited, so the
cost is O(W S_L^2) per output pixel like the paper's angular method, with W the cone's share of the sphere.
Work is chunked so memory stays bounded (about ``chunk_elems`` pairs per block). That schedule is
:func:`block_plan`, shared with the cost model (``relight.costmodel.angular``), which counts the same blocks.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import IsotropicBRDF, Lobe, RadialLobe
from relight.conventions import check_latlong_shape, latlong_dirs, pixel_solid_angles, ring_thetas
from relight.errors import InputError
from relight.reference import DEFAULT_TRUNCATION
from relight.shrm import brdf_lobes, halfway_normals, lobe_centres, reflect_dirs, sphere_geometry, unit_view

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: theta_o bins of the truncation table (module docstring).
N_THETA_O_BINS = 32
_theta_star_cache: dict[str, FloatArray] = {}


def lobe_truncation_angles(lobe: Lobe, truncation: float) -> FloatArray:
    """theta* about the lobe's centre for each theta_o bin, shape (N_THETA_O_BINS,).

    Bin k covers ``theta_o`` in ``[k, k + 1] pi / N_THETA_O_BINS``; its theta* is the largest, over the bin's two
    edges and midpoint, of the angle holding ``1 - truncation`` of ``int |rho_hat| dw_i`` (max over channels),
    tabulated on 720 theta_i x 24 phi midpoints. Returns pi everywhere for ``truncation <= 0``. Cached per lobe
    spec (a property of the lobe, not of the lighting).
    """
    if truncation <= 0.0:
        return np.full(N_THETA_O_BINS, np.pi)
    try:
        key: str | None = json.dumps([type(lobe).__qualname__, lobe.spec(), truncation], sort_keys=True)
    except (TypeError, ValueError):
        key = None
    if key is not None and key in _theta_star_cache:
        return _theta_star_cache[key]
    samples = np.linspace(0.0, np.pi, 2 * N_THETA_O_BINS + 1)
    if lobe.radially_symmetric:
        per_sample = np.full(samples.size, _truncation_angle(lobe, truncation, np.pi / 2))
    else:
        per_sample = np.array([_truncation_angle(lobe, truncation, t) for t in samples])
    table: FloatArray = np.asarray(
        np.maximum(np.maximum(per_sample[0:-1:2], per_sample[1::2]), per_sample[2::2]), dtype=np.float64
    )
    table.setflags(write=False)
    if key is not None:
        if len(_theta_star_cache) >= 64:
            _theta_star_cache.pop(next(iter(_theta_star_cache)))
        _theta_star_cache[key] = table
    return table


def truncation_for(table: FloatArray, cos_o: FloatArray) -> FloatArray:
    """Per-output theta* from :func:`lobe_truncation_angles` for ``cos theta_o = C . V``."""
    t_o = np.arccos(np.clip(cos_o, -1.0, 1.0))
    k = np.clip((t_o / np.pi * table.size).astype(np.intp), 0, table.size - 1)
    return np.asarray(table[k], dtype=np.float64)


#: Outputs per group of the block plan (sorted by the polar angle of their lobe centre, module docstring).
GROUP_SIZE = 256
#: About this many (output, input pixel) pairs per block: bounds the memory of one block's arrays (~4 MB per float).
CHUNK_ELEMS = 500_000
#: A block whose pairs inside the truncation cones exceed this share of it is evaluated densely (every pair, masked),
#: which beats gathering index arrays for wide lobes; the cost model counts such a block's evaluations as all pairs.
DENSE_FRACTION = 0.3


@dataclass(frozen=True)
class ViewGroup:
    """Outputs evaluated together and the environment rows that can meet their cones, visited ``step`` rows at a
    time (:meth:`blocks`)."""

    outputs: IntArray
    rows: IntArray
    step: int

    def blocks(self) -> Iterator[slice]:
        """Slices of :attr:`rows`, one per block of at most ``step`` rows."""
        for r0 in range(0, self.rows.size, self.step):
            yield slice(r0, min(r0 + self.step, self.rows.size))


@dataclass(frozen=True)
class LobeBlockPlan:
    """One lobe's schedule over the outputs: its centres, per-output cone half-angle theta* and polar angle of the
    centre, and the groups of :func:`block_plan`."""

    centres: FloatArray  # (n, 3)
    theta_star: FloatArray  # (n,)
    c_theta: FloatArray  # (n,)
    groups: tuple[ViewGroup, ...]


def block_plan(
    lobe: Lobe, normals: FloatArray, refl: FloatArray, view: FloatArray, height: int, truncation: float,
    *, group: int = GROUP_SIZE, chunk_elems: int = CHUNK_ELEMS,
) -> LobeBlockPlan:
    """The groups and row blocks in which :func:`reflected_radiance` evaluates one lobe (module docstring).

    Outputs facing away from the view (``N . V <= 0``) are in no group. A group's rows are those within the largest
    theta* of the group (plus half a pixel) of its centres' polar angles; each block holds at most ``chunk_elems``
    pairs (at least one row).
    """
    width = 2 * height
    env_theta = ring_thetas(height)
    half_px = 0.5 * np.pi / height
    table = lobe_truncation_angles(lobe, truncation)
    centres = lobe_centres(str(lobe.center), normals, refl)
    theta_star = truncation_for(table, centres @ view)  # per output: its view's theta_o bin
    c_theta = np.arccos(np.clip(centres[:, 1], -1.0, 1.0))
    facing = (normals @ view) > 0.0
    order = np.argsort(c_theta, kind="stable")
    order = order[facing[order]]
    groups = []
    for g0 in range(0, order.size, group):
        idx = order[g0 : g0 + group]
        reach = float(theta_star[idx].max()) + half_px
        lo, hi = c_theta[idx].min(), c_theta[idx].max()
        rows = np.nonzero((env_theta >= lo - reach) & (env_theta <= hi + reach))[0]
        if rows.size:
            groups.append(ViewGroup(outputs=idx, rows=rows, step=max(1, chunk_elems // (idx.size * width))))
    return LobeBlockPlan(centres=centres, theta_star=theta_star, c_theta=c_theta, groups=tuple(groups))


def is_dense(inside: float, pairs: int) -> bool:
    """Whether a block with ``inside`` of its ``pairs`` inside the cones is evaluated densely
    (:data:`DENSE_FRACTION`)."""
    return inside > DENSE_FRACTION * pairs


def _truncation_angle(lobe: Lobe, truncation: float, theta_o: float) -> float:
    n_i, n_p = 720, 24
    ti = (np.arange(n_i) + 0.5) * np.pi / n_i
    ph = (np.arange(n_p) + 0.5) * np.pi / n_p
    v = np.asarray(lobe.rho_hat(ti[:, None], np.full((1, 1), theta_o), ph[None, :]), dtype=np.float64)
    if v.ndim == 2:
        v = v[..., None]
    g = np.abs(v).sum(axis=1) * np.sin(ti)[:, None]  # (n_i, C)
    cum = np.cumsum(g, axis=0)
    tot = cum[-1]
    worst = 0.0
    for c in range(g.shape[1]):
        if tot[c] <= 0.0:
            continue
        k = int(np.searchsorted(cum[:, c], (1.0 - truncation) * tot[c]))
        worst = max(worst, float(ti[min(k + 1, n_i - 1)]) + 0.5 * np.pi / n_i)
    return float(min(worst, np.pi))


def _integrand(
    lobe: Lobe, w: FloatArray, v: FloatArray, n: FloatArray, c: FloatArray
) -> FloatArray:
    """``rho_hat`` for light w, view v, normal n, centre c (broadcastable (..., 3)); returns (..., channels)."""
    if isinstance(lobe, IsotropicBRDF):
        w, v, n = np.broadcast_arrays(w, v, n)
        ndl = np.einsum("...k,...k->...", n, w)
        ndv = np.einsum("...k,...k->...", n, v)
        ok = (ndl > 0.0) & (ndv > 0.0)
        val = np.asarray(lobe.f(w, v, n), dtype=np.float64)
        if val.ndim == ndl.ndim:
            val = val[..., None]
        return np.where(ok[..., None], val * np.clip(ndl, 0.0, None)[..., None], 0.0)
    cos_i = np.clip(np.einsum("...k,...k->...", c, w), -1.0, 1.0)
    if isinstance(lobe, RadialLobe):
        val = np.asarray(lobe.u(cos_i), dtype=np.float64)
        return val[..., None] if val.ndim == cos_i.ndim else val
    cos_o = np.clip(np.einsum("...k,...k->...", c, v), -1.0, 1.0)
    a = w - cos_i[..., None] * c
    b = v - cos_o[..., None] * c
    na = np.linalg.norm(a, axis=-1)
    nb = np.linalg.norm(b, axis=-1)
    good = (na > 1e-12) & (nb > 1e-12)
    cos_phi = np.where(good, np.einsum("...k,...k->...", a, b) / np.where(good, na * nb, 1.0), 1.0)
    phi = np.arccos(np.clip(cos_phi, -1.0, 1.0))
    ti, to, ph = np.broadcast_arrays(np.arccos(cos_i), np.arccos(cos_o), phi)
    val = np.asarray(lobe.rho_hat(ti, to, ph), dtype=np.float64)
    return val[..., None] if val.ndim == ti.ndim else val


def reflected_radiance(
    pixels: NDArray[np.floating],
    brdf: Any,
    normals: NDArray[np.floating],
    view: NDArray[np.floating],
    *,
    truncation: float = DEFAULT_TRUNCATION,
    chunk_elems: int = CHUNK_ELEMS,
    group: int = GROUP_SIZE,
) -> FloatArray:
    """``B(N, V)`` of eq. 1 for every normal (n, 3) and one distant view V (3,) by pixel sums, (n, 3).

    ``brdf`` is a lobe or a sum of lobes (``.lobes``); N . V <= 0 gives 0 (the surface faces away). The pixels are
    visited in the blocks of :func:`block_plan`.
    """
    env = np.asarray(pixels, dtype=np.float64)
    try:
        h, w = check_latlong_shape(env.shape)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if env.ndim != 3 or env.shape[2] != 3:
        raise InputError(f"the environment map must be (H, W, 3), got shape {env.shape}")
    v = unit_view(view)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    refl = reflect_dirs(nrm, v)
    env_dirs = latlong_dirs(h, w)
    weighted = env * pixel_solid_angles(h, w)[:, None, None]  # L_k dOmega_k
    out = np.zeros((nrm.shape[0], 3))
    for lobe in brdf_lobes(brdf):
        plan = block_plan(lobe, nrm, refl, v, h, truncation, group=group, chunk_elems=chunk_elems)
        cos_star = np.cos(plan.theta_star)
        for grp in plan.groups:
            idx = grp.outputs
            c = plan.centres[idx]
            acc = np.zeros((idx.size, 3))
            for sl in grp.blocks():
                block = grp.rows[sl]
                d = env_dirs[block].reshape(-1, 3)
                lw = weighted[block].reshape(-1, 3)
                mask = c @ d.T >= cos_star[idx][:, None]  # (G, n): pairs inside the truncation cones
                inside = int(np.count_nonzero(mask))
                if inside == 0:
                    continue
                if is_dense(inside, mask.size):  # wide lobe: evaluate densely, no index arrays
                    val = _integrand(lobe, d[None], v[None, None], nrm[idx][:, None], c[:, None])
                    val = np.where(mask[..., None], val, 0.0)
                    if val.shape[-1] == 1:
                        acc += val[..., 0] @ lw
                    elif val.shape[-1] == 3:
                        acc += np.einsum("gnc,nc->gc", val, lw)
                    else:
                        raise InputError(f"lobe {lobe.kind!r} returned {val.shape[-1]} channels; expected 1 or 3")
                    continue
                io, ie = np.nonzero(mask)
                val = _integrand(lobe, d[ie], v[None], nrm[idx][io], c[io])
                if val.shape[1] not in (1, 3):
                    raise InputError(f"lobe {lobe.kind!r} returned {val.shape[1]} channels; expected 1 or 3")
                contrib = val * lw[ie]
                for ch in range(3):
                    acc[:, ch] += np.bincount(io, weights=contrib[:, ch], minlength=idx.size)
            out[idx] += acc
    return out


def reference_view(
    pixels: NDArray[np.floating],
    brdf: Any,
    view: NDArray[np.floating],
    size: int,
    *,
    truncation: float = DEFAULT_TRUNCATION,
    chunk_elems: int = CHUNK_ELEMS,
) -> FloatArray:
    """Brute-force reflection map for view V indexed by R, (S, 2S, 3) — the reference for ``shrm.reflect``.

    Pixel R: ``N = normalize(R + V)``, then :func:`reflected_radiance`; R = -V (no normal) gives 0.
    """
    validate.at_least("size", size, 1)
    v = unit_view(view)
    r = latlong_dirs(size, 2 * size).reshape(-1, 3)
    n, ok = halfway_normals(r, v)
    out = np.zeros((r.shape[0], 3))
    out[ok] = reflected_radiance(pixels, brdf, n[ok], v, truncation=truncation, chunk_elems=chunk_elems)
    return out.reshape(size, 2 * size, 3)


def reference_sphere(
    pixels: NDArray[np.floating],
    brdf: Any,
    view: NDArray[np.floating],
    size: int,
    *,
    truncation: float = DEFAULT_TRUNCATION,
    background: float = 0.0,
) -> FloatArray:
    """Brute-force image of the unit sphere of ``relight.shrm.render_sphere`` (same camera), (size, size, 3)."""
    validate.at_least("size", size, 1)
    v = unit_view(view)
    n, mask = sphere_geometry(v, size)
    out = np.full((size, size, 3), float(background))
    out[mask] = reflected_radiance(pixels, brdf, n[mask], v, truncation=truncation)
    return out


def directional_view(brdf: Any, direction: NDArray[np.floating], irradiance_rgb: NDArray[np.floating],
                     view: NDArray[np.floating], size: int) -> FloatArray:
    """Reflection map (indexed by R as :func:`reference_view`, (S, 2S, 3)) of a directional light of RGB
    irradiance ``E`` (at normal incidence) from ``direction``: ``B(N, V) = E f(s, V, N) max(N . s, 0)``, the
    integrand of eq. 1 at the one direction s (an extracted sun, ``relight.sun``)."""
    validate.at_least("size", size, 1)
    v = unit_view(view)
    s = np.asarray(direction, dtype=np.float64)
    s = s / np.linalg.norm(s)
    e = np.asarray(irradiance_rgb, dtype=np.float64)
    r = latlong_dirs(size, 2 * size).reshape(-1, 3)
    n, ok = halfway_normals(r, v)
    out = np.zeros((r.shape[0], 3))
    nrm = n[ok]
    for lobe in brdf_lobes(brdf):
        c = lobe_centres(str(lobe.center), nrm, reflect_dirs(nrm, v))
        val = _integrand(lobe, s[None], v[None], nrm, c)
        facing = (nrm @ v) > 0.0
        out[ok] += np.where(facing[:, None], val * e, 0.0)
    return out.reshape(size, 2 * size, 3)
