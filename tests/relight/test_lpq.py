"""BRDF coefficients rho_hat_lpq (seed 000 eq. 13, App. C step 1) and the lobe caches."""

from __future__ import annotations

import numpy as np
import pytest

from relight.brdf import lobe_cache, lpq
from relight.brdf.coefficients import lambda_l, phong_transfer, radial_transfer
from relight.brdf.spec import parse_brdf


@pytest.mark.parametrize("s", [8.0, 64.0, 500.0])
def test_phong_p0_equals_radial_transfer_and_closed_form(s: float) -> None:
    # P = 0 case: rho_hat_l00 = sqrt(4 pi) rho_l, so Lambda_l rho_hat_l00 / sqrt(4 pi) is the radial transfer factor.
    lobe = parse_brdf(f"phong:s={s}")
    f = int(3 * np.sqrt(s)) + 4
    c = lpq.brdf_coefficients(lobe, f, 2)
    got = lambda_l(f) * c.rho[:, 0, 0, 0] / np.sqrt(4.0 * np.pi)
    np.testing.assert_allclose(got, radial_transfer(lobe, f).transfer[:, 0], atol=1e-10)
    np.testing.assert_allclose(got, phong_transfer(s, f), atol=1e-10)
    assert np.all(c.rho[:, 1:] == 0.0)  # no theta_o dependence: every p > 0 coefficient vanishes
    # total energy int int rho_hat^2 = 4 pi int u^2 dOmega = 4 pi * 2 pi (s+1)^2 / (4 pi^2 (2s+1)) (closed form)
    np.testing.assert_allclose(c.total_energy[0], 2.0 * (s + 1.0) ** 2 / (2.0 * s + 1.0), rtol=1e-10)


def test_general_path_on_a_radial_lobe_agrees() -> None:
    # The three-step algorithm treating Phong as a general 3-D BRDF (no symmetry shortcuts) reproduces the radial
    # quadrature of relight.brdf.coefficients (a different rule) in l00 and gives zeros elsewhere.
    lobe = parse_brdf("phong:s=32")
    fast = lpq.brdf_coefficients(lobe, 20, 3)
    full = lpq.brdf_coefficients(lobe, 20, 3, use_symmetry=False)
    assert full.Q == 3 and fast.Q == 0
    np.testing.assert_allclose(full.rho[:, 0, 0], fast.rho[:, 0, 0], rtol=1e-10, atol=1e-11 * np.abs(fast.rho).max())
    assert np.abs(full.rho[:, 1:]).max() < 1e-12 * np.abs(full.rho).max()
    assert np.abs(full.rho[:, :, 1:]).max() < 1e-12 * np.abs(full.rho).max()


def test_microfacet_matches_brute_force_eq13() -> None:
    # Independent reference: eq. 13 summed with a midpoint rule and scipy's harmonics (lpq.rho_lpq_direct).
    # Both rules are first order at the horizon jump of rho_hat, so agreement is ~1e-3 of the largest coefficient.
    lobe = parse_brdf("microfacet:sigma=0.3")
    c = lpq.brdf_coefficients(lobe, 6, 3)
    idx = [(0, 0, 0), (2, 0, 0), (1, 1, 1), (3, 2, 1), (4, 2, 2), (5, 3, 3), (6, 3, 0), (2, 3, 2)]
    direct = lpq.rho_lpq_direct(lobe, idx, n=90)
    got = np.array([c.rho[l, p, q] for l, p, q in idx])
    scale = np.abs(c.rho).max()
    np.testing.assert_allclose(got, direct, atol=2e-3 * scale)
    assert np.abs(got).min() > 2e-4 * scale  # the checked coefficients are not trivially zero


def test_grid_convergence_and_parseval() -> None:
    # The default grid against a 2x oversampled one; the energy split converges to the directly integrated total.
    lobe = parse_brdf("microfacet:sigma=0.1")
    a = lpq.brdf_coefficients(lobe, 26, 3)
    b = lpq.brdf_coefficients(lobe, 26, 3, oversample=2.0)
    assert np.abs(a.rho - b.rho).max() < 3e-4 * np.abs(b.rho).max()
    assert abs(a.epsilon() - b.epsilon()) < 5e-4
    smooth = lpq.brdf_coefficients(parse_brdf("microfacet:sigma=0.5"), 16, 12)
    # sum_lp E_lp -> int int rho_hat^2 (Parseval, App. A); the last 0.3 % sits at grazing theta_o (high p)
    assert smooth.epsilon() < 4e-3 and smooth.epsilon(16, 4) < 0.02
    assert np.all(np.diff(smooth.epsilon_table(), axis=0) <= 1e-15)
    assert np.all(np.diff(smooth.epsilon_table(), axis=1) <= 1e-15)


def test_kajiya_kay_has_only_q0_terms() -> None:
    lobe = parse_brdf("kajiya-kay:s=32")
    assert lobe.azimuthally_symmetric and lobe.center == "T"
    full = lpq.brdf_coefficients(lobe, 16, 6, use_symmetry=False)
    assert np.abs(full.rho[:, :, 1:]).max() < 1e-12 * np.abs(full.rho).max()
    fast = lpq.brdf_coefficients(lobe, 16, 6)
    assert fast.Q == 0
    np.testing.assert_allclose(fast.rho[:, :, 0], full.rho[:, :, 0], atol=1e-12 * np.abs(full.rho).max())


def test_cache_and_errors() -> None:
    lobe_cache.clear()
    lobe = parse_brdf("microfacet:sigma=0.4")
    a, hit_a = lpq.cached_coefficients(lobe, 6, 2)
    b, hit_b = lpq.cached_coefficients(parse_brdf("microfacet:sigma=0.4"), 6, 2)
    assert (hit_a, hit_b) == (False, True) and a is b
    with pytest.raises(ValueError, match="orders"):
        lpq.brdf_coefficients(lobe, -1, 2)
    with pytest.raises(ValueError, match="outside"):
        a.epsilon(7, 0)
    with pytest.raises(ValueError, match="q <= min"):
        lpq.rho_lpq_direct(lobe, [(1, 3, 2)])
