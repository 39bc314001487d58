"""The angular-domain reference and the error metric."""

from __future__ import annotations

import numpy as np
import pytest

from relight.brdf.radial import Phong
from relight.conventions import latlong_dirs, pixel_solid_angles
from relight.metrics import compare, relative_rms
from relight.orders import phong_angular_width
from relight.reference import reference_radial, truncation_angle


@pytest.mark.parametrize("s", [4.0, 100.0, 2000.0])
def test_truncation_angle_matches_appendix_d_closed_form(s: float) -> None:
    eps = 1e-3
    theta_closed, _ = phong_angular_width(s, eps)
    assert truncation_angle(Phong(s), eps) == pytest.approx(theta_closed, rel=2e-3)


def test_reference_of_a_single_bright_pixel_is_the_lobe() -> None:
    # One lit pixel: B(C) = L dOmega u(C . w) exactly, an independent closed form for every output direction.
    h, w = 32, 64
    env = np.zeros((h, w, 3))
    env[10, 20] = [5.0, 2.0, 1.0]
    s, size = 20.0, 8
    out = reference_radial(env, Phong(s), size, epsilon=0.0)
    wdir = latlong_dirs(h, w)[10, 20]
    t = latlong_dirs(size, 2 * size) @ wdir
    expected = (s + 1) / (2 * np.pi) * np.clip(t, 0, None) ** s
    expected = expected[..., None] * env[10, 20] * pixel_solid_angles(h, w)[10]
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-300)


def test_reference_is_independent_of_chunking() -> None:
    rng = np.random.default_rng(42)
    env = rng.random((16, 32, 3))
    a = reference_radial(env, Phong(8), 8, epsilon=1e-6)
    b = reference_radial(env, Phong(8), 8, epsilon=1e-6, chunk_elems=100)
    np.testing.assert_allclose(a, b, rtol=1e-12)


def test_metric_definitions() -> None:
    rng = np.random.default_rng(1)
    ref = rng.random((8, 16, 3)) + 0.1
    assert relative_rms(1.1 * ref, ref) == pytest.approx(0.1)
    assert relative_rms(ref, ref) == 0.0
    c = compare(1.1 * ref, ref)
    assert c["energy_error"] == pytest.approx(0.1)
    assert c["finite"] is True
    with pytest.raises(ValueError, match="shapes differ"):
        relative_rms(ref, ref[:4])
