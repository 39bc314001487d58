"""Lobes at their extremes: Phong s from 0.5 to 1e4, microfacet sigma from 0.5 down to 0.02 (F in the hundreds),
views down to grazing (89.9 degrees between N and V).

References: the closed form of Phong's transfer factors (``phong_transfer``, Ramamoorthi & Hanrahan 2001) and of
its order (App. D), the brute-force angular reference (``relight.reference``), and physical bounds (a non-negative
BRDF under a non-negative environment reflects non-negative radiance; §7.1's F ~ 1/sigma for microfacet lobes).
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from relight.brdf import lpq_search
from relight.brdf.coefficients import phong_transfer, radial_transfer, spectrum_for_tolerance
from relight.brdf.models import GGX, Microfacet, TorranceSparrow
from relight.brdf.radial import Phong
from relight.envmap import read_envmap, resample_latlong
from relight.metrics import relative_rms
from relight.orders import phong_order
from relight.prefilter import prefilter_radial
from relight.reference import reference_radial

from ._hyp import log_uniform, stable

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
GRAZING = math.radians(89.9)


@cache
def env(name: str = "courtyard", rows: int = 32) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


@stable(15)
@given(s=log_uniform(0.5, 1e4))
def test_phong_transfer_matches_the_closed_form_for_any_exponent(s: float) -> None:
    """Quadrature against the closed form to 1e-11 (test_coefficients: 1e-12 at seven fixed exponents; here any s,
    including non-integer s < 1 whose lobe has an infinite slope at the horizon)."""
    lmax = min(int(math.sqrt(30.0 * s)) + 20, 800)
    quad = radial_transfer(Phong(s), lmax).transfer[:, 0]
    np.testing.assert_allclose(quad, phong_transfer(s, lmax), rtol=0, atol=1e-11)


@stable(12)
@given(s=log_uniform(8.0, 1e4), eps=st.sampled_from([0.1, 1e-2, 1e-3, 1e-4]))
def test_phong_order_follows_appendix_d(s: float, eps: float) -> None:
    """F from the energy rule against App. D's sqrt(-s log epsilon): the Gaussian approximation of rho_l holds for
    large s, so within 25 % (and the rule's F is minimal: one order less misses the tolerance)."""
    spec, f = spectrum_for_tolerance(Phong(s), eps)
    closed = phong_order(s, eps)
    assert 0.75 * closed <= f <= 1.25 * closed + 1, (s, eps, f, closed)
    e = spec.epsilon()
    assert e[f] <= eps < e[f - 1]


@stable(8)
@given(s=log_uniform(0.5, 500.0), eps=st.sampled_from([0.1, 1e-2, 1e-3]))
def test_phong_prefilter_within_its_predicted_error(s: float, eps: float) -> None:
    """Measured against the angular reference: within App. B's bound plus the pixel grid's floor (the same
    comparison at F = H - 1, test_prefilter's rule) on a 32-row sample map."""
    px = env()
    res = prefilter_radial(px, Phong(s), epsilon=eps, size=16)
    ref = reference_radial(px, Phong(s), 16, epsilon=0.0)
    floor = relative_rms(prefilter_radial(px, Phong(s), order=31, size=16).map, ref)
    err = relative_rms(res.map, ref)
    assert np.all(np.isfinite(res.map))
    assert err <= res.report.orders.rms_appendix_b + floor, (s, eps, err, floor, res.report.orders)


@pytest.mark.parametrize("s", [1e3, 1e4])
def test_sharp_phong_on_a_coarse_map_is_finite_and_bounded_below(s: float) -> None:
    """Lobes narrower than a pixel (s = 1e4: theta* ~ 0.02 rad on a 64-row map): the order is capped at H - 1 and
    the output stays finite and above the ringing bound."""
    px = env("city", 64)
    res = prefilter_radial(px, Phong(s), epsilon=1e-3, size=32)
    assert res.report.orders.F_B == 63
    lower = np.array(res.report.ringing.lower_bound_rgb)
    assert np.all(np.isfinite(res.map))
    assert np.all(res.map.reshape(-1, 3).min(axis=0) >= lower - 1e-9 * np.abs(res.map).max())


@stable(6)
@given(sigma=log_uniform(0.02, 0.5))
def test_microfacet_order_scales_as_one_over_sigma(sigma: float) -> None:
    """§7.1: F ~ 1/sigma. At epsilon = 0.1 App. C's search gives F sigma = 1.5 over the range (1 to 2.5 allowed, the
    search's doubling granularity); the coefficients are finite and epsilon(F, P) never grows with F or P."""
    sel = lpq_search.select_orders(Microfacet(sigma), 0.1)
    assert sel.met and 1.0 <= sel.F * sigma <= 2.5, (sigma, sel.F)
    table = sel.coefficients.epsilon_table()
    assert np.all(np.isfinite(sel.coefficients.rho)) and np.all(np.isfinite(table))
    assert np.all(np.diff(table, axis=0) <= 1e-12) and np.all(np.diff(table, axis=1) <= 1e-12)


@pytest.mark.slow
def test_microfacet_sigma_002_needs_hundreds_of_orders() -> None:
    """sigma = 0.02 at epsilon = 0.01: F in the hundreds (198 here; §7.1's F ~ 1/sigma scaled by the tolerance), a
    small P, finite coefficients; an SHRM at a capped order on a small map stays finite too."""
    lobe = Microfacet(0.02)
    sel = lpq_search.select_orders(lobe, 0.01)
    assert sel.met and 150 <= sel.F <= 260 and sel.P <= 6
    assert np.all(np.isfinite(sel.coefficients.rho))
    from relight.shrm import create_shrm, reflect

    sm = create_shrm(env("city", 64), lobe, order=63, p_order=sel.P, size=32)
    assert np.all(np.isfinite(sm.components[0].maps))
    assert np.all(np.isfinite(reflect(sm, [0.0, 0.2, 1.0])))


@pytest.mark.parametrize("lobe", [Microfacet(0.02), Microfacet(0.1), Microfacet(0.5), TorranceSparrow(alpha=0.05),
                                  GGX(alpha=0.1), Phong(0.5)], ids=lambda x: str(x.spec()))
def test_lobes_at_grazing_views_are_finite_and_non_negative(lobe: object) -> None:
    """rho_hat over theta_i in [0, pi] and the view up to grazing: in the reflection frame theta_o = 2 theta_v with
    theta_v (between N and V) up to 89.9 degrees, and beyond to the antipode. Non-negative: a BRDF x cosine."""
    theta_v = np.concatenate([np.linspace(0.0, GRAZING, 50), [math.radians(89.99), math.pi / 2]])
    ti = np.linspace(0.0, math.pi, 181)[:, None, None]
    to = np.concatenate([2.0 * theta_v, [math.pi - 1e-9, math.pi]])[None, :, None]
    ph = np.linspace(0.0, math.pi, 13)[None, None, :]
    v = np.asarray(lobe.rho_hat(ti, to, ph))  # type: ignore[attr-defined]
    assert np.all(np.isfinite(v)) and v.min() >= 0.0


@pytest.mark.parametrize("lobe", [Microfacet(0.1), TorranceSparrow(alpha=0.1)], ids=["microfacet", "ts"])
def test_reference_and_shrm_at_grazing_views(lobe: object) -> None:
    """The angular reference at normals 89.9 degrees from V is finite and non-negative; the SHRM's map for a view
    contains grazing pixels (N = normalize(R + V) sweeps 0..90 degrees) and is finite everywhere."""
    from relight.reference_view import reflected_radiance
    from relight.shrm import create_shrm, reflect

    px = env("sunset", 16)
    v = np.array([0.0, 0.0, 1.0])
    az = np.linspace(0.0, 2 * math.pi, 16, endpoint=False)
    for ang in (math.radians(80.0), math.radians(89.0), GRAZING):
        n = np.stack([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.full_like(az, np.cos(ang))], axis=-1)
        b = reflected_radiance(px, lobe, n, v)
        assert np.all(np.isfinite(b)) and b.min() >= 0.0
    sm = create_shrm(px, lobe, order=12, p_order=4, size=16)
    img = reflect(sm, [0.1, 0.1, 1.0])
    assert np.all(np.isfinite(img))
