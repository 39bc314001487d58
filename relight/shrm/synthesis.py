"""Local SHRM synthesis, seed 000 App. C step 3 / App. A eq. 14: ``B_pq(alpha, beta) = sum_{l,m} L_lm rho_hat_lpq
d^l_mq(alpha) e^{i m beta}``, by ducc0's spin-weighted synthesis (fast path) or literally with ``relight.wigner``'s
d^l_mq (reference); the two are tested against each other to l = 2048 (derivations in :mod:`relight.shrm`).
"""

from __future__ import annotations

from collections.abc import Sequence

import ducc0
import numpy as np

from relight import indexing, sh, wigner
from relight.brdf.coefficients import lambda_l
from relight.conventions import (
    column_phis,
    phi0,
    ring_thetas,
)
from relight.shrm.basis import (
    SQRT2,
    Backend,
    ComplexArray,
    FloatArray,
)


# --------------------------------------------------------------------------------------------- synthesis
def _full_light(alm: ComplexArray, lmax: int, l: int) -> ComplexArray:
    """``L_lm`` for m = -lmax..lmax (zero for |m| > l) of a real field, shape (C, 2 lmax + 1)."""
    m = np.arange(l + 1)
    pos = alm[:, indexing.healpy_index(l, m, lmax)]
    out = np.zeros((alm.shape[0], 2 * lmax + 1), dtype=np.complex128)
    out[:, lmax + m] = pos
    out[:, lmax - m[1:]] = ((-1.0) ** m[1:]) * np.conj(pos[:, 1:])
    return out


def synthesize_local(
    light_alm: ComplexArray,
    light_lmax: int,
    rho: FloatArray,
    terms: Sequence[tuple[int, int]],
    height: int,
    *,
    backend: Backend = "ducc0",
    alphas: FloatArray | None = None,
    nthreads: int | None = None,
) -> FloatArray:
    """Local SHRM maps ``Br_pq(alpha, beta)`` (seed 000 App. C step 3, eq. 14), shape (K, rows, 2 height, C).

    ``light_alm`` (C, nalm(light_lmax)) are ``L_lm``; ``rho[l, p, q, c]`` (``relight.brdf.lpq``) sets the orders:
    F = rho.shape[0] - 1 <= light_lmax. Rows are the lat-long rings of an ``height x 2 height`` map (or, for the
    reference backend only, the given ``alphas``). Grey lobes (one channel) broadcast over the lighting's channels.
    See the module docstring for both backends.
    """
    alm = np.asarray(light_alm, dtype=np.complex128)
    if alm.ndim != 2:
        raise ValueError(f"light_alm must be (channels, nalm), got shape {alm.shape}")
    f_order = rho.shape[0] - 1
    if f_order > light_lmax:
        raise ValueError(f"BRDF order F={f_order} exceeds the lighting order {light_lmax}")
    for p, q in terms:
        if not (0 <= p < rho.shape[1] and abs(q) <= p and abs(q) < rho.shape[2]):
            raise ValueError(f"term (p={p}, q={q}) outside the coefficients' range (F+1, P+1, Q+1) = {rho.shape[:3]}")
    alm = sh.truncate(alm, light_lmax, f_order)
    width = 2 * height
    if backend == "ducc0":
        if alphas is not None:
            raise ValueError("the ducc0 backend evaluates on the lat-long rings only (alphas=None)")
        return _synthesize_ducc0(alm, rho, terms, height, width, nthreads or sh.NTHREADS)
    if backend == "wigner":
        a = ring_thetas(height) if alphas is None else np.asarray(alphas, dtype=np.float64).ravel()
        return _synthesize_wigner(alm, rho, terms, a, width)
    raise ValueError(f"unknown backend {backend!r}; use 'ducc0' or 'wigner'")


def _rho_channel(rho: FloatArray, c: int) -> FloatArray:
    return rho[..., c if rho.shape[-1] > 1 else 0]


def _synthesize_ducc0(
    alm: ComplexArray, rho: FloatArray, terms: Sequence[tuple[int, int]], height: int, width: int, nthreads: int
) -> FloatArray:
    """Fast path: one ducc0 spin-|q| synthesis per (p, |q|, colour) (module docstring)."""
    f_order = rho.shape[0] - 1
    n_c = alm.shape[0]
    l, _ = indexing.healpy_lm(f_order)
    lam = lambda_l(f_order)[l]
    index = {t: k for k, t in enumerate(terms)}
    out = np.zeros((len(terms), height, width, n_c))
    groups = sorted({(p, abs(q)) for p, q in terms})
    for p, qa in groups:
        if qa > f_order:
            continue  # rho_hat_lpq = 0 for l < |q|: the maps are zero
        for c in range(n_c):
            coef = lam * _rho_channel(rho, c)[l, p, qa] * alm[c]
            if qa == 0:
                res = ducc0.sht.synthesis_2d(
                    alm=coef[None], spin=0, lmax=f_order, geometry="F1", ntheta=height, nphi=width,
                    phi0=phi0(width), nthreads=nthreads,
                )
                out[index[(p, 0)], :, :, c] = res[0]
                continue
            coef = coef * (SQRT2 * (-1.0) ** (qa + 1))
            res = ducc0.sht.synthesis_2d(
                alm=coef[None], spin=qa, lmax=f_order, geometry="F1", ntheta=height, nphi=width,
                phi0=phi0(width), nthreads=nthreads, mode="GRAD_ONLY",
            )
            if (p, qa) in index:
                out[index[(p, qa)], :, :, c] = res[0]
            if (p, -qa) in index:
                out[index[(p, -qa)], :, :, c] = res[1]
    return out


def _synthesize_wigner(
    alm: ComplexArray, rho: FloatArray, terms: Sequence[tuple[int, int]], alphas: FloatArray, width: int
) -> FloatArray:
    """Reference: App. C step 3 summed literally with ``relight.wigner``'s d^l_mq (module docstring)."""
    f_order = rho.shape[0] - 1
    n_c = alm.shape[0]
    qs = np.array(sorted({abs(q) for _, q in terms}), dtype=np.int64)
    ps = np.array(sorted({p for p, _ in terms}), dtype=np.int64)
    rho_c = np.stack([_rho_channel(rho, c) for c in range(n_c)], axis=-1)[:, ps][:, :, qs]  # (F+1, np, nq, C)
    ms = np.arange(-f_order, f_order + 1)
    b_m = np.zeros((n_c, ps.size, qs.size, alphas.size, ms.size), dtype=np.complex128)
    q_ok = qs[qs <= f_order]
    if q_ok.size:
        for l, d in wigner.iter_wigner_d(f_order, alphas, q_ok, ms=ms):  # d: (n_alpha, 2F+1, nq_ok)
            light = _full_light(alm, f_order, l)  # (C, 2F+1)
            coef = light[:, :, None, None] * np.moveaxis(rho_c[l, :, : q_ok.size], -1, 0)[:, None]  # (C,M,np,nq)
            b_m[:, :, : q_ok.size] += np.einsum("amq,cmpq->cpqam", d, coef)
    betas = column_phis(width)
    phase = np.exp(1j * np.outer(ms, betas))  # (M, W)
    b = b_m @ phase  # (C, np, nq, n_alpha, W): complex B_pq(alpha, beta) for q >= 0
    out = np.zeros((len(terms), alphas.size, width, n_c))
    for k, (p, q) in enumerate(terms):
        v = b[:, int(np.searchsorted(ps, p)), int(np.searchsorted(qs, abs(q)))]
        if q == 0:
            real = v.real
        elif q > 0:
            real = SQRT2 * (-1.0) ** q * v.real
        else:
            real = -SQRT2 * (-1.0) ** q * v.imag
        out[k] = np.moveaxis(real, 0, -1)
    return out

