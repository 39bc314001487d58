"""The paper's numbers (Mahajan, Tseng & Ramamoorthi 2008, Figs. 3A, 5, 7C) and the SVD-free predictions.

Independent references: K measured on the paper's 40^4 equal-area grid with a dense numpy SVD (design notes
§4.2: hemisphere 15, 27, 51, 75, 122 and sphere 25, 48, 95, 140, 232 for s = 5, 10, 20, 30, 50; eq. 14 at
sigma = 0.2: 64), the paper's figures (s = 30 -> 75; K ~ 2.5 s on the hemisphere), and the SVD itself for the
predictions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from relight.brdf.measured import tabulate_merl, write_merl
from relight.brdf.spec import parse_brdf
from relight.factor_predict import HALF_ANGLE_SLOPE, predict_terms, theta_h_curve
from relight.factorization import factorize

PHONG_S = (5, 10, 20, 30, 50)
HEMI_99 = (15, 27, 51, 75, 122)
SPHERE_99 = (25, 48, 95, 140, 232)


def _close(k: int, ref: int) -> bool:
    """The issue's +-3 %, at least +-1 term (integers)."""
    return abs(k - ref) <= max(1.0, 0.03 * ref)


def test_phong_terms_hemisphere_and_sphere() -> None:
    # 48 x 48 Gauss nodes: converged for s <= 50 (60 x 60 and 100 x 160 give the same K, bench/factorize.py).
    hemi, sphere = [], []
    for s, h_ref, s_ref in zip(PHONG_S, HEMI_99, SPHERE_99, strict=True):
        b = parse_brdf(f"phong:s={s}")
        h = factorize(b, n_theta=48).terms[0.99]
        sp = factorize(b, n_theta=48, domain="sphere").terms[0.99]
        assert _close(h, h_ref) and _close(sp, s_ref), (s, h, sp)
        hemi.append(h)
        sphere.append(sp)
    assert hemi[PHONG_S.index(30)] == 75  # the paper's Fig. 6
    # K ~ 2.5 s on the hemisphere and ~ 5 s on the sphere (Fig. 3A): K / s within 3 % for s >= 20 (the small-s
    # points carry the line's offset, K_hemi ~ 2.4 s + 3)
    for s, h, sp in zip(PHONG_S, hemi, sphere, strict=True):
        if s >= 20:
            assert abs(h / s / 2.5 - 1.0) <= 0.03, (s, h)
            assert abs(sp / s / 4.75 - 1.0) <= 0.03, (s, sp)  # 4.6-4.75 s measured; the paper's "5 s" rounds up


def test_radial_prediction_matches_svd() -> None:
    # Sphere: the count from relight's spectrum is the SVD (eq. 9) — equal up to discretisation (<= 1 term).
    # Hemisphere: l + 1 values per band (Fig. 5) — within the 3 %.
    for s in (2, 10, 30, 50):
        b = parse_brdf(f"phong:s={s}")
        sph = factorize(b, n_theta=48, domain="sphere").terms
        hemi = factorize(b, n_theta=48).terms
        p_sph = predict_terms(b, domain="sphere")["terms"]
        p_hemi = predict_terms(b)["terms"]
        for t in (0.9, 0.95, 0.99):
            assert abs(p_sph[t] - sph[t]) <= 1, (s, t, p_sph, sph)
            assert abs(p_hemi[t] - hemi[t]) <= max(1, 0.03 * hemi[t]) + 1, (s, t, p_hemi, hemi)
    assert predict_terms(parse_brdf("lambert"))["terms"] == {0.9: 1, 0.95: 1, 0.99: 1}


def test_half_angle_lobe_eq14() -> None:
    # On the paper's 40^4 grid eq. 14 at sigma = 0.2 needs 64 terms (design notes' independent dense SVD on the
    # equal-area grid; the paper: "about 60") — on both weighted grids.
    b = parse_brdf("microfacet:sigma=0.2")
    assert factorize(b, n_theta=40).terms[0.99] == 64
    assert factorize(b, n_theta=40, grid="equal-area").terms[0.99] == 64
    # The theta_h curve of eq. 14 is the lobe itself (no theta_d dependence): exp(-(theta_h/sigma)^2)/(4 pi sigma^2)
    c = theta_h_curve(b)
    ref = np.exp(-((c["theta_h"] / 0.2) ** 2)) / (4.0 * np.pi * 0.04)
    # (theta_h = 90 deg itself has no direction pair above the horizon: the curve is 0 there)
    np.testing.assert_allclose(c["value"][:-1], ref[:-1], rtol=1e-12, atol=1e-300)
    assert c["value"][-1] == 0.0
    p = predict_terms(b)
    # l* from the curve's SH spectrum, computed — the paper's printed 1/(2 sigma^2) = 12.5 would give K = 39
    assert p["l_star"][0.99] == 15
    assert p["paper_terms"][0.99] == round(15**2 / 4)
    assert p["terms"][0.99] == round(HALF_ANGLE_SLOPE[0.99] * 15**2)


@pytest.mark.parametrize(("sigma", "n_theta", "n_phi"), [(0.3, 96, 128), (0.25, 120, 160)])
def test_half_angle_prediction_against_converged_svd(sigma: float, n_theta: int, n_phi: int) -> None:
    # The calibrated K ~ slope (l*)^2 against the block SVD at a converged grid (the 1.5x finer grid agrees to
    # one term, bench/factorize.py): within 10 % at 99 % and 95 %, 30 % at 90 % (l* is an integer: at 90 % a unit
    # step of l* moves K by ~ 2 slope l*, > 25 % of K for these wide lobes).
    b = parse_brdf(f"microfacet:sigma={sigma}")
    svd = factorize(b, n_theta=n_theta, n_phi=n_phi).terms
    pred = predict_terms(b)["terms"]
    for t, tol in ((0.9, 0.3), (0.95, 0.1), (0.99, 0.1)):
        assert abs(pred[t] - svd[t]) <= tol * svd[t] + 1, (t, pred, svd)


def test_whole_degenerate_groups() -> None:
    # On the sphere the groups are whole bands: s = 30 needs 141 values at 99 %, i.e. band 11 split; whole
    # groups give (11 + 1)^2 = 144 (eq. 10). On the hemisphere only the pairs +-m are degenerate: at most +1.
    b = parse_brdf("phong:s=30")
    sph = factorize(b, n_theta=48, domain="sphere", n_values=200)
    assert sph.terms[0.99] == 141 and sph.terms_whole[0.99] == 144
    assert all(int(round(k**0.5)) ** 2 == k for k in sph.terms_whole.values())
    hemi = factorize(b, n_theta=48, n_values=200)
    for t, k in hemi.terms.items():
        assert 0 <= hemi.terms_whole[t] - k <= 1
        kw = hemi.terms_whole[t]
        assert hemi.singular_values[kw - 1] > hemi.singular_values[kw] * (1 + 1e-8)


def test_measured_merl_table_matches_its_model(tmp_path: Path) -> None:
    # Fig. 7C: measured materials sit on the analytic line. A MERL file tabulated from Torrance–Sparrow (no MERL
    # file ships; design notes §1) gives the model's K within one term and its leading singular values within 3 %
    # (trilinear lookup on MERL's grid smooths the lobe: measured 0.3-1.9 % for the first ten at 24 x 24 nodes),
    # and the same l* per threshold.
    ts = parse_brdf("torrance-sparrow:alpha=0.3,fresnel=none")
    path = tmp_path / "ts.binary"
    write_merl(path, tabulate_merl(ts))  # type: ignore[arg-type]
    merl = parse_brdf(f"merl:{path}")
    a, b = factorize(ts, n_theta=24), factorize(merl, n_theta=24)
    assert all(abs(a.terms[t] - b.terms[t]) <= 1 for t in a.terms), (a.terms, b.terms)
    np.testing.assert_allclose(b.singular_values[:10], a.singular_values[:10], rtol=3e-2)
    assert predict_terms(merl)["l_star"] == predict_terms(ts)["l_star"]
