"""Spherical harmonic transforms on the project's lat-long grid (seed 000 §6.1, App. A).

Conventions (``docs/conventions.md``): orthonormal complex harmonics with the Condon–Shortley phase,
``Y_lm(theta, phi) = Pbar_lm(cos theta) e^{i m phi}`` with ``int |Y_lm|^2 dOmega = 1`` — identical to
``scipy.special.sph_harm_y`` and to ducc0. Theta is measured from +Y; rows of an ``H x W`` lat-long map are
the pixel-centred rings ``theta_i = (i + 1/2) pi / H`` (ducc0 geometry ``F1``); column ``j`` is at
``phi_j = -pi + (j + 1/2) 2 pi / W``.

Coefficients of a real field are stored in the ``healpy`` layout of :mod:`relight.indexing` (ducc0's): complex
``a_lm`` for ``0 <= m <= l <= lmax`` (:func:`relight.indexing.healpy_index`); ``a_{l,-m} = (-1)^m conj(a_lm)``.
``to_real`` / ``from_real`` convert to the real basis (``Yr_{l,m>0} = sqrt2 (-1)^m Re Y_lm``, ``Yr_{l,m<0} =
sqrt2 (-1)^m Im Y_{l|m|}``) stored in the ``full`` layout (:func:`relight.indexing.full_index`, ``l^2 + l + m``).

Two implementations sit behind each call (``backend=``):

* ``"ducc0"`` — the fast, accurate library (stable to l ~ 4000; docs/facts.md).
* ``"numpy"`` — the paper's separable algorithm written plainly (§6.1): an FFT over phi, then Legendre sums over
  theta, with the normalised associated Legendre functions from a scaled three-term recursion that neither
  underflows (``sin^m theta`` near m ~ l/e) nor overflows. Used to test the fast path.

Lighting is projected by *quadrature over the pixels* (Fejér's first rule in cos theta, exact for band-limited
signals), never by a band-limited analysis that folds a sun into low orders (docs/facts.md).
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from typing import Literal

import ducc0
import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import check_latlong_shape, phi0, ring_thetas
from relight.indexing import full_indices, full_size, healpy_index, healpy_lm, healpy_size
from relight.settings import SETTINGS, limit_blas_threads

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Backend = Literal["ducc0", "numpy"]

#: Threads ducc0 may use (RELIGHT_THREADS, :mod:`relight.settings`); BLAS is limited to the same count here, once
#: NumPy has loaded it (do not run two thread pools at their own defaults, docs/facts.md).
NTHREADS = SETTINGS.threads
limit_blas_threads()

# Scaled recursion: mantissas are renormalised by 2^-600 once they exceed 2^600 (well inside float64 range).
_BIG = 2.0**600
_LOG_BIG = 600.0 * np.log(2.0)


def truncate(alm: ComplexArray, lmax: int, new_lmax: int) -> ComplexArray:
    """Coefficients up to ``new_lmax <= lmax`` (leading axes kept)."""
    if new_lmax > lmax:
        raise ValueError(f"cannot truncate order {lmax} to a higher order {new_lmax}")
    l, m = healpy_lm(new_lmax)
    return np.ascontiguousarray(alm[..., healpy_index(l, m, lmax)])


# -------------------------------------------------------------------------------- real <-> complex forms
def to_real(alm: ComplexArray, lmax: int) -> FloatArray:
    """Real-basis coefficients (..., (lmax+1)^2), ``full`` layout, from complex ``a_lm`` (healpy) of a real field."""
    l, m = healpy_lm(lmax)
    out = np.zeros(alm.shape[:-1] + (full_size(lmax),))
    zero = m == 0
    out[..., full_indices(l[zero], 0)] = alm[..., zero].real
    pos = ~zero
    sign = np.where(m[pos] % 2 == 0, 1.0, -1.0)
    out[..., full_indices(l[pos], m[pos])] = np.sqrt(2.0) * sign * alm[..., pos].real
    out[..., full_indices(l[pos], -m[pos])] = -np.sqrt(2.0) * sign * alm[..., pos].imag
    return out


def from_real(coeffs: FloatArray, lmax: int) -> ComplexArray:
    """Inverse of ``to_real``."""
    if coeffs.shape[-1] != full_size(lmax):
        raise ValueError(f"expected {full_size(lmax)} real coefficients for lmax={lmax}, got {coeffs.shape[-1]}")
    l, m = healpy_lm(lmax)
    out = np.zeros(coeffs.shape[:-1] + (healpy_size(lmax),), dtype=np.complex128)
    zero = m == 0
    out[..., zero] = coeffs[..., full_indices(l[zero], 0)]
    pos = ~zero
    sign = np.where(m[pos] % 2 == 0, 1.0, -1.0)
    re = coeffs[..., full_indices(l[pos], m[pos])] * sign / np.sqrt(2.0)
    im = -coeffs[..., full_indices(l[pos], -m[pos])] * sign / np.sqrt(2.0)
    out[..., pos] = re + 1j * im
    return out


def power_spectrum(alm: ComplexArray, lmax: int) -> FloatArray:
    """Energy per band ``E_l = sum_{m=-l..l} |a_lm|^2`` of a real field, shape (..., lmax+1).

    Parseval: ``sum_l E_l`` is the field's ``int f^2 dOmega`` when the field is band-limited to ``lmax``.
    """
    l, m = healpy_lm(lmax)
    e = np.abs(alm) ** 2 * np.where(m == 0, 1.0, 2.0)
    flat = e.reshape(-1, e.shape[-1])
    out = np.stack([np.bincount(l, weights=row, minlength=lmax + 1) for row in flat])
    return np.asarray(out.reshape(alm.shape[:-1] + (lmax + 1,)), dtype=np.float64)


# ------------------------------------------------------------------------------------ quadrature weights
def fejer1_weights(n: int) -> FloatArray:
    """Ring weights of Fejér's first rule on ``theta_k = (k + 1/2) pi / n``, normalised to sum 4 pi.

    ``int f dOmega ~= sum_k w_k mean_phi f(theta_k, .)``; exact for polynomials in cos(theta) of degree < n.
    Notes: ``int_{-1}^{1} g(x) dx ~= (2/n) sum_k g(x_k) [1 - 2 sum_{j=1}^{n/2} cos(2 j theta_k) / (4 j^2 - 1)]``
    (Waldvogel 2006, eq. 2.5); the azimuthal integral contributes the factor 2 pi.
    """
    theta = ring_thetas(n)
    j = np.arange(1, n // 2 + 1)
    s = np.cos(2.0 * np.outer(theta, j)) / (4.0 * j**2 - 1.0)
    return np.asarray(2.0 * np.pi * (2.0 / n) * (1.0 - 2.0 * s.sum(axis=1)), dtype=np.float64)


def quadrature_weights(height: int, kind: Literal["fejer", "area"] = "fejer") -> FloatArray:
    """Per-ring weights (sum 4 pi). ``fejer``: Fejér's first rule (ducc0 ``F1``); ``area``: exact pixel areas."""
    if kind == "fejer":
        return np.asarray(ducc0.sht.experimental.get_gridweights("F1", height), dtype=np.float64)
    if kind == "area":
        edges = np.arange(height + 1) * np.pi / height
        return 2.0 * np.pi * (np.cos(edges[:-1]) - np.cos(edges[1:]))
    raise ValueError(f"unknown quadrature kind {kind!r}; use 'fejer' or 'area'")


# ----------------------------------------------------------------------------- Legendre (NumPy reference)
def _log_pmm(mmax: int) -> FloatArray:
    """``log |Pbar_mm| - m log sin(theta)`` = 0.5 log((2m+1)/(4 pi) prod_{k<=m} (2k-1)/(2k))."""
    k = np.arange(1, mmax + 1)
    cum = np.concatenate([[0.0], np.cumsum(np.log((2.0 * k - 1.0) / (2.0 * k)))])
    m = np.arange(mmax + 1)
    return np.asarray(0.5 * (np.log((2.0 * m + 1.0) / (4.0 * np.pi)) + cum), dtype=np.float64)


def legendre_rows(lmax: int, theta: NDArray[np.floating], mmax: int | None = None) -> Iterator[FloatArray]:
    """Yield ``Pbar_lm(cos theta)`` for l = 0..lmax as arrays (min(l, mmax) + 1, ntheta).

    ``Y_lm = Pbar_lm(cos theta) e^{i m phi}`` (orthonormal, Condon–Shortley phase).

    Notes
    -----
    Start ``Pbar_mm = (-1)^m sqrt((2m+1)/(4 pi) prod_{k=1}^m (2k-1)/(2k)) sin^m theta`` and recur upward in l:
    ``Pbar_{m+1,m} = sqrt(2m+3) x Pbar_mm`` and
    ``Pbar_lm = a_lm (x Pbar_{l-1,m} - b_lm Pbar_{l-2,m})`` with ``a_lm = sqrt((4l^2-1)/(l^2-m^2))``,
    ``b_lm = sqrt(((l-1)^2-m^2)/(4(l-1)^2-1))``. Each (m, theta) carries a mantissa and a log-scale:
    ``Pbar = mantissa * exp(scale)``; ``sin^m theta`` lives in the scale, so nothing underflows until the final
    ``exp``, where a value below 1e-308 is truly negligible.
    """
    theta = np.atleast_1d(np.asarray(theta, dtype=np.float64))
    mmax = lmax if mmax is None else min(mmax, lmax)
    x = np.cos(theta)[None, :]
    with np.errstate(divide="ignore"):
        log_sin = np.log(np.abs(np.sin(theta)))[None, :]
    m = np.arange(mmax + 1)[:, None].astype(np.float64)
    # (M, T): -inf at the poles for m > 0 (Pbar_mm = 0 there); m = 0 has no sin factor at all
    with np.errstate(invalid="ignore"):  # 0 * -inf for m = 0 at a pole; replaced by 0 just below
        log_pmm = _log_pmm(mmax)[:, None] + np.where(m > 0, m * log_sin, 0.0)
    sign_mm = np.where(np.arange(mmax + 1) % 2 == 0, 1.0, -1.0)[:, None]
    nt = theta.size
    p1 = np.zeros((mmax + 1, nt))  # mantissa at l-1
    p2 = np.zeros((mmax + 1, nt))  # mantissa at l-2
    scale = np.zeros((mmax + 1, nt))
    for l in range(lmax + 1):
        new = np.zeros((mmax + 1, nt))
        mm = min(l, mmax)
        # general recursion for m <= l - 2
        k = min(l - 1, mmax + 1)  # rows 0..k-1 have m <= l-2
        if k > 0:
            mv = np.arange(k, dtype=np.float64)[:, None]
            a = np.sqrt((4.0 * l * l - 1.0) / (l * l - mv * mv))
            b = np.sqrt(((l - 1.0) ** 2 - mv * mv) / (4.0 * (l - 1.0) ** 2 - 1.0))
            new[:k] = a * (x * p1[:k] - b * p2[:k])
        if 1 <= l and l - 1 <= mmax:
            new[l - 1] = np.sqrt(2.0 * (l - 1) + 3.0) * x[0] * p1[l - 1]
        if l <= mmax:
            new[l] = sign_mm[l]
            scale[l] = log_pmm[l]
            p1[l] = 0.0
        p2, p1 = p1, new
        big = np.abs(p1) > _BIG
        if np.any(big):
            p1 = np.where(big, p1 / _BIG, p1)
            p2 = np.where(big, p2 / _BIG, p2)
            scale = np.where(big, scale + _LOG_BIG, scale)
        with np.errstate(under="ignore"):
            yield p1[: mm + 1] * np.exp(scale[: mm + 1])


def legendre(l: int, m: int, theta: NDArray[np.floating]) -> FloatArray:
    """``Pbar_lm(cos theta)`` for one (l, m), m >= 0, by the scaled recursion (reference, O(l^2) rows)."""
    if not 0 <= m <= l:
        raise ValueError(f"need 0 <= m <= l, got l={l}, m={m}")
    last = functools.reduce(lambda _, row: row, legendre_rows(l, theta, mmax=m))
    return np.asarray(last[m], dtype=np.float64)


# ---------------------------------------------------------------------------------------------- transforms
def _as_stack(field: NDArray[np.floating]) -> tuple[FloatArray, bool]:
    """(C, H, W) float64 view of an (H, W) or (H, W, C) map; the flag says whether it had a channel axis."""
    a = np.asarray(field, dtype=np.float64)
    if a.ndim == 2:
        return a[None], False
    if a.ndim == 3:
        return np.ascontiguousarray(np.moveaxis(a, -1, 0)), True
    raise ValueError(f"expected an (H, W) or (H, W, C) map, got shape {a.shape}")


def project(
    field: NDArray[np.floating],
    lmax: int,
    *,
    backend: Backend = "ducc0",
    weights: Literal["fejer", "area"] = "fejer",
    nthreads: int | None = None,
) -> ComplexArray:
    """Coefficients ``a_lm = int f Y*_lm dOmega`` of a lat-long field by quadrature over its pixels (§6.1).

    ``field`` is (H, W) or (H, W, C) with W = 2H; returns (nalm,) or (C, nalm) complex128.
    """
    validate.at_least("lmax", lmax, 0)
    a = np.asarray(field)
    if a.ndim not in (2, 3):
        raise ValueError(f"expected an (H, W) or (H, W, C) map, got shape {a.shape}")
    chan = a.ndim == 3
    h, w = check_latlong_shape(a.shape)
    ring_w = quadrature_weights(h, weights)
    if backend == "ducc0":
        planes = [a[..., k] for k in range(a.shape[2])] if chan else [a]
        # Each channel is a strided view (no copy for float64 input); the ring weights go in as ducc0's
        # ``ringfactor``, so ``a_lm = sum_rings (w_ring / W) sum_phi f e^{-i m phi} Pbar_lm``.
        alm = np.stack(
            [
                ducc0.sht.adjoint_synthesis_2d(
                    map=np.asarray(plane, dtype=np.float64)[None], spin=0, lmax=lmax, geometry="F1",
                    phi0=phi0(w), ringfactor=ring_w / w, nthreads=nthreads or NTHREADS,
                )[0]
                for plane in planes
            ]
        )
    elif backend == "numpy":
        stack, _ = _as_stack(a)
        alm = _project_numpy(stack, lmax, ring_w)
    else:
        raise ValueError(f"unknown backend {backend!r}; use 'ducc0' or 'numpy'")
    alm = np.asarray(alm, dtype=np.complex128)
    return alm if chan else alm[0]


def _project_numpy(stack: FloatArray, lmax: int, ring_w: FloatArray) -> ComplexArray:
    """§6.1: ``L_m(theta) = int L e^{-i m phi} dphi`` by FFT, then ``L_lm = int L_m Pbar_lm sin dtheta``."""
    c, h, w = stack.shape
    if lmax > w // 2 - 1:
        raise ValueError(f"numpy backend needs lmax < W/2 = {w // 2}, got {lmax}")
    m = np.arange(lmax + 1)
    spec = np.fft.fft(stack, axis=-1)[..., : lmax + 1]  # sum_j f_j e^{-2 pi i m j / W}
    g = spec * np.exp(-1j * m * phi0(w))[None, None, :] * (ring_w / w)[None, :, None]  # (C, H, M)
    out = np.zeros((c, healpy_size(lmax)), dtype=np.complex128)
    for l, row in enumerate(legendre_rows(lmax, ring_thetas(h))):
        mm = np.arange(l + 1)
        out[:, healpy_index(l, mm, lmax)] = np.einsum("mt,ctm->cm", row, g[:, :, : l + 1])
    return out


def synthesize(
    alm: ComplexArray,
    lmax: int,
    height: int,
    width: int | None = None,
    *,
    backend: Backend = "ducc0",
    nthreads: int | None = None,
) -> FloatArray:
    """Evaluate ``f = sum a_lm Y_lm`` on an ``height x width`` lat-long grid (default width = 2 height).

    ``alm`` is (nalm,) or (C, nalm); returns (H, W) or (H, W, C).
    """
    width = 2 * height if width is None else width
    a = np.asarray(alm, dtype=np.complex128)
    chan = a.ndim == 2
    a2 = a if chan else a[None]
    if a2.shape[-1] != healpy_size(lmax):
        raise ValueError(f"expected {healpy_size(lmax)} coefficients for lmax={lmax}, got {a2.shape[-1]}")
    if backend == "ducc0":
        # ducc0 evaluates exactly on rings with nphi < 2 lmax + 1 too (it aliases the higher m correctly).
        out = np.concatenate(
            [
                ducc0.sht.synthesis_2d(
                    alm=np.ascontiguousarray(a2[k : k + 1]), spin=0, lmax=lmax, geometry="F1",
                    ntheta=height, nphi=width, phi0=phi0(width), nthreads=nthreads or NTHREADS,
                )
                for k in range(a2.shape[0])
            ]
        )
    elif backend == "numpy":
        # Evaluate on a grid fine enough for every m, starting at the same azimuth, then keep every k-th column.
        k = max(1, -(-(2 * lmax + 2) // width))
        fine = _synthesize_numpy(a2, lmax, height, k * width, first_phi=phi0(width))
        out = fine[..., ::k]
    else:
        raise ValueError(f"unknown backend {backend!r}; use 'ducc0' or 'numpy'")
    out = np.asarray(out, dtype=np.float64)
    return np.moveaxis(out, 0, -1) if chan else out[0]


def _synthesize_numpy(alm: ComplexArray, lmax: int, height: int, width: int, first_phi: float) -> FloatArray:
    """Inverse of §6.1: ``c_m(theta) = sum_l a_lm Pbar_lm``, then an inverse real FFT over phi (needs W > 2 lmax)."""
    c = alm.shape[0]
    mmax = lmax
    cm = np.zeros((c, height, mmax + 1), dtype=np.complex128)
    for l, row in enumerate(legendre_rows(lmax, ring_thetas(height), mmax=mmax)):
        mm = np.arange(row.shape[0])
        cm[..., : row.shape[0]] += np.einsum("mt,cm->ctm", row, alm[:, healpy_index(l, mm, lmax)])
    m = np.arange(mmax + 1)
    g = cm * np.exp(1j * m * first_phi)
    full = np.zeros((c, height, width // 2 + 1), dtype=np.complex128)
    full[..., : mmax + 1] = g
    # irfft(n=W) computes (1/W)(g_0 + 2 Re sum_{m>0} g_m e^{2 pi i m j/W}); a real field needs exactly that sum.
    return np.asarray(np.fft.irfft(full, n=width, axis=-1) * width, dtype=np.float64)


def evaluate(alm: ComplexArray, lmax: int, dirs_theta: FloatArray, dirs_phi: FloatArray) -> FloatArray:
    """``sum a_lm Y_lm`` at arbitrary angles (flat arrays); (N,) or (N, C). Uses ducc0 ``synthesis_general``."""
    a = np.asarray(alm, dtype=np.complex128)
    chan = a.ndim == 2
    a2 = a if chan else a[None]
    loc = np.stack([np.ravel(dirs_theta), np.mod(np.ravel(dirs_phi), 2.0 * np.pi)], axis=-1).astype(np.float64)
    out = np.concatenate(
        [
            ducc0.sht.synthesis_general(
                alm=np.ascontiguousarray(a2[k : k + 1]), spin=0, lmax=lmax, loc=loc, epsilon=1e-13,
                nthreads=NTHREADS,
            )
            for k in range(a2.shape[0])
        ]
    )
    out = np.asarray(out, dtype=np.float64)
    return out.T if chan else out[0]
