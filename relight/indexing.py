"""Coefficient packing layouts, each named by its layout and written once (docs/conventions.md, "Layouts").

Two packings of spherical-harmonic coefficients exist in the project:

``healpy`` — ducc0's / healpy's triangular, m-major layout of the complex coefficients of a *real* field:
    ``a_lm`` for ``0 <= m <= l <= lmax`` at index ``m (2 lmax + 1 - m) / 2 + l``, i.e. ``(0,0), (1,0), ..,
    (lmax,0), (1,1), .., (lmax,lmax)``; ``(lmax + 1)(lmax + 2) / 2`` entries (``a_{l,-m} = (-1)^m conj(a_lm)``
    is implied). What :mod:`relight.sh` and ducc0's transforms use (ducc0 ``sht`` documentation, "alm layout").

``full`` — l-major with every order ``m = -l..l``: index ``l^2 + l + m``; ``(lmax + 1)^2`` entries, degree ``l``
    occupying the block ``[l^2, (l + 1)^2)`` (:func:`full_block`). Used for real-basis coefficients
    (:func:`relight.sh.to_real`), the complex coefficients of any (not necessarily real) field
    (:func:`relight.alm_rotation.rotate_alm`), the SHRM terms ``(p, q)`` (:mod:`relight.shrm`) and the viewer's texture
    layers (:mod:`relight.gl.layout`). The same formula serves (l, m) and (p, q).

(The BRDF coefficients ``rho_hat_lpq`` of :mod:`relight.brdf.lpq` are not packed: a dense array ``rho[l, p, q]``
with ``0 <= q <= p``.)
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

IntArray = NDArray[np.intp]


def _check_order(lmax: int, what: str = "lmax") -> int:
    if isinstance(lmax, bool) or not isinstance(lmax, int | np.integer) or lmax < 0:
        raise ValueError(f"{what} must be a non-negative integer, got {lmax!r}")
    return int(lmax)


# ------------------------------------------------------------------------------------------------- healpy
def healpy_size(lmax: int, mmax: int | None = None) -> int:
    """Entries of the healpy layout for ``0 <= m <= mmax``, ``m <= l <= lmax`` (``mmax`` defaults to ``lmax``)."""
    lmax = _check_order(lmax)
    mmax = lmax if mmax is None else _check_order(mmax, "mmax")
    if mmax > lmax:
        raise ValueError(f"mmax={mmax} exceeds lmax={lmax}")
    return ((mmax + 1) * (mmax + 2)) // 2 + (mmax + 1) * (lmax - mmax)


def healpy_index(l: ArrayLike, m: ArrayLike, lmax: int) -> IntArray:
    """Index of ``a_lm`` (``0 <= m <= l <= lmax``) in the healpy layout of order ``lmax``."""
    l_arr = np.asarray(l, dtype=np.intp)
    m_arr = np.asarray(m, dtype=np.intp)
    if np.any(m_arr < 0) or np.any(m_arr > l_arr) or np.any(l_arr > lmax):
        raise ValueError(f"need 0 <= m <= l <= lmax={lmax}, got l={l_arr.tolist()}, m={m_arr.tolist()}")
    return np.asarray(m_arr * (2 * lmax + 1 - m_arr) // 2 + l_arr, dtype=np.intp)


def healpy_lm(lmax: int) -> tuple[IntArray, IntArray]:
    """(l, m) of every entry of the healpy layout, in storage order."""
    lmax = _check_order(lmax)
    m = np.repeat(np.arange(lmax + 1, dtype=np.intp), np.arange(lmax + 1, 0, -1))
    l = np.concatenate([np.arange(k, lmax + 1, dtype=np.intp) for k in range(lmax + 1)])
    return l, m


def healpy_lmax(size: int) -> int:
    """The order ``lmax`` whose full healpy triangle has ``size`` entries (inverse of :func:`healpy_size`)."""
    lmax = int(round((math.sqrt(8 * size + 1) - 3) / 2)) if size > 0 else -1
    if lmax < 0 or healpy_size(lmax) != size:
        raise ValueError(f"{size} is not the size of a full healpy coefficient triangle")
    return lmax


# --------------------------------------------------------------------------------------------------- full
def full_size(lmax: int) -> int:
    """Entries of the full layout up to ``lmax``: ``(lmax + 1)^2``."""
    lmax = _check_order(lmax)
    return (lmax + 1) ** 2


def full_index(l: int, m: int) -> int:
    """Index ``l^2 + l + m`` of (l, m) (or (p, q)) in the full layout, ``|m| <= l``."""
    if l < 0 or abs(m) > l:
        raise ValueError(f"need |m| <= l, l >= 0, got l={l}, m={m}")
    return l * l + l + m


def full_indices(l: ArrayLike, m: ArrayLike) -> IntArray:
    """:func:`full_index` for arrays of (l, m), broadcast."""
    l_arr = np.asarray(l, dtype=np.intp)
    m_arr = np.asarray(m, dtype=np.intp)
    if np.any(l_arr < 0) or np.any(np.abs(m_arr) > l_arr):
        raise ValueError(f"need |m| <= l, l >= 0, got l={l_arr.tolist()}, m={m_arr.tolist()}")
    return np.asarray(l_arr * l_arr + l_arr + m_arr, dtype=np.intp)


def full_lm(lmax: int) -> tuple[IntArray, IntArray]:
    """(l, m) of every entry of the full layout, in storage order."""
    lmax = _check_order(lmax)
    l = np.repeat(np.arange(lmax + 1, dtype=np.intp), 2 * np.arange(lmax + 1) + 1)
    return l, np.arange(l.size, dtype=np.intp) - l * l - l


def full_block(l: int) -> slice:
    """The entries of degree ``l`` in the full layout: ``slice(l^2, (l + 1)^2)``, ordered m = -l..l."""
    l = _check_order(l, "l")
    return slice(l * l, (l + 1) ** 2)


def full_lmax(size: int) -> int:
    """The order ``lmax`` whose full layout has ``size`` entries (inverse of :func:`full_size`)."""
    lmax = math.isqrt(size) - 1 if size > 0 else -1
    if lmax < 0 or full_size(lmax) != size:
        raise ValueError(f"{size} is not the size of a full (lmax + 1)^2 coefficient layout")
    return lmax
