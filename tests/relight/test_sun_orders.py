"""The order reduction a sun extraction buys (relight.planning.sun_orders; issue 17, item 6) on city.exr, and the
harmonic fill behind the residual (relight.sun.harmonic_fill).

Measured (city.exr, 512 rows; per view band, orientation average, grazing limit 0.1): microfacet sigma = 0.2 keeps
its planned F_B = 31 with the sun (the prediction does not meet epsilon below it) and needs 18 without it at
epsilon = 1e-3 (1.7x; the issue asks 4x, which this criterion does not give there: the residual's city skyline
alone needs F = 18 in the grazing bands), 7 of F_B = 32 at epsilon = 1e-2 (4.6x). The former extraction (core
pixels only, flat fill) left an aureole ring and a hard-edged hole: 25 at 1e-3.
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


def test_plan_shows_the_reduction() -> None:
    """The job plan with sun=extract lists per lobe the orders with and without the sun and their ratio; the
    issue's 4x holds for microfacet sigma = 0.2 at epsilon = 1e-2 (module docstring: 1.7x at 1e-3)."""
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
    assert plan.to_json()["sun"]["extracted"]["mode"] == "extract"


def test_residual_shrm_at_the_reduced_order_plus_the_analytic_sun_equals_the_brute_force() -> None:
    """The order the plan gives without the sun suffices: the residual's SHRM at (order_without_sun, P_B) for
    microfacet sigma = 0.2 at epsilon = 1e-3, plus the sun as a directional light
    (``relight.reference_view.directional_view``: ``E f(s, V, N) max(N . s, 0)``), against the angular brute force
    of the *original* map (``reference_view``, both maps area-averaged to 128 rows to keep the brute force at ~15 s
    a view). The issue's bound is 2 %: the plan holds the residual's part to epsilon = 1e-3 of its energy per view
    band (relative RMS ~ 3 % of a part that is about half of the output), and the removed disc (3.2 deg) as a point
    costs about (3.2 / 11)^2 / 8 ~ 1 % of the sun's part under a lobe ~ 11 deg wide. Without the sun the map is
    ~ 50 % off, so the test can fail."""
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
