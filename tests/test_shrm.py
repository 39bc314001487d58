"""SHRMs (seed 000 eqs. 5–8, 12, App. C) against independent references.

Accuracy tests compare the eq. 12 map of an SHRM with ``relight.reference_view`` (brute-force eq. 1 over the
environment's pixels, independent of every SH routine) on sample maps area-averaged to 64 x 128, output 32 x 64.
A single view's R-indexed map contains every normal-view angle from 0 to 90 degrees (N = normalize(R + V)), so each
view covers grazing configurations; errors are measured on the R pixels whose angle between N and V is at most
89 degrees (``masked_rms``), and separately on the grazing band 70–89 degrees.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from relight import sh, shrm
from relight.brdf import lpq
from relight.brdf.spec import parse_brdf
from relight.conventions import latlong_dirs, ring_thetas
from relight.envmap import read_envmap, resample_latlong
from relight.errors import InputError
from relight.metrics import relative_rms
from relight.prefilter import prefilter_radial
from relight.reference_view import reference_sphere, reference_view

DATA = Path(__file__).resolve().parents[1] / "data" / "envmaps"
S = 32  # output rows of the accuracy tests
VIEWS = [(0.0, 0.0, 1.0), (0.2, 0.95, 0.1), (-0.6, -0.3, 0.7)]


@cache
def env(name: str = "courtyard", rows: int = 64) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


def masked_rms(a: np.ndarray, ref: np.ndarray, view: np.ndarray, lo_deg: float = 0.0, hi_deg: float = 89.0) -> float:
    """Relative RMS over the R pixels whose angle between N = normalize(R + V) and V lies in [lo, hi] degrees."""
    s = a.shape[0]
    v = np.asarray(view, float) / np.linalg.norm(view)
    n, ok = shrm.halfway_normals(latlong_dirs(s, 2 * s), v)
    ang = np.degrees(np.arccos(np.clip(n @ v, -1.0, 1.0)))
    keep = (ok & (ang >= lo_deg) & (ang <= hi_deg))[..., None]
    return relative_rms(np.where(keep, a, 0.0), np.where(keep, ref, 0.0))


# ------------------------------------------------------------------------------------------ exact identities
def test_p0_shrm_equals_prefilter_radial() -> None:
    lobe = parse_brdf("phong:s=32")
    e = env("city")
    for kw in ({"order": 20}, {"epsilon": 0.01}):
        ref = prefilter_radial(e, lobe, size=S, **kw)  # type: ignore[arg-type]
        sm = shrm.create_shrm(e, lobe, size=S, **kw)  # type: ignore[arg-type]
        comp = sm.components[0]
        assert comp.structure == "radial" and comp.terms == [(0, 0)] and comp.P == 0
        assert comp.F == ref.report["orders"]["F_B"]
        got = shrm.reflect(sm, [0.3, 0.4, -0.5])  # view independent
        np.testing.assert_allclose(got, ref.map, rtol=0, atol=1e-9 * np.abs(ref.map).max())
        np.testing.assert_allclose(comp.maps[0] * shrm.Y00, ref.map, atol=1e-9 * np.abs(ref.map).max())


def test_real_harmonics_match_scipy() -> None:
    from scipy.special import sph_harm_y

    rng = np.random.default_rng(42)
    th, ph = rng.uniform(0, np.pi, 50), rng.uniform(-np.pi, np.pi, 50)
    y = shrm.real_harmonics(5, th, ph)
    for p in range(6):
        for q in range(-p, p + 1):
            c = sph_harm_y(p, abs(q), th, ph)
            want = c.real if q == 0 else np.sqrt(2) * (-1) ** q * (c.real if q > 0 else c.imag)
            np.testing.assert_allclose(y[:, shrm.real_index(p, q)], want, atol=1e-13)
    # consistent with relight.sh's real basis: sum Br Yr == sum B Y for random real-field coefficients
    lmax = 4
    l, m = sh.lm_arrays(lmax)
    alm = rng.standard_normal(l.size) + 1j * rng.standard_normal(l.size)
    alm[m == 0] = alm[m == 0].real
    direct = sh.evaluate(alm, lmax, th, ph)
    np.testing.assert_allclose(y[:, : (lmax + 1) ** 2] @ sh.to_real(alm, lmax), direct, atol=1e-12)


def _random_inputs(f: int, p: int, rng: np.random.Generator, channels: int = 3) -> tuple[np.ndarray, np.ndarray]:
    l, m = sh.lm_arrays(f)
    alm = (rng.standard_normal((channels, l.size)) + 1j * rng.standard_normal((channels, l.size))) / np.sqrt(1 + l)
    alm[:, m == 0] = alm[:, m == 0].real
    rho = rng.standard_normal((f + 1, p + 1, p + 1, 1)) / (1.0 + np.arange(f + 1))[:, None, None, None]
    return alm, rho


@pytest.mark.parametrize(("f", "p"), [(20, 3), (32, 8)])
def test_fast_synthesis_matches_wigner_reference(f: int, p: int) -> None:
    # ducc0 spin-|q| synthesis (sign/normalisation derived in relight.shrm) against App. C step 3 summed with
    # relight.wigner's d^l_mq; q up to 8 (beyond FACTS.md's tested |q| <= 5).
    alm, rho = _random_inputs(f, p, np.random.default_rng(42))
    terms = shrm.terms_for("general", p)
    a = shrm.synthesize_local(alm, f, rho, terms, 16)
    b = shrm.synthesize_local(alm, f, rho, terms, 16, backend="wigner")
    assert np.abs(a - b).max() < 1e-12 * np.abs(b).max()


@pytest.mark.slow
def test_fast_synthesis_matches_reference_to_l2048() -> None:
    f, p, rows = 2048, 2, [0, 7, 15]
    alm, rho = _random_inputs(f, p, np.random.default_rng(7), channels=1)
    terms = shrm.terms_for("general", p)
    a = shrm.synthesize_local(alm, f, rho, terms, 16)[:, rows]
    b = shrm.synthesize_local(alm, f, rho, terms, 16, backend="wigner", alphas=ring_thetas(16)[rows])
    assert np.abs(a - b).max() < 1e-11 * np.abs(b).max()


@pytest.mark.parametrize("view", [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, -1.0, 1e-9), (0.7, -0.1, -0.7)])
def test_global_shrm_equals_rotated_local(view: tuple[float, float, float]) -> None:
    # eq. 8 + eq. 12 (global maps, Y_pq(V) once) == eq. 6 per pixel with the local view angles R^{-1} V (eq. 3)
    sm = shrm.create_shrm(env(), parse_brdf("microfacet:sigma=0.3"), order=10, p_order=3, size=24)
    comp = sm.components[0]
    g = comp.view_map(np.array(view))
    loc = shrm.evaluate_local(comp, view)
    assert np.abs(g - loc).max() < 1e-12 * np.abs(loc).max()


def test_rotating_the_environment_about_y_shifts_the_shrm() -> None:
    # Rolling the map by k columns rotates the lighting about +Y by 2 pi k / W: local SHRM maps shift by whole
    # columns, and the eq. 12 map for the rotated view is the shifted map.
    e = env()  # 64 x 128
    k = 6  # -> 3 output columns at 32 x 64
    lobe = parse_brdf("microfacet:sigma=0.2")
    a = shrm.create_shrm(e, lobe, order=12, p_order=3, size=S)
    b = shrm.create_shrm(np.roll(e, k, axis=1), lobe, order=12, p_order=3, size=S)
    shift = k * 2 * S // e.shape[1]
    scale = np.abs(a.components[0].maps).max()
    np.testing.assert_allclose(b.components[0].maps, np.roll(a.components[0].maps, shift, axis=2), atol=1e-12 * scale)
    v = np.array([0.5, 0.3, -0.8])
    gamma = 2 * np.pi * k / e.shape[1]  # phi -> phi + gamma, phi = atan2(z, x)
    rot = np.array([[np.cos(gamma), 0, -np.sin(gamma)], [0, 1, 0], [np.sin(gamma), 0, np.cos(gamma)]])
    ma, mb = shrm.reflect(a, v), shrm.reflect(b, rot @ v)
    np.testing.assert_allclose(mb, np.roll(ma, shift, axis=1), atol=1e-11 * np.abs(ma).max())


def test_kajiya_kay_shrm_has_p_plus_1_maps() -> None:
    lobe = parse_brdf("kajiya-kay:s=32")
    sm = shrm.create_shrm(env(), lobe, epsilon=0.03, size=16)
    comp = sm.components[0]
    assert comp.structure == "azimuthal" and comp.center == "T"
    assert comp.terms == [(p, 0) for p in range(comp.P + 1)] and comp.maps.shape[0] == comp.P + 1
    assert "q = 0" in comp.report["reason"]
    # its eq. 12 map (per-pixel Y_p0(C.V)) equals the general eq. 8 route
    v = np.array([0.2, 0.3, 0.9])
    g = shrm.local_to_global(comp.maps, comp.terms, ring_thetas(comp.height))
    th, ph = shrm.sh_angles(v)
    via_eq8 = np.tensordot(shrm.real_harmonics(comp.P, th, ph), g, axes=(0, 0))
    np.testing.assert_allclose(comp.view_map(v), via_eq8, atol=1e-12 * np.abs(via_eq8).max())


# ------------------------------------------------------------------------------- accuracy against eq. 1
def _check_against_reference(spec: str, view: tuple[float, float, float], f_hi: int, size: int, p_hi: int = 12,
                             tol_89: float = 0.035, tol_80: float = 0.02, env_rows: int = 64) -> None:
    """The eq. 12 map of SHRMs for one view against ``reference_view``; tolerances:

    * orders chosen for epsilon = 0.03: relative RMS over 0-89 degrees <= the predicted sqrt(epsilon_brdf) (seed 000
      §5.1 uses the BRDF error as a conservative estimate of the light field's);
    * generous orders (F_hi, P_hi): below ``tol_89`` over 0-89 degrees and ``tol_80`` over 0-80 degrees (measured
      1-2.5 % and 0.5-1.5 % for microfacet at P = 12, 2.5-3.7 % and 1-2 % for skin at P = 16);
    * grazing band 70-89 degrees: the error falls by at least 30 % from P = 4 to P_hi — near grazing rho_hat varies
      fastest with theta_o, so the SHRM converges there slowly but surely in P (microfacet ~0.15 -> ~0.06).
    """
    e = env(rows=env_rows)
    lobe = parse_brdf(spec)
    v = np.array(view)
    ref = reference_view(e, lobe, v, size)
    assert np.all(np.isfinite(ref)) and ref.max() > 0
    sm = shrm.create_shrm(e, lobe, epsilon=0.03, size=size)
    pred = sm.report["predicted"]["rms_brdf"]
    assert 0.0 < pred < 0.2  # sqrt(0.03) ~ 0.17
    err = masked_rms(shrm.reflect(sm, v), ref, v)
    assert err <= pred, f"{spec} view {view}: measured {err:.4f} > predicted {pred:.4f}"
    lo_p = shrm.reflect(shrm.create_shrm(e, lobe, order=f_hi, p_order=4, size=size), v)
    hi_p = shrm.reflect(shrm.create_shrm(e, lobe, order=f_hi, p_order=p_hi, size=size), v)
    assert masked_rms(hi_p, ref, v) < tol_89
    assert masked_rms(hi_p, ref, v, hi_deg=80.0) < tol_80
    assert masked_rms(hi_p, ref, v, lo_deg=70.0) < 0.7 * masked_rms(lo_p, ref, v, lo_deg=70.0)


@pytest.mark.parametrize(
    ("sigma", "view", "f_hi", "size"),
    [
        (0.1, VIEWS[0], 40, 32),
        (0.1, VIEWS[2], 40, 32),
        (0.2, VIEWS[1], 30, 32),
        (0.3, VIEWS[0], 24, 24),
        pytest.param(0.3, VIEWS[2], 24, 24, marks=pytest.mark.slow),
        pytest.param(0.5, VIEWS[1], 16, 24, marks=pytest.mark.slow),
        pytest.param(0.5, VIEWS[0], 16, 24, marks=pytest.mark.slow),
    ],
)
def test_microfacet_shrm_matches_angular_reference(sigma: float, view: tuple[float, float, float], f_hi: int,
                                                   size: int) -> None:
    _check_against_reference(f"microfacet:sigma={sigma}", view, f_hi, size)


@pytest.mark.parametrize(
    ("spec", "view", "env_rows", "size"),
    [
        ("lafortune:preset=skin", VIEWS[0], 32, 16),
        pytest.param("lafortune:preset=skin", VIEWS[0], 64, 24, marks=pytest.mark.slow),
        pytest.param("lafortune:preset=skin", VIEWS[2], 64, 24, marks=pytest.mark.slow),
        pytest.param("lafortune:preset=housepaint-blue", VIEWS[1], 64, 24, marks=pytest.mark.slow),
    ],
)
def test_lafortune_matches_angular_reference(spec: str, view: tuple[float, float, float], env_rows: int,
                                             size: int) -> None:
    # Seed 000 §7.1: Marschner et al.'s skin fit (RGB lobes, "much stronger specularities toward grazing angles"),
    # plus Cornell's housepaint fit. Grazing needs more terms than microfacet: compare at P = 16.
    _check_against_reference(spec, view, min(30, env_rows - 1), size, p_hi=16, tol_89=0.045, tol_80=0.025,
                             env_rows=env_rows)


def test_kajiya_kay_matches_angular_reference() -> None:
    # T-centred lobe: the component is indexed by T = normalize(+Y x N) and looked up there (bilinear); with the
    # SHRM at 4x the output resolution the interpolation error is small and the error is the truncation's.
    e = env(rows=32)
    lobe = parse_brdf("kajiya-kay:s=16")
    v = np.array([0.2, 0.95, 0.1])
    ref = reference_view(e, lobe, v, 16)
    sm = shrm.create_shrm(e, lobe, epsilon=0.03, size=64)
    assert masked_rms(shrm.reflect(sm, v, size=16), ref, v) <= sm.report["predicted"]["rms_brdf"]
    hi = shrm.create_shrm(e, lobe, order=24, p_order=16, size=64)
    assert hi.components[0].maps.shape[0] == 17
    assert masked_rms(shrm.reflect(hi, v, size=16), ref, v) < 0.01


def test_sum_of_lobes_components_and_accuracy() -> None:
    e = env()
    brdf = parse_brdf("lambert:albedo=0.5+microfacet:sigma=0.3")
    size = 16
    sm = shrm.create_shrm(e, brdf, order=20, p_order=8, size=size)
    assert [(c.center, c.structure) for c in sm.components] == [("N", "radial"), ("R", "general")]
    v = np.array([0.1, 0.5, 0.86])
    ref = reference_view(e, brdf, v, size)
    assert masked_rms(shrm.reflect(sm, v), ref, v) < 0.03
    # the N-indexed component is the irradiance map (looked up at N = normalize(R + V) by reflect)
    lam = prefilter_radial(e, brdf.lobes[0], order=20, size=size)
    np.testing.assert_allclose(sm.components[0].maps[0] * shrm.Y00, lam.map, atol=1e-9 * lam.map.max())


# --------------------------------------------------------------------------------- rendering and forms
def test_sphere_render_global_local_and_reference() -> None:
    e = env()
    lobe = parse_brdf("microfacet:sigma=0.3")
    sm = shrm.create_shrm(e, lobe, order=24, p_order=6, size=64)
    v = np.array([0.0, 0.0, 1.0])
    g = shrm.render_sphere(sm, v, 24)
    loc = shrm.render_sphere(sm, v, 24, local=True)
    ref = reference_sphere(e, lobe, v, 24)
    n, mask = shrm.sphere_geometry(v, 24)
    assert mask.sum() > 0.7 * 24 * 24 and np.all(g[~mask] == 0.0)
    assert np.allclose(n[12, 12], [0, 0, 1], atol=0.1) and n[0, 12, 1] > 0.9  # +Y up, centre faces the camera
    lum = lambda x: x[mask] @ np.array([0.2126, 0.7152, 0.0722])  # noqa: E731
    rms = lambda a, b: float(np.sqrt(np.mean((lum(a) - lum(b)) ** 2) / np.mean(lum(b) ** 2)))  # noqa: E731
    assert rms(g, loc) < 0.01  # same SHRM, interpolated before or after eq. 12
    # the orthographic camera's pixels near the rim are grazing: compare with the reference at the map's accuracy
    assert rms(g, ref) < 0.05


def test_explicit_forms() -> None:
    ico = shrm.icosahedron_views()
    assert ico.shape == (12, 3) and np.allclose(np.linalg.norm(ico, axis=1), 1.0)
    d = ico @ ico.T
    np.fill_diagonal(d, -2)
    assert np.allclose(np.sort(d, axis=1)[:, -5:], 1 / np.sqrt(5))  # 5 neighbours at the icosahedron's edge angle
    sm = shrm.create_shrm(env(), parse_brdf("microfacet:sigma=0.3"), order=10, p_order=3, size=16)
    maps = shrm.explicit_maps(sm, ico)
    for k in (0, 7):
        np.testing.assert_allclose(maps[k], shrm.reflect(sm, ico[k]), rtol=1e-5, atol=1e-6 * np.abs(maps).max())
    grid = shrm.view_grid(4)
    assert grid.shape == (4, 4, 3)
    assert shrm.explicit_maps(sm, grid).shape == (16, 16, 32, 3)
    comp = sm.components[0]
    km = shrm.kautz_mccool_texture(comp, 5)
    theta = ring_thetas(5)[2]
    want = sum(comp.maps[k] * shrm.real_harmonics(comp.P, np.array(theta), np.array(0.0))[shrm.real_index(p, 0)]
               for k, (p, q) in enumerate(comp.terms) if q == 0)
    np.testing.assert_allclose(km[2], want, rtol=1e-5, atol=1e-6 * np.abs(want).max())


def test_report_and_errors() -> None:
    e = env(rows=32)
    sm = shrm.create_shrm(e, parse_brdf("microfacet:sigma=0.4"), epsilon=0.05)
    rep = sm.report
    assert rep["representation"] == "shrm" and rep["layout"] == "local"
    c = rep["components"][0]
    assert c["structure"] == "general" and "(P + 1)^2" in c["reason"] and c["n_maps"] == (c["orders"]["P_B"] + 1) ** 2
    for key in ("epsilon_brdf", "epsilon_lighting", "epsilon_appendix_b", "rms_brdf"):
        assert 0.0 <= c["predicted"][key] <= 1.0
    assert set(rep["timings"]) >= {"brdf_coefficients", "lighting_projection", "synthesis"}
    lobe = parse_brdf("microfacet:sigma=0.4")
    with pytest.raises(InputError, match="either"):
        shrm.create_shrm(e, lobe, epsilon=0.1, order=3)
    with pytest.raises(InputError, match="epsilon"):
        shrm.create_shrm(e, lobe, epsilon=2.0)
    with pytest.raises(InputError, match="width"):
        shrm.create_shrm(e[:, :40], lobe)
    with pytest.raises(InputError, match="zero"):
        shrm.reflect(sm, [0, 0, 0])
    with pytest.raises(InputError, match="3 finite"):
        shrm.reflect(sm, [0, 1])
    with pytest.raises(ValueError, match="backend"):
        shrm.synthesize_local(np.zeros((1, 1), complex), 0, np.zeros((1, 1, 1, 1)), [(0, 0)], 4, backend="x")  # type: ignore[arg-type]
    lpq.clear_cache()


def test_oversized_plans_are_refused_before_allocating() -> None:
    """A plan whose coefficient maps would not fit in memory is an InputError naming the size, not an OOM crash."""
    from relight.errors import InputError

    px = np.ones((16, 32, 3))
    with pytest.raises(InputError, match=r"289 maps of 2048 x 4096"):
        shrm.create_shrm(px, parse_brdf("microfacet:sigma=0.3"), order=15, p_order=16, size=2048)
