"""Tests for environment maps: validation and layouts (relight.envmap.environment).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import numpy as np
import pytest
from envmap_refs import (
    DATA,
    rgb_exr_bytes,
)

from relight import envmap as E
from relight.errors import InputError


def test_read_envmap_from_bytes_matches_path() -> None:
    path = DATA / "studio.exr"
    a = E.read_envmap(path)
    b = E.read_envmap(path.read_bytes())
    np.testing.assert_array_equal(a.pixels, b.pixels)


def test_wrong_aspect_ratio() -> None:
    with pytest.raises(InputError, match="300 x 200"):
        E.read_envmap(rgb_exr_bytes(np.ones((200, 300, 3))))
    with pytest.raises(InputError, match="64 x 64"):
        E.read_envmap(rgb_exr_bytes(np.ones((64, 64, 3))), layout="latlong")


def test_non_finite_pixels_named() -> None:
    rgb = np.ones((64, 128, 3), np.float32)
    rgb[12, 40, 1] = np.nan
    rgb[30, 5, 0] = np.inf
    rgb[63, 127, 2] = -np.inf
    with pytest.raises(InputError, match=r"^3 non-finite pixel values \(NaN/Inf\), first at row 12, column 40$"):
        E.read_envmap(rgb_exr_bytes(rgb))
    with pytest.raises(InputError, match=r"first at face \+X row"):
        faces = np.ones((6, 4, 4, 3), np.float32)
        faces[0, 1, 2, 0] = np.nan
        E.envmap_from_cube(faces)


def test_envmap_from_array_clamps_and_counts() -> None:
    rgb = np.ones((4, 8, 3))
    rgb[1, 2] = [-0.5, -0.25, 0.5]
    env = E.envmap_from_array(rgb)
    assert (env.negatives_clamped, env.min_negative, env.source_format) == (2, -0.5, "array")
    assert env.pixels.min() == 0.0 and rgb.min() == -0.5  # the caller's array is untouched
