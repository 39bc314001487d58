"""The order reduction a sun extraction buys (relight.planning.sun_orders; issue 17, item 6) on city.exr, and the
harmonic fill behind the residual (relight.sun.harmonic_fill).

Measured (city.exr, 512 rows; per view band, orientation average, grazing limit 0.1): microfacet sigma = 0.2 keeps
its planned F_B = 31 with the sun (the prediction does not meet epsilon below it). Without the sun the output is the
residual's SHRM plus the sun as a point light, held to the same epsilon of the original output's energy, the point
light's own error included: 13 at epsilon = 1e-3 (2.4x), 4 of F_B = 32 at 1e-2 (8x). Held to its own energy the
residual needs 18 at 1e-3 (1.7x) and 7 at 1e-2. The issue asks 4x at 1e-3; it is out of reach
(test_what_limits_the_reduction_at_1e_3): the residual's skyline alone, with no point-light error at all, needs
F = 8 > 31 / 4 there. The former extraction (core pixels only, flat fill) left an aureole ring and a hard-edged
hole: 25 at 1e-3 held to its own energy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, pixel_solid_angles
from relight.envmap import read_envmap
from relight.planning.job import StoredLighting
from relight.planning.sun_orders import lighting_order, plan_job_with_sun
from relight.prefilter import project_lighting
from relight.sun import REL_THRESHOLD, extract_sun, harmonic_fill

REPO = Path(__file__).resolve().parents[2]
CITY = REPO / "data" / "envmaps" / "city.exr"
MICROFACET = {"kind": "microfacet", "sigma": 0.2}
GRAZING = 0.1


def _city() -> np.ndarray:
    return np.asarray(read_envmap(CITY).pixels, dtype=np.float64)


def _stored(px: np.ndarray) -> StoredLighting:
    lit = project_lighting(px, px.shape[0] - 1)
    return StoredLighting(lit.band_energy(), float(lit.total_energy))


def _info(px: np.ndarray) -> dict[str, object]:
    s = _stored(px)
    return {"height": px.shape[0], "width": px.shape[1], "sh_power_spectrum": s.energies.tolist(),
            "total_energy": s.total_energy}


def test_harmonic_fill_is_exact_on_a_discrete_harmonic_and_obeys_the_maximum_principle() -> None:
    h, w = 64, 128
    rows = np.arange(h, dtype=np.float64)[:, None, None]
    lin = np.broadcast_to(0.5 + 0.01 * rows * np.array([1.0, 2.0, 3.0]), (h, w, 3)).copy()
    region = np.zeros((h, w), dtype=bool)
    region[20:30, 120:128] = True
    region[20:30, 0:6] = True  # across the longitude seam
    # a function of the row alone, linear in it, has a zero 5-point Laplacian: the fill reproduces it exactly
    np.testing.assert_allclose(harmonic_fill(lin, region), lin, rtol=0, atol=1e-12)
    rng = np.random.default_rng(3)
    noisy = rng.uniform(0.0, 1.0, (h, w, 3))
    filled = harmonic_fill(noisy, region)
    edge = np.zeros_like(region)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        edge |= np.roll(region, (dr, dc), axis=(0, 1))
    edge &= ~region
    for c in range(3):
        assert noisy[edge, c].min() - 1e-12 <= filled[region, c].min()
        assert filled[region, c].max() <= noisy[edge, c].max() + 1e-12
    np.testing.assert_array_equal(filled[~region], noisy[~region])


def test_city_residual_keeps_no_ring() -> None:
    px = _city()
    res = extract_sun(px)
    h, w = px.shape[:2]
    d = latlong_dirs(h, w)
    lum0, lum = px @ LUMINANCE_WEIGHTS, res.pixels @ LUMINANCE_WEIGHTS
    peak = np.unravel_index(int(np.argmax(lum0)), lum0.shape)
    ang = np.degrees(np.arccos(np.clip(d @ d[peak], -1.0, 1.0)))
    region = ang <= res.report["region_deg"]
    assert int(region.sum()) == res.report["region_pixels"]
    mean = float(np.average(lum0, weights=np.broadcast_to(pixel_solid_angles(h, w)[:, None], (h, w))))
    # the aureole: pixels near the sun above 10 x the sky's mean luminance but below the core threshold
    aureole = (ang < 3.0) & (lum0 < REL_THRESHOLD * lum0.max()) & (lum0 > 10.0 * mean)
    assert aureole.sum() >= 5  # city.exr has one: the test checks something
    assert np.all(region[aureole])  # all of it is removed
    border = np.zeros_like(region)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        border |= np.roll(region, (dr, dc), axis=(0, 1))
    border &= ~region
    # what replaces it lies below the sky around the region (maximum principle), which holds no aureole pixel
    assert lum0[border].max() < 10.0 * mean
    assert lum[region].max() <= lum0[border].max() * (1 + 1e-9)


def _flat_fill_residual(px: np.ndarray) -> np.ndarray:
    """The former extraction: the core (>= 1 % of the peak) set to the mean of a 2 deg ring outside it."""
    h, w = px.shape[:2]
    lum = px @ LUMINANCE_WEIGHTS
    d = latlong_dirs(h, w)
    peak = np.unravel_index(int(np.argmax(lum)), lum.shape)
    ang = np.degrees(np.arccos(np.clip(d @ d[peak], -1.0, 1.0)))
    core = (lum >= REL_THRESHOLD * lum.max()) & (ang <= 10.0)
    reach = ang[core].max()
    ring = (ang > reach) & (ang <= reach + 2.0) & ~core
    out = px.copy()
    out[core] = np.average(px[ring], axis=0, weights=np.broadcast_to(pixel_solid_angles(h, w)[:, None], (h, w))[ring])
    return out


def test_city_order_with_and_without_the_sun() -> None:
    """microfacet sigma = 0.2 at epsilon = 1e-3: the order without the sun is met and lower than with it and than the
    former extraction's; the bisection agrees with a scan of every order (a second algorithm)."""
    from relight.brdf.spec import parse_brdf
    from relight.planning.job import plan_job
    from relight.shrm import brdf_lobes

    px = _city()
    h = px.shape[0]
    eps = 1e-3
    plan = plan_job(_info(px), MICROFACET, {"epsilon": eps})
    assert plan.component_plans is not None
    f_b, p_b = plan.component_plans[0].F_B, plan.component_plans[0].P_B
    lobe = brdf_lobes(parse_brdf(MICROFACET))[0]
    kw = {"height": h, "grazing_limit": GRAZING}
    with_sun, met_with = lighting_order(lobe, _stored(px), f_b, p_b, eps, **kw)
    residual = _stored(extract_sun(px).pixels)
    without, met_without = lighting_order(lobe, residual, f_b, p_b, eps, **kw)
    flat, _ = lighting_order(lobe, _stored(_flat_fill_residual(px)), f_b, p_b, eps, **kw)
    assert met_without and without < with_sun
    assert without < flat  # the halo and the smooth fill are what lowers it
    # a scan: every order below `without` misses epsilon, `without` meets it
    from relight.shrm.creation import spectrum_order
    from relight.shrm.order_search import cached_spectrum
    from relight.shrm.view_bands import predicted_by_view
    from relight.shrm.view_spectrum import band_edges

    spec = cached_spectrum(lobe, spectrum_order(f_b, h - 1), p_b, band_edges(GRAZING))
    worst = [max(b.epsilon for b in predicted_by_view(spec, residual, f, p_b, epsilon=eps, grazing_limit=GRAZING)
                 if b.enforced) for f in range(f_b + 1)]
    assert worst[without] <= eps and all(x > eps for x in worst[:without])
    if not met_with:
        assert with_sun == f_b


def test_point_error_spectrum_is_the_addition_theorem_double_sum() -> None:
    """``point_error_lighting``'s band energies (a projection plus a Legendre recurrence) against the double sum
    ``(2l+1)/(4 pi) sum_jk w_j w_k P_l(d_j . d_k)`` over the removed pixels and the point ``-E`` at the sun's
    direction (scipy's Legendre polynomials): the band energies of that set of point masses by the addition theorem.
    Tolerance: both are float64 sums of ~400^2 terms of size <= E^2 (2l+1)/(4 pi) ~ 70 at l = 96, so 1e-9 of that
    scale; E^delta_0 = 0 because E is the removed illuminance."""
    from scipy.special import eval_legendre

    from relight.planning.sun_orders import point_error_lighting

    px = _city()
    res = extract_sun(px)
    lmax = 96
    pe = point_error_lighting(px, res.pixels, res.report, lmax)
    h, w = px.shape[:2]
    x = (px - res.pixels) @ LUMINANCE_WEIGHTS
    sel = x != 0.0
    wk = (x * pixel_solid_angles(h, w)[:, None])[sel]
    s = np.asarray(res.report["direction"])
    pts = np.vstack([latlong_dirs(h, w)[sel], s])
    ww = np.concatenate([wk, [-wk.sum()]])
    c = np.clip(pts @ pts.T, -1.0, 1.0)
    ref = np.array([(2 * ell + 1) / (4 * np.pi) * ww @ eval_legendre(ell, c) @ ww for ell in range(lmax + 1)])
    scale = wk.sum() ** 2 * (2 * lmax + 1) / (4 * np.pi)
    np.testing.assert_allclose(pe.energies, np.clip(ref, 0.0, None), rtol=0, atol=1e-9 * scale)
    assert pe.energies[0] < 1e-12 * scale and pe.energies[lmax] > 1e-6 * scale  # the point differs at high l


def test_what_limits_the_reduction_at_1e_3() -> None:
    """Issue 17 asks the residual's order at epsilon = 1e-3 to be 4x lower than with the sun (31, F_B: not met
    below it). Held to the original output's energy, the residual's SHRM error *alone* (the sun's point-light error
    left out, which can only raise the order) needs more than 31 / 4: the skyline's bands 8..15 hold 1.0e-3 of the
    output energy at N.V in [0.1, 0.2]. With the point light's error (the order the plan reports) it is higher still
    and at most the order the residual needs held to its own, smaller, output energy."""
    from relight.brdf.spec import parse_brdf
    from relight.planning.job import plan_job
    from relight.planning.sun_orders import point_error_lighting
    from relight.shrm import brdf_lobes

    px = _city()
    eps = 1e-3
    plan = plan_job(_info(px), MICROFACET, {"epsilon": eps})
    assert plan.component_plans is not None
    f_b, p_b = plan.component_plans[0].F_B, plan.component_plans[0].P_B
    lobe = brdf_lobes(parse_brdf(MICROFACET))[0]
    kw = {"height": px.shape[0], "grazing_limit": GRAZING}
    original = _stored(px)
    res = extract_sun(px)
    residual = _stored(res.pixels)
    bare, met_bare = lighting_order(lobe, residual, f_b, p_b, eps, output=original, **kw)
    point = point_error_lighting(px, res.pixels, res.report, px.shape[0] - 1)
    full, met_full = lighting_order(lobe, residual, f_b, p_b, eps, output=original, exact_part=point, **kw)
    alone, _ = lighting_order(lobe, residual, f_b, p_b, eps, **kw)
    assert met_bare and met_full
    assert 4 * bare > f_b  # the 4x is out of reach whatever the sun's model
    assert bare <= full <= alone


def test_plan_shows_the_reduction() -> None:
    """The job plan with sun=extract lists per lobe the orders with and without the sun and their ratio; the
    issue's 4x holds for microfacet sigma = 0.2 at epsilon = 1e-2 (module docstring: 2.4x at 1e-3)."""
    px = _city()
    info = _info(px)
    plain = plan_job_with_sun(info, MICROFACET, {"epsilon": 1e-2}, CITY)
    assert plain.sun is None and "sun" not in plain.to_json()
    plan = plan_job_with_sun(info, MICROFACET, {"epsilon": 1e-2, "sun": "extract"}, CITY)
    assert plan.sun is not None
    (lobe,) = plan.sun["lobes"]
    assert lobe["F_B"] == plan.orders.F_B and lobe["factor"] == pytest.approx(
        lobe["order_with_sun"] / lobe["order_without_sun"])
    assert lobe["met_without_sun"] and lobe["factor"] >= 4.0
    # held to the original output the residual needs no more than held to its own, smaller, output energy
    assert lobe["met_residual_alone"] and lobe["order_without_sun"] <= lobe["order_residual_alone"]
    assert plan.to_json()["sun"]["extracted"]["mode"] == "extract"


def test_residual_shrm_at_the_reduced_order_plus_the_analytic_sun_equals_the_brute_force() -> None:
    """The order the plan gives without the sun suffices: the residual's SHRM at (order_without_sun, P_B) for
    microfacet sigma = 0.2 at epsilon = 1e-3, plus the sun as a directional light
    (``relight.reference_view.directional_view``: ``E f(s, V, N) max(N . s, 0)``), against the angular brute force
    of the *original* map (``reference_view``, both maps area-averaged to 128 rows to keep the brute force at ~15 s
    a view). The issue's bound is 2 %: the plan holds the residual SHRM's error plus the point light's to
    epsilon = 1e-3 of the original output's energy per view band (relative RMS ~ 3 % in the worst, grazing band,
    where few texels lie; the bands of most texels are predicted below 1e-4, relative RMS 1 %). Measured: 0.30 % and
    0.25 % at order 12, 0.26 % and 0.23 % at 18 (0.84 % and 0.57 % at 7, 2.9 % and 2.3 % at 5; the plan gives 13).
    Without the sun the map is ~ 50 % off, so the test can fail."""
    from relight.brdf.spec import parse_brdf
    from relight.envmap.resample import resample_latlong
    from relight.metrics import relative_rms
    from relight.reference_view import directional_view, reference_view
    from relight.shrm import create_shrm, reflect

    px = _city()
    plan = plan_job_with_sun(_info(px), MICROFACET, {"epsilon": 1e-3, "sun": "extract"}, CITY)
    assert plan.sun is not None
    (lobe,) = plan.sun["lobes"]
    assert lobe["met_without_sun"] and lobe["order_without_sun"] < lobe["F_B"]
    res = extract_sun(px)
    rows = 128
    residual = np.asarray(resample_latlong(res.pixels, rows), dtype=np.float64)
    original = np.asarray(resample_latlong(px, rows), dtype=np.float64)
    brdf = parse_brdf(MICROFACET)
    shrm = create_shrm(residual, brdf, order=lobe["order_without_sun"], p_order=lobe["P_B"], size=32)
    sun = res.report
    for view in ([0.0, 0.0, 1.0], [0.6, 0.3, 0.74]):
        v = np.asarray(view) / np.linalg.norm(view)
        ref = reference_view(original, brdf, v, 32)
        without = reflect(shrm, v, size=32)
        with_sun = without + directional_view(brdf, sun["direction"], sun["irradiance_rgb"], v, 32)
        assert relative_rms(with_sun, ref) < 0.02, view
        assert relative_rms(without, ref) > 0.1, view


def test_directional_view_is_the_brute_force_of_one_pixel() -> None:
    """A map dark but for one pixel is, in the angular brute force, a directional light of irradiance
    ``L dOmega`` from that pixel's centre (inside every truncation cone that reaches it)."""
    from relight.brdf.spec import parse_brdf
    from relight.reference_view import directional_view, reference_view

    h = 32
    px = np.zeros((h, 2 * h, 3))
    px[9, 20] = [3.0, 2.0, 1.0]
    e = px[9, 20] * pixel_solid_angles(h, 2 * h)[9]
    brdf = parse_brdf(MICROFACET)
    v = np.array([0.3, 0.5, 0.81]) / np.linalg.norm([0.3, 0.5, 0.81])
    ref = reference_view(px, brdf, v, 16, truncation=1e-12)
    mine = directional_view(brdf, latlong_dirs(h, 2 * h)[9, 20], e, v, 16)
    assert np.abs(ref).max() > 0.0
    np.testing.assert_allclose(mine, ref, rtol=1e-10, atol=1e-14 * np.abs(ref).max())
