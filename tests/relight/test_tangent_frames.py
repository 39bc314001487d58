"""Tests of relight.tangent_frames: orthonormality, the documented fallbacks at the singular points (no NaN), and
continuity right next to them (1e-8 away the projection, not the fallback, is used)."""

from __future__ import annotations

import numpy as np
import pytest

from relight.errors import InputError
from relight.shrm import tangent_field
from relight.tangent_frames import azimuthal_frames, frame_errors, mesh_frames, projected_frames


def _near(d: np.ndarray, eps: float) -> np.ndarray:
    """Unit vectors at angle ~eps from d, in several directions around it, plus d and -d themselves."""
    d = d / np.linalg.norm(d)
    a = np.cross(d, [0.3, 0.5, 0.7])
    a /= np.linalg.norm(a)
    b = np.cross(d, a)
    out = [d, -d]
    for ang in np.linspace(0, 2 * np.pi, 7)[:-1]:
        for s in (1.0, -1.0):
            v = s * d + eps * (np.cos(ang) * a + np.sin(ang) * b)
            out.append(v / np.linalg.norm(v))
    return np.array(out)


@pytest.mark.parametrize("d", [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [1.0, 1.0, 1.0]])
def test_projected_frames_at_and_next_to_singularities(d: list[float]) -> None:
    dv = np.asarray(d) / np.linalg.norm(d)
    n = _near(dv, 1e-8)
    f = projected_frames(n, dv)
    assert np.all(np.isfinite(f))
    assert frame_errors(f) < 1e-12
    assert np.allclose(np.linalg.det(f), 1.0)
    assert np.abs(f[:, 2] - n).max() == 0.0
    # exactly on the singular points: the documented fallback (the least-aligned world axis, projected)
    k = int(np.argmin(np.abs(dv)))
    for row in (0, 1):
        axis = np.eye(3)[k] - (np.eye(3)[k] @ n[row]) * n[row]
        assert np.allclose(f[row, 0], axis / np.linalg.norm(axis), atol=1e-15)
    # next to them: the projection of d (not the fallback), accurate in direction to ~1e-8 relative
    proj = dv - (n[2:] @ dv)[:, None] * n[2:]
    proj /= np.linalg.norm(proj, axis=1, keepdims=True)
    assert np.abs(f[2:, 0] - proj).max() < 1e-6
    # away from them, t is the normalised projection and b = n x t
    rng = np.random.default_rng(0)
    m = rng.normal(size=(50, 3))
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    g = projected_frames(m, dv)
    p = dv - (m @ dv)[:, None] * m
    assert np.allclose(g[:, 0], p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-14)
    assert np.allclose(g[:, 1], np.cross(m, g[:, 0]), atol=1e-14)


def test_azimuthal_y_is_the_shrm_tangent_field() -> None:
    n = np.concatenate([_near(np.array([0.0, 1.0, 0.0]), 1e-8), np.random.default_rng(1).normal(size=(40, 3))])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    f = azimuthal_frames(n)
    assert np.all(np.isfinite(f)) and frame_errors(f) < 1e-12
    assert np.abs(f[:, 0] - tangent_field(n)).max() < 1e-7  # tangent_field single-pass rounding next to the pole
    assert np.array_equal(f[0, 0], [1.0, 0.0, 0.0]) and np.array_equal(f[1, 0], [1.0, 0.0, 0.0])


def test_mesh_frames_gltf_sign_and_degenerate_tangents() -> None:
    n = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    t = np.array([[1.0, 0.0, 0.2, 1.0], [1.0, 0.0, 0.0, -1.0], [0.0, 0.0, 3.0, 1.0], [0.0, 0.0, 0.0, 1.0]])
    f = mesh_frames(n, t)
    assert np.all(np.isfinite(f)) and frame_errors(f) < 1e-12
    assert np.allclose(f[0], [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert np.allclose(f[1, 1], -np.cross(n[1], f[1, 0]))  # w = -1: mirrored bitangent
    assert np.linalg.det(f[1]) < 0.0
    # tangent parallel to n, and a zero tangent: fallback (least-aligned axis with +Y, projected)
    assert np.allclose(f[2, 0], [1.0, 0.0, 0.0]) and np.allclose(f[3, 0], [0.0, 0.0, 1.0])
    with pytest.raises(InputError, match="handedness"):
        mesh_frames(n[:1], [[1.0, 0.0, 0.0, 0.5]])
    with pytest.raises(InputError, match="shape"):
        mesh_frames(n, t[:2])


def test_bad_inputs() -> None:
    with pytest.raises(InputError, match="non-zero"):
        projected_frames([[0.0, 0.0, 0.0]], [0, 1, 0])
    with pytest.raises(InputError, match="finite"):
        azimuthal_frames([[np.nan, 0.0, 1.0]])
