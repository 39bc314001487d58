"""Real Gaunt coefficients ``G_ijk = int Yr_i Yr_j Yr_k dOmega`` and the product (triple-product) matrices they give.

For a function V with real SH coefficients ``v_k`` the matrix of "multiply by V" on the band-limited functions of
order F is ``M_ij = int V Yr_i Yr_j dOmega = sum_k v_k G_ijk`` (Ng, Ramamoorthi & Hanrahan 2004, "Triple product
wavelet integrals", §3; Sloan et al. 2002 §5's transfer matrix of a shadow-only transport). ``Yr_i Yr_j`` is a
polynomial of degree ``2F`` on the sphere, so the sum over k stops at order 2F *exactly*: the contraction of V's
coefficients to order 2F reproduces M to rounding, and truncating V at order F leaves the bands F < l <= 2F out
(:func:`contraction_bound` bounds what they can contribute).

The coefficients are computed by a product quadrature exact for the integrand (degree ``La + Lb + Lc``): Gauss–
Legendre in ``cos theta`` with ``ceil((La + Lb + Lc + 1) / 2)`` nodes times ``La + Lb + Lc + 1`` equally spaced
azimuths — independent of the Monte Carlo directions of ``relight.visibility``.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from relight.shrm import real_harmonics

FloatArray = NDArray[np.float64]


@functools.cache
def real_gaunt(order_a: int, order_b: int, order_c: int) -> FloatArray:
    """``G[i, j, k] = int Yr_i Yr_j Yr_k`` for ``i`` of order ``order_a``, ``j`` of ``order_b``, ``k`` of ``order_c``
    (relight's real basis, index ``l^2 + l + m``), shape ((a+1)^2, (b+1)^2, (c+1)^2). Read-only (cached)."""
    degree = order_a + order_b + order_c
    x, w = np.polynomial.legendre.leggauss(degree // 2 + 1)
    n_phi = degree + 1
    theta = np.arccos(x)[:, None]
    phi = (2.0 * np.pi * np.arange(n_phi) / n_phi)[None, :]
    weights = (w[:, None] * np.full((1, n_phi), 2.0 * np.pi / n_phi)).ravel()
    top = max(order_a, order_b, order_c)
    y = real_harmonics(top, theta, phi).reshape(-1, (top + 1) ** 2)
    ya, yb, yc = y[:, : (order_a + 1) ** 2], y[:, : (order_b + 1) ** 2], y[:, : (order_c + 1) ** 2]
    g = np.einsum("q,qi,qj,qk->ijk", weights, ya, yb, yc, optimize=True)
    g[np.abs(g) < 1e-14] = 0.0
    g.setflags(write=False)
    return np.asarray(g, dtype=np.float64)


def product_matrix(coeffs: NDArray[np.floating], coeff_order: int, order: int) -> FloatArray:
    """``M_ij = sum_k v_k G_ijk`` (module docstring) for coefficients (..., (coeff_order+1)^2): shape
    (..., (order+1)^2, (order+1)^2). Exact for V's projection when ``coeff_order >= 2 order``."""
    v = np.asarray(coeffs, dtype=np.float64)
    if v.shape[-1] != (coeff_order + 1) ** 2:
        raise ValueError(f"expected {(coeff_order + 1) ** 2} coefficients for order {coeff_order}, got {v.shape}")
    used = min(coeff_order, 2 * order)
    g = real_gaunt(order, order, used)
    return np.asarray(np.einsum("...k,ijk->...ij", v[..., : (used + 1) ** 2], g), dtype=np.float64)


def contraction_bound(coeffs: NDArray[np.floating], coeff_order: int, order: int) -> FloatArray:
    """Bound on ``max_ij |M_ij - product_matrix(v truncated at coeff_order)_ij|`` from V's bands above
    ``coeff_order`` (up to 2 order; coefficients (..., (2 order + 1)^2)): by Cauchy–Schwarz
    ``|sum_{k > K} v_k G_ijk| <= ||v_{k > K}|| max_ij ||G_ij, k > K||``. Shape (...)."""
    v = np.asarray(coeffs, dtype=np.float64)
    top = 2 * order
    if v.shape[-1] != (top + 1) ** 2:
        raise ValueError(f"need coefficients to order 2F = {top}, got {v.shape[-1]}")
    k0 = (coeff_order + 1) ** 2
    g = real_gaunt(order, order, top)[:, :, k0:]
    gmax = float(np.sqrt((g * g).sum(axis=2)).max()) if g.size else 0.0
    return np.asarray(np.linalg.norm(v[..., k0:], axis=-1) * gmax, dtype=np.float64)
