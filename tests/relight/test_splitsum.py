"""The engines' split-sum GGX lobe (relight.brdf.splitsum) against brute-force quadrature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from relight.brdf.coefficients import radial_transfer
from relight.brdf.spec import parse_brdf
from relight.brdf.splitsum import GGXSplitSum, splitsum_normaliser
from relight.errors import InputError


def _z_quad(alpha: float) -> float:
    a2 = alpha * alpha

    def integrand(t: float) -> float:
        nh2 = 0.5 * (1.0 + t)
        return float(2.0 * np.pi * a2 / (np.pi * (nh2 * (a2 - 1.0) + 1.0) ** 2) * t)

    # the peak sits at t = 1 with width ~ alpha^2: give quad the break point
    return float(quad(integrand, 0.0, 1.0, points=[max(0.0, 1.0 - 10.0 * a2)], limit=400, epsabs=0.0,
                      epsrel=1e-12)[0])


@pytest.mark.parametrize("alpha", [1e-3, 0.01, 0.1, 0.5, 0.9, 0.998, 0.9995, 1.0, 1.0004, 1.68, 8.0])
def test_normaliser_matches_quadrature(alpha: float) -> None:
    # closed form and its series (|alpha^2 - 1| < 3e-3) against adaptive quadrature; 1e-9 covers quad's own
    # accuracy on the sharpest lobe and the closed form's cancellation next to the series' range
    assert splitsum_normaliser(alpha) == pytest.approx(_z_quad(alpha), rel=1e-9)


@pytest.mark.parametrize("roughness", [0.05, 0.2, 0.5, 1.0, 1.3, 2.8])
def test_lobe_integrates_to_one(roughness: float) -> None:
    # Lambda_0 rho_0 = 2 pi int u dt: the lobe's integral over the sphere, by relight's composite quadrature
    # (r > 1: the wide lobes at the end of Babylon's chains)
    lobe = GGXSplitSum(roughness, max_roughness=3.0)
    assert radial_transfer(lobe, 4).transfer[0, 0] == pytest.approx(1.0, abs=1e-9)


def test_rough_one_is_the_clamped_cosine() -> None:
    # alpha = 1: D = 1/pi is constant, so K(t) = max(t, 0) / pi (the Lambert lobe about the normal)
    t = np.linspace(-1.0, 1.0, 101)
    np.testing.assert_allclose(GGXSplitSum(1.0).u(t)[:, 0], np.maximum(t, 0.0) / np.pi, rtol=1e-12, atol=1e-15)


def test_spec_and_bad_values() -> None:
    lobe = parse_brdf("ggx-ld:roughness=0.25")
    assert isinstance(lobe, GGXSplitSum) and lobe.alpha == pytest.approx(0.0625)
    for bad in ("ggx-ld:roughness=0", "ggx-ld:roughness=1.5", "ggx-ld:roughness=nan"):
        with pytest.raises(InputError, match="roughness"):
            parse_brdf(bad)
