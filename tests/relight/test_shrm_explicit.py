"""Tests for explicit forms, App. C (relight.shrm.explicit), against independent references
(closed forms, a second algorithm, brute-force quadrature of eq. 1: ``relight.reference_view``).
"""

from __future__ import annotations

import numpy as np
from shrm_refs import (
    env,
)

from relight import indexing, shrm
from relight.brdf.spec import parse_brdf
from relight.conventions import ring_thetas


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
    want = sum(comp.maps[k] * shrm.real_harmonics(comp.P, np.array(theta), np.array(0.0))[indexing.full_index(p, 0)]
               for k, (p, q) in enumerate(comp.terms) if q == 0)
    np.testing.assert_allclose(km[2], want, rtol=1e-5, atol=1e-6 * np.abs(want).max())
