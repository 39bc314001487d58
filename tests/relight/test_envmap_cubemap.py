"""Tests for cube maps (relight.envmap.cubemap).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from envmap_refs import (
    cube_integral,
    footprint_average,
    gl_face_dirs,
    latlong_dirs,
    row_solid_angles,
    smooth_fn,
    sphere_integral,
)
from numpy.typing import NDArray

from relight import envmap as E


def test_cube_constant_gives_constant() -> None:
    faces = {n: np.full((8, 8, 3), (0.25, 0.5, 2.0), np.float32) for n in E.FACE_NAMES}
    out = E.cube_to_latlong(faces, 16)
    assert out.shape == (16, 32, 3)
    np.testing.assert_allclose(out, np.broadcast_to([0.25, 0.5, 2.0], out.shape), rtol=1e-6)


def test_cube_analytic_function_and_integral() -> None:
    size, h = 32, 64
    cube = smooth_fn(gl_face_dirs(size)).astype(np.float32)
    out = E.cube_to_latlong(cube, h)
    ref = footprint_average(smooth_fn, h)
    # Bilinear reconstruction from 32^2 texels per face: error O(texel^2) ~ 0.5 % of the values here.
    assert np.max(np.abs(out - ref)) < 0.01
    assert np.mean(np.abs(out - ref)) < 1e-3
    assert sphere_integral(out) == pytest.approx(cube_integral(cube), rel=1e-4)


def test_cube_integral_preserved_with_hot_spots() -> None:
    rng = np.random.default_rng(9)
    size = 16
    cube = (rng.random((6, size, size, 3)) ** 8 * 100).astype(np.float32)
    assert sphere_integral(E.cube_to_latlong(cube, 2 * size)) == pytest.approx(cube_integral(cube), rel=5e-3)
    sun = np.zeros((6, size, size, 1), np.float32)
    sun[4, 6:9, 9:12] = 3.4e4  # a 3 x 3 texel "sun" on +Z
    assert sphere_integral(E.cube_to_latlong(sun, 2 * size)) == pytest.approx(cube_integral(sun), rel=5e-3)


FACE_AXES = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


@pytest.mark.parametrize(("face", "axis"), list(enumerate(FACE_AXES)))
def test_each_face_lands_on_its_axis(face: int, axis: tuple[int, int, int]) -> None:
    size, h = 8, 16
    cube = np.zeros((6, size, size, 1), np.float32)
    cube[face] = 1.0
    out = E.cube_to_latlong(cube, h)[..., 0]
    centroid = np.sum(out[..., None] * latlong_dirs(h) * row_solid_angles(h)[:, None, None], axis=(0, 1))
    np.testing.assert_allclose(centroid / np.linalg.norm(centroid), axis, atol=1e-6)
    assert sphere_integral(out[..., None]) == pytest.approx(4 * np.pi / 6, rel=5e-3)


def test_plus_x_face_is_the_centre_column_and_oriented_as_gl() -> None:
    size, h = 8, 16
    cube = np.zeros((6, size, size, 1), np.float32)
    cube[0, : size // 2, : size // 2] = 1.0  # top-left quarter of +X: t < 1/2 -> +Y, s < 1/2 -> +Z (sc = -rz)
    out = E.cube_to_latlong(cube, h)[..., 0]
    w = 2 * h
    assert out[h // 2 - 2, w // 2 + 1] == pytest.approx(1.0)  # just above the horizon, just toward +Z of +X
    assert out[h // 2 + 2, w // 2 - 2] == 0.0 and out[h // 2, 0] == 0.0
    d = np.sum(out[..., None] * latlong_dirs(h) * row_solid_angles(h)[:, None, None], axis=(0, 1))
    assert d[0] > 0 and d[1] > 0 and d[2] > 0


def build_layout(faces: NDArray[np.float32], layout: str) -> NDArray[np.float32]:
    """Assemble the documented layouts by hand."""
    s = faces.shape[1]
    px, nx, py, ny, pz, nz = faces
    if layout == "strip-h":
        return np.concatenate(list(faces), axis=1)
    if layout == "strip-v":
        return np.concatenate(list(faces), axis=0)
    if layout == "cross-h":
        cells = {(0, 1): py, (1, 0): nx, (1, 1): pz, (1, 2): px, (1, 3): nz, (2, 1): ny}
        out = np.full((3 * s, 4 * s, 3), np.nan, np.float32)  # unused cells may hold anything
    else:
        cells = {(0, 1): py, (1, 0): nx, (1, 1): pz, (1, 2): px, (2, 1): ny, (3, 1): nz[::-1, ::-1]}
        out = np.full((4 * s, 3 * s, 3), np.nan, np.float32)
    for (r, c), face in cells.items():
        out[r * s:(r + 1) * s, c * s:(c + 1) * s] = face
    return out


@pytest.mark.parametrize("layout", ["strip-h", "strip-v", "cross-h", "cross-v"])
def test_cube_layouts_equal_faces(tmp_path: Path, layout: str) -> None:
    size = 8
    faces = np.random.default_rng(10).random((6, size, size, 3)).astype(np.float32)
    faces[2, 0, 0, 1] = -0.003  # one negative value, clamped and counted
    image = build_layout(faces, layout)
    path = tmp_path / "cube.exr"
    E.write_exr(path, image)
    env = E.read_envmap(path)
    expected = E.envmap_from_cube({n: faces[i] for i, n in enumerate(E.FACE_NAMES)})
    assert env.layout == layout and env.source_format == "exr" and expected.source_format == "cube"
    assert env.pixels.shape == (2 * size, 4 * size, 3)
    assert env.negatives_clamped == expected.negatives_clamped == 1
    assert env.min_negative == pytest.approx(-0.003)
    np.testing.assert_array_equal(env.pixels, expected.pixels)
    np.testing.assert_array_equal(E.cube_faces_from_image(image, layout)[:, :, :, :], np.asarray(faces))


def test_cube_face_dirs_match_gl_table() -> None:
    np.testing.assert_allclose(E.cube_face_dirs(5), gl_face_dirs(5), atol=1e-15)
