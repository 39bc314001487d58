"""Tests for the SHRM real basis and stored terms (relight.shrm.basis), against independent references
(closed forms, a second algorithm, brute-force quadrature of eq. 1: ``relight.reference_view``).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from shrm_refs import (
    env,
)

from relight import indexing, sh, shrm
from relight.brdf.spec import parse_brdf
from relight.conventions import dirs_to_angles, ring_thetas


def test_real_harmonics_match_scipy() -> None:
    from scipy.special import sph_harm_y

    rng = np.random.default_rng(42)
    th, ph = rng.uniform(0, np.pi, 50), rng.uniform(-np.pi, np.pi, 50)
    y = shrm.real_harmonics(5, th, ph)
    for p in range(6):
        for q in range(-p, p + 1):
            c = sph_harm_y(p, abs(q), th, ph)
            want = c.real if q == 0 else np.sqrt(2) * (-1) ** q * (c.real if q > 0 else c.imag)
            np.testing.assert_allclose(y[:, indexing.full_index(p, q)], want, atol=1e-13)
    # consistent with relight.sh's real basis: sum Br Yr == sum B Y for random real-field coefficients
    lmax = 4
    l, m = indexing.healpy_lm(lmax)
    alm = rng.standard_normal(l.size) + 1j * rng.standard_normal(l.size)
    alm[m == 0] = alm[m == 0].real
    direct = sh.evaluate(alm, lmax, th, ph)
    np.testing.assert_allclose(y[:, : (lmax + 1) ** 2] @ sh.to_real(alm, lmax), direct, atol=1e-12)


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
    th, ph = dirs_to_angles(v)
    via_eq8 = np.tensordot(shrm.real_harmonics(comp.P, th, ph), g, axes=(0, 0))
    np.testing.assert_allclose(comp.view_map(v), via_eq8, atol=1e-12 * np.abs(via_eq8).max())


def test_package_reexports_every_module_name() -> None:
    """``relight.shrm`` re-exports each module's public names (the same objects) and imports nothing else."""
    assert sorted(shrm.__all__) == sorted(shrm._EXPORTS)
    for name in shrm.__all__:
        module = importlib.import_module(f"relight.shrm.{shrm._EXPORTS[name]}")
        assert getattr(shrm, name) is getattr(module, name)
    with pytest.raises(AttributeError, match="no_such_name"):
        shrm.no_such_name  # noqa: B018
