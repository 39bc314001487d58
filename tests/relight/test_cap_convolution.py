"""The cap sum of a lobe that vanishes beyond a cap (relight.cap_convolution) against the dense sum over every
pixel, and the windowed near and far parts of a lobe against the lobe itself."""

from __future__ import annotations

import numpy as np
import pytest
from sky_refs import sun_sky

from relight.brdf.splitsum import GGXSplitSum
from relight.cap_convolution import WindowedLobe, angular_convolution, brute_force
from relight.envmap import cube_face_dirs


@pytest.mark.parametrize("theta1_pixels", [3.0, 12.0, 40.0])
def test_near_sum_backends_equal_the_dense_pixel_sum(theta1_pixels: float) -> None:
    # The compiled and the vectorised near sums against the dense sum over every pixel (the same quadrature, so
    # they differ only by the tabulated kernel, ~1e-7 here, and summation order). Directions: cube texel centres,
    # the exact poles and the seam at phi = +-pi, caps from a few pixels to one covering a pole (40 px of 32 rows).
    px = sun_sky(32)
    h = px.shape[0]
    theta1 = theta1_pixels * np.pi / h
    lobe = WindowedLobe(GGXSplitSum(0.15), 0.5 * theta1, theta1, near=True)
    dirs = np.concatenate([cube_face_dirs(4).reshape(-1, 3),
                           [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 1e-9], [-1.0, 0.3, -1e-9]]])
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    ref = brute_force(px, lobe, dirs)
    for backend in ("jit", "numpy"):
        got = angular_convolution(px, lobe, dirs, theta1, backend=backend)  # type: ignore[arg-type]
        np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max(), err_msg=backend)


def test_near_and_far_parts_sum_to_the_lobe() -> None:
    lobe = GGXSplitSum(0.1)
    t = np.cos(np.linspace(0.0, np.pi, 2001))
    near = WindowedLobe(lobe, 0.02, 0.04, near=True).u(t)
    far = WindowedLobe(lobe, 0.02, 0.04, near=False).u(t)
    np.testing.assert_allclose(near + far, lobe.u(t), rtol=1e-13, atol=0.0)
    assert np.all(near[np.arccos(t) > 0.04] == 0.0)
