"""The normalised spherical Gaussian (vMF) lobe of seed 002 (relight.brdf.vmf) against independent references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special

from relight.brdf.coefficients import radial_transfer
from relight.brdf.spec import parse_brdf
from relight.brdf.vmf import VonMisesFisher, vmf, vmf_energy, vmf_transfer
from relight.errors import InputError


def quadrature_transfer(sigma: float, lmax: int) -> np.ndarray:
    """``2 pi int G(cos g) P_l(cos g) sin g dg`` by Gauss-Legendre panels in gamma, 10 panels per sigma near the
    centre (the lobe is exp(-g^2 / (2 sigma^2)) there) and per oscillation of P_lmax."""
    h = min(sigma / 10.0, math.pi / (4.0 * (lmax + 1)))
    edges = np.unique(np.concatenate([np.arange(0.0, min(40.0 * sigma, math.pi), h), [min(40 * sigma, math.pi)]]))
    x, w = np.polynomial.legendre.leggauss(20)
    a, b = edges[:-1, None], edges[1:, None]
    g = (0.5 * (b - a) * x + 0.5 * (b + a)).ravel()
    wg = (0.5 * (b - a) * w).ravel() * np.sin(g)
    kappa = 1.0 / sigma**2
    u = vmf(np.cos(g), kappa)
    return np.array([2 * math.pi * np.sum(wg * u * special.eval_legendre(l, np.cos(g))) for l in range(lmax + 1)])


@pytest.mark.parametrize("sigma", [1.0, 0.3, 0.05, math.radians(1.0), math.radians(0.2)])
def test_transfer_against_quadrature(sigma: float) -> None:
    lmax = 300
    closed = vmf_transfer(1.0 / sigma**2, lmax)
    quad = quadrature_transfer(sigma, lmax)
    # both are exact to rounding: 20-point Gauss-Legendre on panels of sigma / 10 integrates the smooth lobe to
    # machine precision (measured differences <= 4e-14)
    np.testing.assert_allclose(closed, quad, atol=1e-11)
    assert closed[0] == pytest.approx(1.0, abs=1e-15)  # normalised: the lobe integrates to 1


@pytest.mark.parametrize("sigma", [math.radians(1.0), math.radians(0.1), 1e-5, 1e-6])
def test_transfer_against_large_kappa_asymptote(sigma: float) -> None:
    # I_{l+1/2}(k) / I_{1/2}(k) = exp(-l (l+1) / (2k)) (1 + O(1/k)) uniformly in l: the measured difference is
    # 1.3 / k at sigma = 1 degree; 2 / k allows for it. sigma <= 1e-5 (k >= 1e10) runs the asymptote path, where
    # scipy's ive returns NaN: the result must still be finite and in [0, 1].
    kappa = 1.0 / sigma**2
    lmax = 5000
    c = vmf_transfer(kappa, lmax)
    l = np.arange(lmax + 1)
    assert np.all(np.isfinite(c)) and np.all((c >= 0) & (c <= 1))
    np.testing.assert_allclose(c, np.exp(-l * (l + 1) / (2 * kappa)), atol=2.0 / kappa)


def test_high_order_tail_underflows_to_zero_without_nan() -> None:
    c = vmf_transfer(100.0, 3000)  # sigma = 5.7 degrees: the coefficients fall below 1e-300 long before l = 3000
    assert np.all(np.isfinite(c)) and c[-1] == 0.0 and c[40] > 0.0


def test_energy_and_radial_pipeline_use_the_closed_form() -> None:
    lobe = VonMisesFisher(0.2, weight=[0.5, 1.0, 2.0])
    spec = radial_transfer(lobe, 64)
    np.testing.assert_allclose(spec.transfer, vmf_transfer(25.0, 64)[:, None] * [0.5, 1.0, 2.0], rtol=1e-13)
    # int G^2 dOmega by quadrature in t = cos gamma
    t, w = np.polynomial.legendre.leggauss(400)
    t = 0.5 * (t + 1) * 2 - 1
    e = 2 * math.pi * np.sum(w * vmf(t, 25.0) ** 2)
    assert vmf_energy(25.0) == pytest.approx(e, rel=1e-10)
    np.testing.assert_allclose(spec.total_energy, e * np.array([0.25, 1.0, 4.0]), rtol=1e-10)


def test_spec_string_and_bad_values() -> None:
    lobe = parse_brdf("vmf:sigma=0.1")
    assert isinstance(lobe, VonMisesFisher) and lobe.sigma == 0.1 and lobe.kappa == pytest.approx(100.0)
    assert isinstance(parse_brdf({"kind": "vmf", "sigma": 0.2, "weight": [1, 0.5, 0.25]}), VonMisesFisher)
    with pytest.raises(InputError, match="sigma"):
        parse_brdf("vmf:sigma=0")
    with pytest.raises(InputError, match="weight"):
        VonMisesFisher(0.1, weight=-1.0)
