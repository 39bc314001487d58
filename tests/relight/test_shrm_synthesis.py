"""Tests for local SHRM synthesis, App. C step 3 / eq. 14 (relight.shrm.synthesis), against independent references
(closed forms, a second algorithm, brute-force quadrature of eq. 1: ``relight.reference_view``).
"""

from __future__ import annotations

import numpy as np
import pytest
from shrm_refs import (
    S,
    env,
    random_inputs,
)

from relight import shrm
from relight.brdf.spec import parse_brdf
from relight.conventions import ring_thetas
from relight.prefilter import prefilter_radial


def test_p0_shrm_equals_prefilter_radial() -> None:
    lobe = parse_brdf("phong:s=32")
    e = env("city")
    for kw in ({"order": 20}, {"epsilon": 0.01}):
        ref = prefilter_radial(e, lobe, size=S, **kw)  # type: ignore[arg-type]
        sm = shrm.create_shrm(e, lobe, size=S, **kw)  # type: ignore[arg-type]
        comp = sm.components[0]
        assert comp.structure == "radial" and comp.terms == [(0, 0)] and comp.P == 0
        assert comp.F == ref.report.orders.F_B
        got = shrm.reflect(sm, [0.3, 0.4, -0.5])  # view independent
        np.testing.assert_allclose(got, ref.map, rtol=0, atol=1e-9 * np.abs(ref.map).max())
        np.testing.assert_allclose(comp.maps[0] * shrm.Y00, ref.map, atol=1e-9 * np.abs(ref.map).max())


@pytest.mark.parametrize(("f", "p"), [(20, 3), (32, 8)])
def test_fast_synthesis_matches_wigner_reference(f: int, p: int) -> None:
    # ducc0 spin-|q| synthesis (sign/normalisation derived in relight.shrm) against App. C step 3 summed with
    # relight.wigner's d^l_mq; q up to 8 (beyond docs/facts.md's tested |q| <= 5).
    alm, rho = random_inputs(f, p, np.random.default_rng(42))
    terms = shrm.terms_for("general", p)
    a = shrm.synthesize_local(alm, f, rho, terms, 16)
    b = shrm.synthesize_local(alm, f, rho, terms, 16, backend="wigner")
    assert np.abs(a - b).max() < 1e-12 * np.abs(b).max()


@pytest.mark.slow
def test_fast_synthesis_matches_reference_to_l2048() -> None:
    f, p, rows = 2048, 2, [0, 7, 15]
    alm, rho = random_inputs(f, p, np.random.default_rng(7), channels=1)
    terms = shrm.terms_for("general", p)
    a = shrm.synthesize_local(alm, f, rho, terms, 16)[:, rows]
    b = shrm.synthesize_local(alm, f, rho, terms, 16, backend="wigner", alphas=ring_thetas(16)[rows])
    assert np.abs(a - b).max() < 1e-11 * np.abs(b).max()


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
