"""Radial BRDF coefficients and error analysis against closed forms (seed 000 §6.3, App. B, App. D)."""

from __future__ import annotations

import numpy as np
import pytest

from relight.brdf import coefficients as co
from relight.brdf.radial import Lambert, Phong
from relight.orders import (
    appendix_b_bound,
    order_for_tolerance,
    phong_angular_width,
    phong_order,
    rms_from_energy,
    uncaptured,
)


@pytest.mark.parametrize("s", [0.5, 1, 8, 64, 512, 4096, 10000])
def test_phong_quadrature_equals_closed_form(s: float) -> None:
    lmax = 400
    quad = co.radial_transfer(Phong(s), lmax).transfer[:, 0]
    closed = co.phong_transfer(s, lmax)
    np.testing.assert_allclose(quad, closed, atol=1e-12)


def test_phong_closed_form_by_independent_brute_force() -> None:
    # scipy's adaptive quadrature of (s+1) int_0^1 t^s P_l(t) dt: a different integrator and Legendre evaluation.
    from scipy.integrate import quad
    from scipy.special import eval_legendre

    s = 32.0
    closed = co.phong_transfer(s, 12)
    for l in range(13):
        val, _ = quad(lambda t, l=l: (s + 1) * t**s * eval_legendre(l, t), 0.0, 1.0, epsabs=1e-14, epsrel=1e-13)
        assert abs(val - closed[l]) < 1e-11


def test_lambert_closed_form_and_nine_coefficients() -> None:
    quad = co.radial_transfer(Lambert(), 30).transfer[:, 0]
    np.testing.assert_allclose(quad, co.lambert_transfer(30), atol=1e-13)
    # Ramamoorthi & Hanrahan 2001a: A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4 (divided by pi for albedo 1).
    np.testing.assert_allclose(co.lambert_transfer(2), [1.0, 2.0 / 3.0, 0.25], atol=1e-15)
    assert np.all(co.lambert_transfer(31)[3::2] == 0.0)


@pytest.mark.parametrize("s", [64, 512, 4096])
def test_phong_gaussian_approximation(s: float) -> None:
    # Seed 000 §6.3: Lambda_l rho_l ~ exp(-l^2 / 2s); the approximation error is O(l/s) for l ~ sqrt(s).
    l = np.arange(0, int(3 * np.sqrt(s)))
    exact = co.phong_transfer(s, int(l[-1]))
    approx = np.exp(-(l**2) / (2.0 * s))
    assert np.max(np.abs(exact - approx)) < 3.0 / np.sqrt(s)


@pytest.mark.parametrize("s", [8, 64, 512, 4096])
def test_phong_order_closed_form_matches_energy_rule(s: float) -> None:
    # App. D: F ~ sqrt(-s log eps) from the Gaussian approximation; the exact energy rule lands close to it.
    eps = 1e-3
    spec, f = co.spectrum_for_tolerance(Phong(s), eps)
    f_closed = phong_order(s, eps)
    assert abs(f - f_closed) <= 0.15 * f_closed + 2
    assert spec.epsilon()[f] <= eps < spec.epsilon()[f - 1]


def test_orders_helpers() -> None:
    e = np.array([4.0, 3.0, 2.0, 1.0])
    np.testing.assert_allclose(uncaptured(e, 10.0), [0.6, 0.3, 0.1, 0.0])
    assert order_for_tolerance(e, 10.0, 0.15) == 2
    assert order_for_tolerance(e, 20.0, 0.15) is None
    assert rms_from_energy(0.04) == pytest.approx(0.2)
    theta, w = phong_angular_width(100.0, 0.01)
    assert np.cos(theta) == pytest.approx(0.01 ** (1 / 101))
    assert w == pytest.approx(0.5 * (1 - 0.01 ** (1 / 101)))
    # App. B: zero residual -> zero error; the bound is a fraction in [0, 1].
    assert appendix_b_bound(0.5, 0.0, 1.0, 0.1, 1.0, 1.0) == 0.0
    assert 0.0 < appendix_b_bound(0.5, 0.5, 1.0, 0.1, 1.0, 1.0) < 1.0


def test_ringing_minimum_is_the_band_limited_kernel_minimum() -> None:
    # Independent: evaluate u_F on a fine grid by scipy's Legendre polynomials.
    from scipy.special import eval_legendre

    transfer = co.phong_transfer(512, 40)[:, None]
    t = np.cos(np.linspace(0, np.pi, 20001))
    u_f = sum((2 * l + 1) / (4 * np.pi) * transfer[l, 0] * eval_legendre(l, t) for l in range(41))
    got = co.ringing_minimum(transfer)[0]
    # a valid bound lies at or below every sampled value, and is tight (the 20001-point grid is within 1e-5)
    assert got <= u_f.min() + 1e-12
    assert got == pytest.approx(u_f.min(), rel=1e-5)
    assert co.ringing_minimum(transfer)[0] < 0.0  # a truncated sharp lobe rings
    windowed = transfer * co.window_factors(40, "hann")[:, None]
    assert abs(co.ringing_minimum(windowed)[0]) < abs(co.ringing_minimum(transfer)[0])


def test_invalid_arguments() -> None:
    with pytest.raises(ValueError, match="epsilon"):
        co.spectrum_for_tolerance(Phong(8), 0.0)
    with pytest.raises(ValueError, match="window"):
        co.window_factors(4, "kaiser")
    with pytest.raises(ValueError):
        phong_order(-1.0, 0.1)


def test_too_narrow_lobe_is_refused_before_allocating() -> None:
    """Issue 12: a lobe1d peak 1e-5 rad wide at order 4096 would need a (4097 x 6e6) Legendre table (190 GiB). The
    size is checked from the node count alone: the refusal allocates next to nothing (tracemalloc sees NumPy's
    allocations) and names the width and the order."""
    import tracemalloc

    from relight.brdf.coefficients import MAX_QUADRATURE_WORK, quadrature_nodes, radial_transfer
    from relight.brdf.spec import parse_brdf
    from relight.errors import InputError

    lobe = parse_brdf({"kind": "lobe1d", "t": [-1.0, 1.0 - 1e-10, 1.0], "u": [0.0, 0.0, 1.0]})
    assert 4097 * quadrature_nodes(4096, 1.4e-5) > MAX_QUADRATURE_WORK
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="too narrow for order 4096"):
            radial_transfer(lobe, 4096)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20


def test_node_count_and_blocked_quadrature() -> None:
    """quadrature_nodes is an upper bound of the nodes _theta_nodes makes (np.unique may merge a few graded edges),
    and the block-by-block sum over nodes equals the closed form of Phong at order 300 (more nodes than one block)
    to 1e-12: the blocks' partial sums only reorder the additions."""
    from relight.brdf.coefficients import _NODE_BLOCK, _theta_nodes, phong_transfer, quadrature_nodes, radial_transfer
    from relight.brdf.spec import parse_brdf

    for lmax, width in [(10, 0.5), (100, 0.01), (300, 0.02), (2000, 1e-3)]:
        n = _theta_nodes(lmax, width)[0].size
        assert n <= quadrature_nodes(lmax, width) <= n + 64 * 16
    lobe = parse_brdf("phong:s=500")
    assert _theta_nodes(300, 0.1)[0].size > _NODE_BLOCK
    got = radial_transfer(lobe, 300).transfer[:, 0]
    np.testing.assert_allclose(got, phong_transfer(500.0, 300), rtol=0, atol=1e-12)
