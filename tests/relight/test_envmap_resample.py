"""Tests for lat-long resampling (relight.envmap.resample).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import numpy as np
import pytest
from envmap_refs import (
    footprint_average,
    row_solid_angles,
    smooth_fn,
    sphere_integral,
)

from relight import envmap as E


def test_resample_downsample_matches_block_average() -> None:
    rng = np.random.default_rng(11)
    src = rng.random((32, 64, 3)) ** 4
    out = E.resample_latlong(src, 16)
    w = row_solid_angles(32).reshape(16, 2)  # the two source rows of each output row
    blocks = src.reshape(16, 2, 32, 2, 3)
    expected = np.einsum("iajbc,ia->ijc", blocks, w) / (2 * w.sum(axis=1))[:, None, None]
    np.testing.assert_allclose(out, expected, rtol=1e-5)
    assert sphere_integral(out) == pytest.approx(sphere_integral(src), rel=1e-6)


def test_resample_non_integer_factor_and_upsample() -> None:
    rng = np.random.default_rng(12)
    src = rng.random((48, 96, 3))
    down = E.resample_latlong(src, 20)
    assert down.shape == (20, 40, 3)
    assert sphere_integral(down) == pytest.approx(sphere_integral(src), rel=1e-6)
    np.testing.assert_allclose(E.resample_latlong(np.full((12, 24), 3.0), 5), 3.0, rtol=1e-6)
    up = E.resample_latlong(np.full((8, 16, 3), 2.0), 32)
    assert up.shape == (32, 64, 3)
    np.testing.assert_allclose(up, 2.0, rtol=1e-6)
    smooth = footprint_average(smooth_fn, 16)
    up = E.resample_latlong(smooth, 64)
    assert sphere_integral(up) == pytest.approx(sphere_integral(smooth), rel=5e-3)
