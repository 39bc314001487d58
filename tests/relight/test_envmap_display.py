"""Tests for tone mapping and previews (relight.envmap.display).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from envmap_refs import (
    srgb_oetf,
)
from PIL import Image

from relight import envmap as E
from relight.errors import InputError


def test_tonemap_operators() -> None:
    x = np.array([0.0, 0.01, 0.18, 1.0, 4.0, 100.0, 1e30])
    aces = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    expected = np.round(srgb_oetf(aces) * 255).astype(np.uint8)
    rgb = np.stack([x, x, x], -1)
    np.testing.assert_array_equal(E.tonemap(rgb)[:, 0], expected)
    np.testing.assert_array_equal(E.tonemap(rgb, operator="reinhard")[:, 0],
                                  np.round(srgb_oetf(x / (1 + x)) * 255).astype(np.uint8))
    assert E.tonemap(np.array([[1.0, 1.0, 1.0]]), operator="reinhard")[0, 0] == 188  # 0.5 -> sRGB 0.7354
    np.testing.assert_array_equal(E.tonemap(rgb, exposure=1.0), E.tonemap(2 * rgb))
    assert E.tonemap(np.array([[np.nan, -1.0, np.inf]])).tolist() == [[0, 0, 255]]
    with pytest.raises(InputError, match="operator"):
        E.tonemap(rgb, operator="filmic")


def test_png_preview(tmp_path: Path) -> None:
    rgb = np.random.default_rng(8).random((8, 16, 3)) * 4
    E.write_png_preview(tmp_path / "p.png", rgb, exposure=-1.0, operator="reinhard")
    with Image.open(tmp_path / "p.png") as im:
        assert im.mode == "RGB"
        np.testing.assert_array_equal(np.asarray(im), E.tonemap(rgb, exposure=-1.0, operator="reinhard"))
