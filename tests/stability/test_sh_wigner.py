"""SH transforms and Wigner-d at l up to 2048: property-based sweeps of the angle (at and next to the poles and
pi/2) and of m near l/e, the cases the fixed tables of ``tests/relight/test_sh.py`` and
``tests/relight/test_wigner.py`` sample at a few points only (those stay the table-driven part; nothing here repeats
them).

References: ducc0's own Legendre values (``alm2leg``, a different recursion, within 3e-13 of mpmath to l = 4000 per
docs/facts.md) and the exact Wigner sum in mpmath of ``tests/relight/test_wigner.py`` (``d_exact``, imported,
not copied).
Relation used: ``d^l_m0(beta) = Lambda_l Pbar_l|m|(cos beta)`` for m >= 0, times (-1)^m for m < 0 (the addition
theorem; checked at low l by ``test_wigner``'s closed forms).
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from types import ModuleType

import ducc0
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from relight import indexing, sh, wigner

from ._hyp import HARD_ANGLES, m_near_l_over_e, rng, stable


def _test_wigner() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "relight" / "test_wigner.py"
    spec = importlib.util.spec_from_file_location("_relight_test_wigner_reference", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


D_EXACT = _test_wigner().d_exact


def ducc0_legendre(l: int, m: int, theta: np.ndarray) -> np.ndarray:
    """Pbar_lm(cos theta) (orthonormal, CS phase) from ducc0's alm2leg with a single unit coefficient."""
    a = np.zeros((1, l + 1), dtype=np.complex128)
    a[0, l] = 1.0  # index mstart + l with mstart = 0: only degrees m..l exist, and only l is set
    leg = ducc0.sht.alm2leg(alm=a, spin=0, lmax=l, mval=np.array([m], dtype=np.uintp),
                            mstart=np.array([0], dtype=np.uintp), theta=np.asarray(theta, dtype=np.float64))
    return np.asarray(leg[0, :, 0].real, dtype=np.float64)


@st.composite
def degree_order(draw: st.DrawFn, lmax: int = 2048) -> tuple[int, int]:
    l = draw(st.one_of(st.integers(0, 64), st.integers(65, lmax), st.sampled_from([lmax, 1000, 1024])))
    return l, draw(m_near_l_over_e(l))


@stable(60)
@given(lm=degree_order(), thetas=st.lists(HARD_ANGLES, min_size=1, max_size=6))
def test_legendre_matches_ducc0_at_hard_angles(lm: tuple[int, int], thetas: list[float]) -> None:
    """Absolute agreement 1e-11 x max(1, |value|): ducc0's 3e-13 plus relight's recursion, whose rounding error grows
    about like sqrt(l) ulps (45 ulps at l = 2048). Both flush values below ~1e-30 to or near 0; those are checked
    relatively against mpmath in the next test."""
    l, m = lm
    theta = np.array(thetas)
    got = sh.legendre(l, m, theta)
    ref = ducc0_legendre(l, m, theta)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11 * max(1.0, float(np.abs(ref).max())))


@pytest.mark.slow
@stable(25)
@given(lm=degree_order(), q=st.integers(-3, 3), betas=st.lists(HARD_ANGLES, min_size=1, max_size=3))
def test_wigner_d_matches_the_exact_sum(lm: tuple[int, int], q: int, betas: list[float]) -> None:
    """d^l_mq against the exact Wigner sum in mpmath (>= 50 significant digits): abs 2e-14 + rel 1e-11, the
    tolerances test_wigner states for l = 2048 (the recursion's error grows ~sqrt(l) ulps; |d| <= 1)."""
    l, m = lm
    if abs(q) > l:
        q = 0
    m = -m if (l + m) % 2 else m  # both signs of m over the examples
    beta = np.array(betas)
    d = np.zeros(())
    for _, d_l in wigner.iter_wigner_d(l, beta, np.array([q]), ms=np.array([m])):
        d = d_l
    assert d.shape == (beta.size, 1, 1) and np.all(np.isfinite(d))
    for i, b in enumerate(betas):
        assert d[i, 0, 0] == pytest.approx(D_EXACT(l, m, q, b), abs=2e-14, rel=1e-11), (l, m, q, b)


@stable(40)
@given(lm=degree_order(lmax=600), beta=HARD_ANGLES)
def test_wigner_q0_column_is_the_normalised_legendre_function(lm: tuple[int, int], beta: float) -> None:
    """d^l_m0 = Lambda_l Pbar_l|m| (x (-1)^m for m < 0), Pbar from ducc0; 1e-12 absolute (|d| <= 1)."""
    l, m = lm
    d = np.zeros(())
    for _, d_l in wigner.iter_wigner_d(l, np.array([beta]), np.array([0]), ms=np.array([-m, m])):
        d = d_l
    lam = math.sqrt(4.0 * math.pi / (2 * l + 1))
    p = float(ducc0_legendre(l, m, np.array([beta]))[0])
    assert d[0, 1, 0] == pytest.approx(lam * p, abs=1e-12)
    assert d[0, 0, 0] == pytest.approx((-1) ** m * lam * p, abs=1e-12)


@pytest.mark.slow
@stable(1)
@given(betas=st.lists(HARD_ANGLES, min_size=4, max_size=4))
def test_wigner_unitarity_at_l2048_at_hard_angles(betas: list[float]) -> None:
    """sum_m d^l_mq d^l_mq' = delta_qq' at l = 2048 for every q, q' in -2..2; 1e-12 (rounding in 4097-term sums)."""
    d = np.zeros(())
    for _, d_l in wigner.iter_wigner_d(2048, np.array(betas), np.arange(-2, 3)):
        d = d_l
    gram = np.einsum("bmq,bmr->bqr", d, d)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(5), gram.shape), atol=1e-12)


@stable(12)
@given(lmax=st.integers(0, 300), extra=st.integers(1, 40), seed=st.integers(0, 2**16))
def test_sh_round_trip_on_random_grids(lmax: int, extra: int, seed: int) -> None:
    """Synthesis then quadrature projection returns a band-limited field's coefficients on any grid of H >= 2 lmax + 1
    rings: Fejér's first rule with H nodes integrates polynomials in cos(theta) of degree <= H - 1 exactly, and
    ``Y_lm Y*_l'm`` has degree l + l' <= 2 lmax. 1e-11 of the largest coefficient."""
    r = rng(seed)
    n = indexing.healpy_size(lmax)
    a = r.standard_normal(n) + 1j * r.standard_normal(n)
    a[: lmax + 1] = a[: lmax + 1].real  # m = 0 coefficients of a real field are real
    h = 2 * lmax + extra
    back = sh.project(sh.synthesize(a, lmax, h), lmax)
    assert np.abs(back - a).max() <= 1e-11 * np.abs(a).max()


@stable(20)
@given(lmax=st.integers(1, 80), thetas=st.lists(HARD_ANGLES, min_size=1, max_size=8),
       phis=st.lists(st.floats(-math.pi, math.pi), min_size=1, max_size=8), seed=st.integers(0, 2**16))
def test_sh_evaluate_at_hard_angles_matches_ducc0(lmax: int, thetas: list[float], phis: list[float],
                                                  seed: int) -> None:
    """``relight.sh.evaluate`` at directions at and next to the poles and the equator against a direct sum over
    ducc0's Legendre values, ``sum_lm a_lm Pbar_lm e^{i m phi}`` (real field); 1e-11 of sum |a_lm|."""
    r = rng(seed)
    n = indexing.healpy_size(lmax)
    a = r.standard_normal(n) + 1j * r.standard_normal(n)
    a[: lmax + 1] = a[: lmax + 1].real
    k = min(len(thetas), len(phis))
    theta, phi = np.array(thetas[:k]), np.array(phis[:k])
    got = sh.evaluate(a, lmax, theta, phi)
    ref = np.zeros(k)
    for m in range(lmax + 1):
        leg = np.stack([ducc0_legendre(l, m, theta) for l in range(m, lmax + 1)])  # (l, k)
        coef = a[indexing.healpy_index(np.arange(m, lmax + 1), np.full(lmax + 1 - m, m), lmax)]
        term = (coef[:, None] * leg).sum(axis=0) * np.exp(1j * m * phi)
        ref += term.real if m == 0 else 2.0 * term.real
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11 * np.abs(a).sum())
