"""Per-view spectra, predicted errors per view band and the view-band order search (relight/shrm/view_spectrum.py,
view_bands.py, order_search.py; issue 18), against independent references: App. C's own coefficients on another
grid, a plain midpoint quadrature of eq. 13 at one view, Parseval, and the angular brute force over views spread
on the sphere (relight/view_error.py, relight/reference_view.py) including grazing texels down to N.V = 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from relight.brdf import lpq
from relight.brdf.spec import parse_brdf
from relight.envmap import read_envmap, resample_latlong
from relight.resources import sample_envmaps
from relight.shrm import create_shrm, order_search, reflect
from relight.shrm.view_bands import VIEW_MARGIN, brdf_band_epsilon, predicted_by_view
from relight.shrm.view_spectrum import band_edges, view_nodes, view_spectrum
from relight.view_error import sample_by_view


def _map(name: str, rows: int) -> np.ndarray:
    root = sample_envmaps()
    assert root is not None, "the sample maps are package data (relight.data)"
    return np.asarray(resample_latlong(read_envmap(root / f"{name}.exr").pixels, rows), dtype=np.float64)


@pytest.mark.parametrize("spec", ["microfacet:sigma=0.2", "ggx:alpha=0.3"])
def test_coefficients_match_app_c_grid(spec: str) -> None:
    """rho_hat_lpq from the view nodes equal relight.brdf.lpq's (10 theta_i nodes per order, 10 P theta_o nodes,
    5 P phi samples: another grid). Both rules are first order at the horizon jump; lpq is good to about 1e-4 of the
    largest coefficient, the view grid (4 per order) to 2.5 times that: 2e-3 leaves margin and still catches any
    wrong factor or index (a 2 pi or a q-swap changes coefficients by O(1))."""
    lobe = parse_brdf(spec)
    vs = view_spectrum(lobe, 24, 6)
    ref = lpq.brdf_coefficients(lobe, 24, 6)
    scale = float(np.abs(ref.rho).max())
    assert np.abs(vs.rho - ref.rho).max() <= 2e-3 * scale
    assert vs.total_energy == pytest.approx(ref.total_energy, rel=1e-3)


def test_per_view_coefficients_match_midpoint_quadrature() -> None:
    """k_lq(theta_o) at one grazing node against eq. 13 summed literally at that view with a midpoint rule and
    scipy's Y_lq (O(1/n) at the horizon jump: n = 400 gives about 1e-3 of the largest value; 5e-3 allowed)."""
    from scipy.special import sph_harm_y

    lobe = parse_brdf("torrance-sparrow:alpha=0.3")
    vs = view_spectrum(lobe, 12, 4)
    o = int(np.argmin(np.abs(vs.theta_o - 2.0 * math.acos(0.2))))  # a node near N.V = 0.2
    n = 400
    t = (np.arange(n) + 0.5) * np.pi / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    vals = lobe.rho_hat(t[:, None], np.full((1, 1), vs.theta_o[o]), ph[None, :])[..., 0]  # (n, 2n)
    peak = float(np.abs(vs.k[:, :, o, 0]).max())
    for l, q in [(0, 0), (3, 1), (8, 2), (12, 4)]:
        ki = np.real(sph_harm_y(l, q, t, 0.0)) * np.sin(t) * (np.pi / n)
        kp = np.cos(q * ph) * (np.pi / n)
        direct = 2.0 * np.pi * float(ki @ vals @ kp)
        assert vs.k[l, q, o, 0] == pytest.approx(direct, abs=5e-3 * peak), (l, q)


def test_band_errors_integrate_to_the_whole_lobe() -> None:
    """Parseval in theta_o: the fine bands' missing energies, summed with their weights, are App. C's whole-lobe
    epsilon(F, P) of the same coefficients (the f_pq are orthonormal; the node rule integrates their products to
    about 1e-6 at P = 6)."""
    lobe = parse_brdf("microfacet:sigma=0.3")
    vs = view_spectrum(lobe, 40, 6)
    table = vs.coefficients().epsilon_table()
    tot = vs.band_sum(vs.k_tot[None])[0][:, 0]
    for f, p in [(10, 2), (20, 4), (40, 6)]:
        per_band = brdf_band_epsilon(vs, p)[f]
        whole = float(np.sum(per_band * tot) / np.sum(tot))
        assert whole == pytest.approx(table[f, p], rel=1e-3, abs=1e-6), (f, p)


def test_radial_lobe_has_no_view_dependence() -> None:
    """Phong about R: every band misses exactly the whole lobe's epsilon(F) (closed form, seed 000 App. D)."""
    from relight.brdf.coefficients import phong_transfer

    vs = view_spectrum(parse_brdf("phong:s=64"), 30, 0)
    eps = brdf_band_epsilon(vs, 0)
    tr = phong_transfer(64.0, 400)
    e_l = tr**2 * (2 * np.arange(401) + 1) / (4 * np.pi)  # band energies of u = (s+1)/(2pi) t^s
    closed = 1.0 - np.cumsum(e_l) / e_l.sum()
    for f in (4, 8, 16):
        assert np.allclose(eps[f], closed[f], rtol=1e-6, atol=1e-12), f


def test_nodes_cover_every_view_once() -> None:
    """The band intervals tile theta_o in [0, pi] for each centre (weights in cos theta_o sum to 2)."""
    for center in ("R", "N", "T"):
        _, w, band = view_nodes(center, band_edges(0.15))
        assert w.sum() == pytest.approx(2.0, rel=1e-9), center
        assert set(np.unique(band[band >= 0])) == set(range(len(band_edges(0.15)) - 1))


def test_search_says_which_band_cannot_be_met() -> None:
    """Torrance–Sparrow alpha = 0.2 at epsilon = 0.01 (issue 18: minutes before, then "not met"): the band N.V in
    [0.1, 0.2] cannot reach 0.01 within P <= 16 and the search says so with what it can reach; at a grazing limit
    of 0.2 every enforced band meets it, checked on an independent finer tabulation (oversample 2) at the orders
    found, within the grids' 2e-4 accuracy on epsilon (relight.brdf.lpq)."""
    lobe = parse_brdf("torrance-sparrow:alpha=0.2")
    res = order_search.search_orders(lobe, 0.01, grazing_limit=0.1)
    assert not res.met and (0.1, 0.2) in res.unmet
    i = res.edges.index(0.1)
    assert 0.01 < res.achievable[i] < 1.0
    ok = order_search.search_orders(lobe, 0.01, grazing_limit=0.2)
    assert ok.met and ok.P <= 16
    fine = view_spectrum(lobe, max(ok.F, 8), ok.P, edges=ok.edges, oversample=2.0)
    eps = brdf_band_epsilon(fine, ok.P)[ok.F]
    on = np.asarray(ok.enforced)
    assert np.all(eps[on] <= 0.01 + 2e-4), eps


CASES = [("phong:s=64", 16, 0), ("microfacet:sigma=0.1", 40, 8), ("ggx:alpha=0.3", 20, 6),
         ("torrance-sparrow:alpha=0.3", 20, 6)]
BANDS = ((0.0, 0.1), (0.1, 0.3), (0.3, 0.7), (0.7, 1.0))
#: A measurement resolves the 3x rule when its standard error is at most this share of it (derivation below).
RESOLVED = 1.0 / 3.0
#: Rounds of 100 views (seeds 0, 1, ...) before a band must be resolved.
MAX_ROUNDS = 4


def measure_resolved(sm: object, px: np.ndarray, lobe: object) -> tuple[np.ndarray, np.ndarray]:
    """Per band: the measured relative RMS and its jackknife standard error, adding rounds of 100 views (12
    texels per band each) until every band's standard error is at most RESOLVED times its value."""
    meas = sample_by_view(sm, px, lobe, BANDS, views=100, per_view=12, seed=0)
    for seed in range(1, MAX_ROUNDS):
        if np.all(meas.standard_error() <= RESOLVED * meas.rms):
            break
        meas = meas.merged(sample_by_view(sm, px, lobe, BANDS, views=100, per_view=12, seed=seed))
    return meas.rms, meas.standard_error()


@pytest.mark.parametrize("name", ["city", "courtyard", "sunset"])
@pytest.mark.parametrize(("spec", "f", "p"), CASES)
def test_prediction_brackets_the_brute_force(name: str, spec: str, f: int, p: int) -> None:
    """Per view band, down to N.V = 0: measured <= predicted <= 3 measured + 0.005 (issue 18), measured against
    the angular brute force (relight.reference_view, the map's pixels as point samples) at texels of views spread
    over the sphere (relight.view_error), on 64 x 128 maps: city (single-pixel lamps: 45 % of its energy beyond the
    map's order l = 63), courtyard (smooth sky) and sunset (a sun).

    Why 3 holds for a right prediction and fails a wrong one: the prediction is ``rms = 1.5 A`` with A the
    orientation average of the error (relight.shrm.view_bands). The measurement m estimates A with standard error
    s; the test first samples until s <= m / 3 (RESOLVED; city's lamps and sunset's sun leave s near m after 48
    views of 6 texels: a band's error is carried by the few orientations that put a light in the lobe). A right A
    lies within 2 s of m, so ``rms = 1.5 A <= 1.5 (m + 2 m / 3) = 2.5 m``: the factor 3 leaves m / 2 for the model's
    own approximations (the lighting's level continued flat beyond the map's order over-estimates a decaying tail;
    the view quadrature), and a prediction off by more fails (App. B's step in place of the flat continuation gave
    up to 6.9 m on city, docs/accuracy/grazing.md). The other side, m <= rms, is the margin's own claim (1.5 above
    every measured / average ratio seen, 0.76-1.23 on four maps) and is asserted as the issue states it."""
    px = _map(name, 64)
    lobe = parse_brdf(spec)
    sm = create_shrm(px, lobe, order=f, p_order=p, size=64)
    m, se = measure_resolved(sm, px, lobe)
    assert np.all(se <= RESOLVED * m), (m, se)
    from relight.prefilter import project_lighting
    from relight.shrm.creation import spectrum_order

    vs = order_search.cached_spectrum(lobe, spectrum_order(f, 63), p, band_edges(0.1))
    pred = predicted_by_view(vs, project_lighting(px, min(vs.F, 63)), f, p, bands=BANDS)
    for b, mb in zip(pred, m, strict=True):
        assert mb <= b.rms <= 3.0 * mb + 0.005, (b.ndotv, mb, b.rms)
        assert b.rms == pytest.approx(VIEW_MARGIN * b.rms_average)
    # the report's own by_view (create_shrm) is the same prediction for its bands
    rep = sm.report["components"][0]["predicted"]["by_view"]
    mine = predicted_by_view(vs, project_lighting(px, min(vs.F, 63)), f, p, bands=[tuple(x["ndotv"]) for x in rep])
    assert [x["rms"] for x in rep] == pytest.approx([b.rms for b in mine], rel=1e-9)


def test_report_carries_by_view_and_no_negative_radiance() -> None:
    """create_shrm's report lists predicted.by_view for [0, 0.3], [0.3, 0.7], [0.7, 1] (and the fine bands) per
    component and for the material; reflect() never returns negative radiance, and its clamp never increases a
    texel's error against the brute force (|max(x, 0) - t| <= |x - t| for t >= 0), checked where Phong at F = 4
    rings around city's lamps."""
    from relight.reference_view import reference_view

    px = _map("city", 32)
    lobe = parse_brdf("phong:s=64")
    sm = create_shrm(px, lobe, order=4, size=16)
    by_view = sm.report["predicted"]["by_view"]
    assert [b["ndotv"] for b in by_view] == [[0.0, 0.3], [0.3, 0.7], [0.7, 1.0]]
    assert all(b["rms"] > 0.0 and b["rms_appendix_b"] >= b["rms_average"] for b in by_view)
    assert len(sm.report["components"][0]["predicted"]["by_view_fine"]) == 10
    v = np.array([0.3, 0.2, 0.93])
    raw, clamped = reflect(sm, v, clamp=False), reflect(sm, v)
    assert raw.min() < 0.0, "the case must ring"
    assert clamped.min() >= 0.0
    ref = reference_view(px, lobe, v, 16)
    assert np.all(np.abs(clamped - ref) <= np.abs(raw - ref) + 1e-12)


def test_plan_names_the_band_that_cannot_be_met() -> None:
    """POST /plan's core (plan_job) for Torrance–Sparrow alpha = 0.2 at epsilon = 0.01: predicted_error.by_view says,
    before anything is computed, that N.V in [0, 0.3] cannot meet it (and what it can reach) while [0.7, 1] does."""
    from relight import costmodel, planning
    from relight.prefilter import project_lighting

    px = _map("courtyard", 32)
    lig = project_lighting(px, 31)
    info = {"height": 32, "width": 64, "sh_power_spectrum": lig.band_energy().tolist(),
            "total_energy": lig.total_energy}
    plan = planning.plan_job(info, {"kind": "torrance-sparrow", "alpha": 0.2}, {"epsilon": 0.01},
                             calibration=costmodel.default_calibration())
    rim, mid, top = plan.to_json()["predicted_error"]["by_view"]
    assert rim["enforced"] and rim["met"] is False and rim["achievable_epsilon_brdf"] > 0.01
    assert top["enforced"] and top["met"] is True and top["epsilon_brdf"] <= 0.01
    assert mid["rms"] > top["rms"] > 0.0
