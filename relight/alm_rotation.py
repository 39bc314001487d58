"""Rotation of spherical-harmonic coefficients by z-y-z Euler angles, ``R = R_z(alpha) R_y(beta) R_z(gamma)``
(seed 000 Table 1, App. A eq. 14), with the Wigner matrices of :mod:`relight.wigner` and their convention.

For the orthonormal complex harmonics with Condon-Shortley phase, ``Y_lm(R^{-1} x) = sum_{m'} Y_lm'(x)
D^l_{m'm}(R)`` (:func:`relight.wigner.wigner_D_matrix`), so the actively rotated field ``f'(x) = f(R^{-1} x)`` has
coefficients ``a'_{lm'} = sum_m D^l_{m'm}(R) a_lm`` (:func:`rotate_alm`; ducc0's ``rotate_alm`` is the fast path).
"""

from __future__ import annotations

import ducc0
import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.indexing import full_block, full_indices, full_size, healpy_lm, healpy_size
from relight.wigner import check_lmax, wigner_D_matrix

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


def rotation_matrix_zyz(alpha: float, beta: float, gamma: float) -> FloatArray:
    """The 3x3 matrix ``R = R_z(alpha) R_y(beta) R_z(gamma)`` (active, right-handed) in the SH frame (x, y, z)."""

    def rz(a: float) -> FloatArray:
        return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])

    cb, sb = np.cos(beta), np.sin(beta)
    ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    return np.asarray(rz(alpha) @ ry @ rz(gamma), dtype=np.float64)


def _check_alm(alm: ArrayLike, lmax: int) -> ComplexArray:
    a = np.asarray(alm)
    if a.ndim < 1 or a.shape[-1] != full_size(lmax):
        raise InputError(f"alm must have a trailing axis of length (lmax+1)^2 = {full_size(lmax)}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError("alm must be finite")
    return np.asarray(a, dtype=np.complex128)


def rotate_alm(
    alm: ArrayLike, lmax: int, alpha: float, beta: float, gamma: float, *, method: str = "ducc0"
) -> ComplexArray:
    """Coefficients of the actively rotated field ``f'(x) = f(R^{-1} x)``, ``R = R_z(alpha) R_y(beta) R_z(gamma)``.

    ``alm`` holds any complex field's coefficients in the ``full`` layout of :mod:`relight.indexing` (``l^2 + l + m``)
    for the orthonormal CS-phase harmonics of the module docstring; the result is ``a'_{lm'} = sum_m D^l_{m'm}(R)
    a_lm``. ``method="ducc0"`` (fast path) splits the field into two real fields and calls
    ``ducc0.sht.rotate_alm(a, lmax, psi=gamma, theta=beta, phi=alpha)`` (its angles are the successive active
    rotations about z, the original y and the original z); ``method="reference"`` multiplies by the matrices of
    :func:`wigner_D_matrix` (O(lmax^4) in Python-level work, for testing).
    """
    lmax = check_lmax(lmax)
    a = _check_alm(alm, lmax)
    alpha, beta, gamma = (validate.finite(n, v) for n, v in (("alpha", alpha), ("beta", beta), ("gamma", gamma)))
    if method == "reference":
        out = np.empty_like(a)
        for ell in range(lmax + 1):
            sl = full_block(ell)
            out[..., sl] = a[..., sl] @ wigner_D_matrix(ell, alpha, beta, gamma).T
        return out
    if method != "ducc0":
        raise InputError(f"method must be 'ducc0' or 'reference', got {method!r}")
    ls, ms = healpy_lm(lmax)
    pos = full_indices(ls, ms)
    neg = full_indices(ls, -ms)
    sign = np.where(ms % 2 == 0, 1.0, -1.0)
    # f = g + i h with g, h real: g_lm = (a_lm + (-1)^m conj(a_l,-m)) / 2, h_lm = (a_lm - (-1)^m conj(a_l,-m)) / 2i.
    conj_neg = sign * np.conj(a[..., neg])
    g = 0.5 * (a[..., pos] + conj_neg)
    h = -0.5j * (a[..., pos] - conj_neg)
    flat_g = g.reshape(-1, g.shape[-1])
    flat_h = h.reshape(-1, h.shape[-1])
    rg = np.stack([ducc0.sht.rotate_alm(x.copy(), lmax, gamma, beta, alpha) for x in flat_g]).reshape(g.shape)
    rh = np.stack([ducc0.sht.rotate_alm(x.copy(), lmax, gamma, beta, alpha) for x in flat_h]).reshape(h.shape)
    out = np.empty_like(a)
    out[..., pos] = rg + 1j * rh
    out[..., neg] = sign * (np.conj(rg) + 1j * np.conj(rh))
    return out


def rotate_alm_healpy(alm: ArrayLike, lmax: int, alpha: float, beta: float, gamma: float) -> ComplexArray:
    """:func:`rotate_alm` for a *real* field stored in ducc0/healpy's m >= 0 layout (a thin ducc0 wrapper).

    Same rotation ``R = R_z(alpha) R_y(beta) R_z(gamma)`` and identity as :func:`rotate_alm`;
    ``alm`` has shape ``(..., (lmax+1)(lmax+2)/2)``.
    """
    lmax = check_lmax(lmax)
    a = np.asarray(alm, dtype=np.complex128)
    n = healpy_size(lmax)
    if a.ndim < 1 or a.shape[-1] != n:
        raise InputError(f"alm must have a trailing axis of length (lmax+1)(lmax+2)/2 = {n}, got shape {a.shape}")
    flat = a.reshape(-1, n)
    return np.stack([ducc0.sht.rotate_alm(x.copy(), lmax, gamma, beta, alpha) for x in flat]).reshape(a.shape)
