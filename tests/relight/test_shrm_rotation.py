"""Tests for the global SHRM, eq. 8 (relight.shrm.rotation), against independent references
(closed forms, a second algorithm, brute-force quadrature of eq. 1: ``relight.reference_view``).
"""

from __future__ import annotations

import numpy as np
import pytest
from shrm_refs import (
    env,
)

from relight import shrm
from relight.brdf.spec import parse_brdf


@pytest.mark.parametrize("view", [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, -1.0, 1e-9), (0.7, -0.1, -0.7)])
def test_global_shrm_equals_rotated_local(view: tuple[float, float, float]) -> None:
    # eq. 8 + eq. 12 (global maps, Y_pq(V) once) == eq. 6 per pixel with the local view angles R^{-1} V (eq. 3)
    sm = shrm.create_shrm(env(), parse_brdf("microfacet:sigma=0.3"), order=10, p_order=3, size=24)
    comp = sm.components[0]
    g = comp.view_map(np.array(view))
    loc = shrm.evaluate_local(comp, view)
    assert np.abs(g - loc).max() < 1e-12 * np.abs(loc).max()
