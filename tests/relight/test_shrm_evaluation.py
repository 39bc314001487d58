"""Evaluating SHRMs (relight.shrm.evaluation): sphere renders, eq. 6 and eq. 12.
"""

from __future__ import annotations

import numpy as np
from shrm_refs import (
    env,
)

from relight import shrm
from relight.brdf.spec import parse_brdf
from relight.reference_view import reference_sphere


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
