"""Tests for PNG and JPEG decoding (relight.envmap.ldr).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from envmap_refs import (
    png16_bytes,
    srgb_eotf,
)
from PIL import Image

from relight import envmap as E
from relight.errors import InputError


def test_png_8bit_srgb_decode() -> None:
    values = np.arange(256, dtype=np.uint8)
    img = np.stack([values, values[::-1], np.roll(values, 7)], -1).reshape(8, 32, 3)
    buf = io.BytesIO()
    Image.fromarray(img, "RGB").save(buf, format="PNG")
    rgb, fmt = E.read_image(buf.getvalue())
    assert fmt == "png"
    np.testing.assert_allclose(rgb, srgb_eotf(img / 255.0), rtol=1e-6, atol=1e-9)
    assert rgb[0, 0, 0] == 0.0 and rgb[7, 31, 0] == 1.0


@pytest.mark.parametrize("mode", ["L", "P", "RGBA", "LA"])
def test_png_other_modes(mode: str) -> None:
    grey = np.arange(64, dtype=np.uint8).reshape(4, 16) * 4
    im = Image.fromarray(grey, "L").convert(mode)
    buf = io.BytesIO()
    im.save(buf, format="PNG")
    rgb, _ = E.read_image(buf.getvalue())
    np.testing.assert_allclose(rgb, srgb_eotf(np.repeat(grey[..., None], 3, -1) / 255.0), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(("colour_type", "channels"), [(2, 3), (6, 4), (4, 2), (0, 1)])
def test_png_16bit_all_filters(colour_type: int, channels: int) -> None:
    samples = np.random.default_rng(7).integers(0, 65536, (10, 9, channels)).astype(np.uint16)
    data = png16_bytes(samples, colour_type)
    assert E.probe(data) == E.ImageHeader("png", 9, 10, channels, 16)
    rgb, _ = E.read_image(data)
    colour = samples[..., :3] if channels >= 3 else np.repeat(samples[..., :1], 3, -1)
    np.testing.assert_allclose(rgb, srgb_eotf(colour / 65535.0), rtol=1e-6, atol=1e-9)


def test_jpeg_decode_and_probe() -> None:
    img = np.zeros((16, 24, 3), dtype=np.uint8)
    img[:] = (200, 128, 30)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=100, subsampling=0)
    assert E.probe(buf.getvalue()) == E.ImageHeader("jpeg", 24, 16, 3, 8)
    rgb, fmt = E.read_image(buf.getvalue())
    assert fmt == "jpeg"
    lo, hi = srgb_eotf((img - 1.5) / 255.0), srgb_eotf((img + 1.5) / 255.0)
    assert np.all((rgb >= lo) & (rgb <= hi))


def test_truncated_png_and_jpeg() -> None:
    img = np.random.default_rng(13).integers(0, 256, (32, 64, 3)).astype(np.uint8)
    for fmt in ("PNG", "JPEG"):
        buf = io.BytesIO()
        Image.fromarray(img).save(buf, format=fmt)
        data = buf.getvalue()
        with pytest.raises(InputError, match=f"cannot decode {fmt}"):
            E.read_image(data[: len(data) // 2])
        with pytest.raises(InputError, match=f"truncated {fmt}"):
            E.probe(data[:12])
