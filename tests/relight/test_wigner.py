"""Tests of relight.wigner against independent references.

References: exact sums in mpmath (Wigner's sum, Edmonds 1957 §4.1, evaluated with enough digits that the
alternating sum keeps >= 50 significant digits), the ``spherical`` package (Gumerov-Duraiswami "Wigner H"
recursion, a different algorithm), and scipy's spherical harmonics (rotation identity).
Tolerances are absolute (|d| <= 1) and scale with l: the recursion's error grows about like sqrt(l) ulps.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.special import sph_harm_y

from relight.alm_rotation import rotation_matrix_zyz
from relight.errors import InputError
from relight.wigner import (
    iter_wigner_d,
    wigner_d,
    wigner_D_matrix,
    wigner_d_matrix,
    wigner_d_q,
)

EPS = np.finfo(np.float64).eps
HARD_BETAS = [1e-8, 1e-3, np.pi / 2, np.pi - 1e-6]


def d_exact(ell: int, m1: int, m2: int, beta: float, digits: int = 50) -> float:
    """d^l_{m1 m2}(beta) from the factorial (Wigner) sum, Edmonds 1957 §4.1, in mpmath.

    The sum alternates with terms up to ~C(2l, l) ~ 10^(0.6 l) while the result is <= 1, so the working precision
    is ``digits`` plus the number of decimal digits of the largest term: >= ``digits`` significant digits survive.
    ``beta`` is taken as the exact binary value of the double. Successive terms are formed from their exact ratio
    ``-(s/c)^2 (l+m2-k)(l-m1-k) / ((k+1)(m1-m2+k+1))``.
    """
    dps = digits + int(2 * ell * math.log10(2.0)) + 10
    with mpmath.workdps(dps):
        b = mpmath.mpf(beta)
        c, s = mpmath.cos(b / 2), mpmath.sin(b / 2)
        fac = mpmath.factorial
        k0, k1 = max(0, m2 - m1), min(ell + m2, ell - m1)
        if k1 < k0:
            return 0.0
        term = c ** (2 * ell + m2 - m1 - 2 * k0) * s ** (m1 - m2 + 2 * k0)
        term /= fac(ell + m2 - k0) * fac(k0) * fac(m1 - m2 + k0) * fac(ell - m1 - k0)
        if (m1 - m2 + k0) % 2:
            term = -term
        total = term
        ratio_cs = -((s / c) ** 2) if c != 0 else mpmath.mpf(0)
        for k in range(k0, k1):
            term *= ratio_cs * (ell + m2 - k) * (ell - m1 - k) / ((k + 1) * (m1 - m2 + k + 1))
            total += term
        return float(mpmath.sqrt(fac(ell + m1) * fac(ell - m1) * fac(ell + m2) * fac(ell - m2)) * total)


def last_d(
    lmax: int, beta: NDArray[np.float64], qs: NDArray[np.int64], ms: NDArray[np.int64] | None = None
) -> NDArray[np.float64]:
    d = np.zeros(())
    for _, d_l in iter_wigner_d(lmax, beta, qs, ms=ms):
        d = d_l
    return d


# ---------------------------------------------------------------- closed forms and low order exact values


def test_degree_one_closed_form() -> None:
    beta = np.array([0.0, 0.3, 1.7, np.pi, -2.2, 9.0])
    d = wigner_d(1, beta)[:, 1]  # [..., m + 1, q + 1]
    cb, sb = np.cos(beta), np.sin(beta)
    expected = np.stack(
        [
            [(1 + cb) / 2, sb / np.sqrt(2), (1 - cb) / 2],
            [-sb / np.sqrt(2), cb, sb / np.sqrt(2)],
            [(1 - cb) / 2, -sb / np.sqrt(2), (1 + cb) / 2],
        ]
    ).transpose(2, 0, 1)  # rows m' = -1, 0, 1; d^1_{-1,-1} = (1+cos)/2, d^1_{0,-1} = sin/sqrt2 ...
    np.testing.assert_allclose(d, expected, atol=4 * EPS)
    # the named convention: d^1_{10}(beta) = -sin(beta)/sqrt(2)
    np.testing.assert_allclose(d[:, 2, 1], -sb / np.sqrt(2), atol=4 * EPS)


@pytest.mark.parametrize("beta", [0.0, 1e-9, 0.4, np.pi / 2, 2.5, np.pi, -0.9, 4.0, 7.5])
def test_low_degree_all_entries_vs_mpmath(beta: float) -> None:
    lmax = 7
    d = wigner_d(lmax, beta)
    for ell in range(lmax + 1):
        for m1 in range(-ell, ell + 1):
            for m2 in range(-ell, ell + 1):
                assert d[ell, m1 + lmax, m2 + lmax] == pytest.approx(d_exact(ell, m1, m2, beta), abs=2e-15)
    # entries outside |m|, |q| <= l are exactly zero
    assert d[2, lmax + 3, lmax] == 0.0 and d[2, lmax, lmax - 3] == 0.0


def test_highest_weight_closed_form_large_l() -> None:
    """d^l_{lq} = (-1)^(l-q) sqrt(C(2l, l+q)) cos^(l+q)(beta/2) sin^(l-q)(beta/2) at l = 2048 (log-space, lgamma)."""
    beta = np.array([1e-3, 0.05, 0.5, 2.0, 3.1])
    lmax = 2048
    qs = np.array([-lmax, -3, 0, lmax - 150, lmax - 3, lmax])
    d = last_d(lmax, beta, qs, ms=np.array([lmax]))[:, 0, :]
    c, s = np.cos(beta / 2)[:, None], np.sin(beta / 2)[:, None]
    log_c = np.array([math.lgamma(2 * lmax + 1) - math.lgamma(lmax + q + 1) - math.lgamma(lmax - q + 1) for q in qs])
    log_v = 0.5 * log_c + (lmax + qs) * np.log(c) + (lmax - qs) * np.log(s)
    expected = np.where((lmax - qs) % 2 == 0, 1.0, -1.0) * np.exp(log_v)
    # lgamma(4097) ~ 3e4 carries an absolute error ~1e-12, hence the relative tolerance
    np.testing.assert_allclose(d, expected, rtol=1e-10, atol=1e-300)
    assert np.count_nonzero((d != 0) & (np.abs(d) < 1e-50)) >= 5  # tiny values are resolved, not flushed to zero early


# ---------------------------------------------------------------- high order against mpmath

CASES_200 = [(200, 0, 0), (200, 3, -5), (200, -5, -5), (200, 150, 2), (150, -100, 5), (200, -199, -4), (200, 2, 3)]


@pytest.mark.parametrize("beta", [*HARD_BETAS, 0.7, 2.9])
def test_l200_vs_mpmath(beta: float) -> None:
    lmax = 200
    qs = np.arange(-5, 6)
    d = np.zeros((lmax + 1, 2 * lmax + 1, qs.size))
    for ell, dl in iter_wigner_d(lmax, beta, qs):
        d[ell] = dl
    for ell, m1, m2 in CASES_200:
        exact = d_exact(ell, m1, m2, beta)
        assert d[ell, m1 + lmax, m2 + 5] == pytest.approx(exact, abs=3e-15, rel=1e-12), (ell, m1, m2, beta)


def test_l2048_vs_mpmath() -> None:
    """Spot values at l = 2048, including the near-1 diagonal at beta -> 0, pi (where cos(beta) rounds to +-1)."""
    lmax = 2048
    betas = np.array([1e-8, 1e-3, np.pi / 2, np.pi - 1e-6, 0.7])
    entries = [(0, 0), (-3, -3), (2, 3), (1500, -2), (40, -3)]
    ms = np.array(sorted({m for m, _ in entries}))
    qs = np.arange(-3, 4)
    d = last_d(lmax, betas, qs, ms=ms)
    for i, beta in enumerate(betas):
        for m1, m2 in entries:
            got = d[i, np.searchsorted(ms, m1), m2 + 3]
            assert got == pytest.approx(d_exact(lmax, m1, m2, float(beta)), abs=2e-14, rel=1e-11), (m1, m2, beta)


# ---------------------------------------------------------------- against the `spherical` package


def spherical_d(lmax: int, qmax: int, beta: float) -> NDArray[np.float64]:
    """d^l_{mq}(beta) as [l, m + lmax, q + qmax] from spherical's H wedge: d^l_{m'm} = eps_m' eps_-m H^{m'm}_l.

    eps_k = (-1)^k for k > 0, else 1 (spherical/recursions/wignerH.py); the wedge stores m >= |m'| and the rest
    follows from H^{m'm} = H^{mm'} = H^{-m',-m}. With this relation spherical's d is the d of relight.wigner.
    """
    import spherical
    from spherical.utilities.indexing import WignerHrange

    w = spherical.Wigner(lmax, mp_max=qmax)
    h = np.copy(w.H(np.exp(1j * beta), w.Hwedge, w.Hv, w.Hextra))
    ell, mp, m = WignerHrange(qmax, lmax).T
    out = np.zeros((lmax + 1, 2 * lmax + 1, 2 * qmax + 1))

    def eps(k: NDArray[np.int64]) -> NDArray[np.float64]:
        return np.where((k > 0) & (k % 2 == 1), -1.0, 1.0)

    for a, b in ((mp, m), (m, mp), (-mp, -m), (-m, -mp)):
        ok = np.abs(b) <= qmax
        out[ell[ok], a[ok] + lmax, b[ok] + qmax] = eps(a[ok]) * eps(-b[ok]) * h[ok]
    return out


@pytest.mark.parametrize("beta", [*HARD_BETAS, 0.3, 2.2])
def test_vs_spherical_l512(beta: float) -> None:
    lmax, qmax = 512, 4
    ref = spherical_d(lmax, qmax, beta)
    d = np.zeros_like(ref)
    for ell, dl in iter_wigner_d(lmax, beta, np.arange(-qmax, qmax + 1)):
        d[ell] = dl
    # spherical computes from exp(i beta), so cos(beta) is rounded: its own error near 0 and pi reaches ~1e-14 here
    np.testing.assert_allclose(d, ref, atol=5e-14)


@pytest.mark.slow
@pytest.mark.parametrize("beta", [1e-8, 1e-3, np.pi / 2, np.pi - 1e-6, 1.1])
def test_vs_spherical_l2048(beta: float) -> None:
    """Against spherical up to l = 2048 wherever spherical is finite.

    spherical (1.1.4) returns NaN for l >= 1474 at beta near 0 or pi (the H recursion's Legendre seeds underflow);
    there relight.wigner is checked against mpmath (test_l2048_vs_mpmath) and unitarity instead. Where both are
    finite, spherical's own error near beta = 0 reaches ~1e-13 (rounded cos(beta)); the tolerance is set by it.
    """
    lmax, qmax = 2048, 2
    ref = spherical_d(lmax, qmax, beta)
    d = np.zeros_like(ref)
    for ell, dl in iter_wigner_d(lmax, beta, np.arange(-qmax, qmax + 1)):
        d[ell] = dl
    fin = np.isfinite(ref)
    assert fin[:1400].all()
    assert np.all(np.isfinite(d))
    np.testing.assert_allclose(d[fin], ref[fin], atol=2e-13)


# ---------------------------------------------------------------- algebraic properties


def unitarity_error(lmax: int, betas: NDArray[np.float64], qmax: int) -> float:
    d = last_d(lmax, betas, np.arange(-qmax, qmax + 1))
    gram = np.einsum("bmq,bmr->bqr", d, d)
    return float(np.abs(gram - np.eye(2 * qmax + 1)).max())


def test_unitarity_l512() -> None:
    betas = np.array([*HARD_BETAS, 0.7, 2.9, np.pi / 2 + 1e-9])
    assert unitarity_error(512, betas, 3) < 1e-13


@pytest.mark.slow
def test_unitarity_l2048() -> None:
    """sum_m d^l_{mq} d^l_{mq'} = delta_qq' at l = 2048 (measured <= 1e-14)."""
    betas = np.array([*HARD_BETAS, 2.9])
    assert unitarity_error(2048, betas, 2) < 1e-12


def test_symmetries() -> None:
    rng = np.random.default_rng(42)
    lmax = 24
    for beta in [*rng.uniform(-np.pi, 2 * np.pi, 3), 1e-7, np.pi - 1e-7]:
        d = wigner_d(lmax, beta)
        dn = wigner_d(lmax, -beta)
        dr = wigner_d(lmax, np.pi - beta)
        m = np.arange(-lmax, lmax + 1)
        sign_mq = (-1.0) ** (m[:, None] - m[None, :])
        sign_lm = (-1.0) ** (np.arange(lmax + 1)[:, None, None] + m[None, :, None])
        tol = 1e-13
        np.testing.assert_allclose(d, sign_mq * np.swapaxes(d, 1, 2), atol=tol)  # (-1)^(m-q) d_qm
        np.testing.assert_allclose(d, d[:, ::-1, ::-1].swapaxes(1, 2), atol=tol)  # d_{-q,-m}
        np.testing.assert_allclose(d, np.swapaxes(dn, 1, 2), atol=tol)  # d_qm(-beta)
        np.testing.assert_allclose(d, sign_lm * dr[:, :, ::-1], atol=tol)  # (-1)^(l+m) d_{m,-q}(pi - beta)
        np.testing.assert_allclose(wigner_d(lmax, beta + 2 * np.pi), d, atol=1e-12)  # integer l: period 2 pi


def group_law_error(lmax: int, b1: float, b2: float, qmax: int) -> float:
    """max |d(b1 + b2) - d(b1) d(b2)| on |m|, |q| <= qmax, using d_mk(b1) = d_km(-b1) so only columns are needed."""
    qs = np.arange(-qmax, qmax + 1)
    err = 0.0
    gen_a = iter_wigner_d(lmax, np.array([-b1, b2]), qs)
    gen_s = iter_wigner_d(lmax, b1 + b2, qs, ms=qs)
    for (_, cols), (_, dsum) in zip(gen_a, gen_s, strict=True):
        prod = cols[0].T @ cols[1]
        err = max(err, float(np.abs(prod - dsum).max()))
    return err


def test_group_law_l300() -> None:
    assert group_law_error(300, 0.4, 1.9, 3) < 1e-13
    assert group_law_error(300, 1e-6, 3.0, 3) < 1e-13
    assert group_law_error(300, np.pi / 2, np.pi / 2, 3) < 1e-13  # d(pi/2)^2 = d(pi)


@pytest.mark.slow
def test_group_law_l2048() -> None:
    assert group_law_error(2048, 0.4, 1.9, 2) < 1e-12
    assert group_law_error(2048, 1e-4, np.pi - 1e-3, 2) < 1e-12


# ---------------------------------------------------------------- rotations of spherical harmonics


def test_sh_rotation_identity_scipy() -> None:
    """Y_lm(R^{-1} x) = sum_m' Y_lm'(x) D^l_{m'm}(R) with scipy's CS-phase harmonics, l <= 6."""
    rng = np.random.default_rng(42)
    x = rng.normal(size=(30, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    for alpha, beta, gamma in [(0.3, 1.1, -0.7), (2.0, 3.0, 0.1), (0.0, 1e-6, 0.0), (-1.0, np.pi, 2.5)]:
        rot = rotation_matrix_zyz(alpha, beta, gamma)
        xr = x @ rot  # rows R^T x = R^{-1} x
        th, ph = np.arccos(np.clip(x[:, 2], -1, 1)), np.arctan2(x[:, 1], x[:, 0])
        thr, phr = np.arccos(np.clip(xr[:, 2], -1, 1)), np.arctan2(xr[:, 1], xr[:, 0])
        for ell in range(7):
            ms = np.arange(-ell, ell + 1)
            y = sph_harm_y(ell, ms[None, :], th[:, None], ph[:, None])
            yr = sph_harm_y(ell, ms[None, :], thr[:, None], phr[:, None])
            np.testing.assert_allclose(yr, y @ wigner_D_matrix(ell, alpha, beta, gamma), atol=1e-13)


# ---------------------------------------------------------------- API shapes and validation


def test_shapes_and_consistency() -> None:
    beta = np.array([[0.2, 1.0], [2.0, 3.0]])
    d = wigner_d(10, beta, 3)
    assert d.shape == (2, 2, 11, 21, 7)
    dq = wigner_d_q(10, beta, -2)
    assert dq.shape == (2, 2, 11, 21)
    np.testing.assert_array_equal(dq, d[..., 1])
    full = wigner_d_matrix(10, beta)
    assert full.shape == (2, 2, 21, 21)
    np.testing.assert_allclose(full[..., 7:14], d[..., 10, :, :], atol=0)
    np.testing.assert_allclose(d[..., 3, 21 // 2 + 4 :, :], 0.0)  # |m| > l
    # orthogonal full matrix
    np.testing.assert_allclose(full[0, 1] @ full[0, 1].T, np.eye(21), atol=1e-14)
    assert wigner_d(0, 0.3).shape == (1, 1, 1)


def test_iterator_yields_fresh_arrays() -> None:
    seen = [d for _, d in iter_wigner_d(3, 0.5, [0])]
    assert seen[0] is not seen[1]
    assert seen[1][3, 0] == pytest.approx(np.cos(0.5))  # d^1_00, ms = -3..3 so index 3 is m = 0


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: wigner_d(-1, 0.1), "lmax"),
        (lambda: wigner_d(2.5, 0.1), "lmax"),  # type: ignore[arg-type]
        (lambda: wigner_d(4, np.nan), "beta"),
        (lambda: wigner_d(4, 0.1, 5), "qmax"),
        (lambda: wigner_d_q(4, 0.1, 5), "q"),
        (lambda: list(iter_wigner_d(4, 0.1, [0.5])), "qs"),
        (lambda: list(iter_wigner_d(4, 0.1, [0], ms=[7])), "ms"),
    ],
)
def test_invalid_input(call: object, field: str) -> None:
    with pytest.raises(InputError, match=field):
        call()  # type: ignore[operator]
