"""Tests for Radiance RGBE (relight.envmap.rgbe).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from relight import envmap as E
from relight.envmap import rgbe
from relight.errors import InputError


def rgbe_value(m: int, e: int) -> float:
    """Radiance colr_color: (m + 0.5) 2^(e - 136), black for e = 0."""
    return 0.0 if e == 0 else (m + 0.5) * 2.0 ** (e - 136)


def test_hdr_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    rgb = rng.random((24, 48, 3)) * 10.0 ** rng.uniform(-6, 6, (24, 48, 1))
    rgb[0, :10] = 0.0  # a run of black
    rgb[1] = 5.0  # a constant scanline
    path = tmp_path / "x.hdr"
    E.write_hdr(path, rgb)
    data = path.read_bytes()
    start = data.index(b"-Y 24 +X 48\n") + len(b"-Y 24 +X 48\n")
    assert data[start:start + 4] == bytes([2, 2, 0, 48])  # new-style RLE scanline header
    assert len(data) < start + 24 * 48 * 4  # RLE made it smaller than flat
    back, fmt = E.read_image(path)
    assert fmt == "hdr" and back.shape == rgb.shape
    assert E.read_envmap(path).source_format == "hdr"
    # RGBE keeps 8 mantissa bits under the pixel's largest channel: |error| <= max(r, g, b) / 256.
    bound = rgb.max(axis=-1, keepdims=True) / 256
    assert np.all(np.abs(back - rgb) <= bound * (1 + 1e-6))
    np.testing.assert_array_equal(back[0, :10], 0.0)


def test_hdr_flat_hand_built() -> None:
    pixels = [[(128, 64, 0, 129), (255, 255, 255, 120), (0, 0, 0, 0)],
              [(200, 100, 50, 140), (1, 2, 200, 100), (128, 128, 128, 128)]]
    body = bytes(v for row in pixels for px in row for v in px)
    data = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=2\n\n-Y 2 +X 3\n" + body
    assert E.probe(data) == E.ImageHeader("hdr", 3, 2, 3, 8)
    rgb, _ = E.read_image(data)
    expected = np.array([[[rgbe_value(m, px[3]) / 2 for m in px[:3]] for px in row] for row in pixels])
    np.testing.assert_allclose(rgb, expected, rtol=1e-6)


def test_hdr_rle_hand_built() -> None:
    # One 8-pixel scanline: R is a run of 8, G 8 literals, B a run of 5 then 3 literals, E a run of 8.
    g = [10, 20, 30, 40, 50, 60, 70, 80]
    scan = bytes([2, 2, 0, 8, 128 + 8, 200, 8, *g, 128 + 5, 100, 3, 1, 2, 3, 128 + 8, 130])
    data = b"#?RGBE\n\n-Y 1 +X 8\n" + scan
    rgb, _ = E.read_image(data)
    scale = 2.0 ** (130 - 136)
    expected = np.stack([np.full(8, 200.5), np.array(g) + 0.5, np.array([100] * 5 + [1, 2, 3]) + 0.5], -1) * scale
    np.testing.assert_allclose(rgb[0], expected, rtol=1e-6)


def test_hdr_reader_decodes_a_full_size_map() -> None:
    """A full-size (512 x 1024) RLE file decodes exactly: RGBE keeps 8 mantissa bits of the pixel's largest
    channel, so every channel is within 2^-8 of that maximum (the speed of this path belongs in bench/)."""
    rgb = np.random.default_rng(6).random((512, 1024, 3)) ** 4 * 100
    back, _ = E.read_image(rgbe.encode(rgb))
    assert back.shape == (512, 1024, 3)
    scale = rgb.max(axis=-1, keepdims=True)
    assert np.all(np.abs(back - rgb) <= 2.0**-8 * scale + 1e-30)


def test_hdr_bad_files() -> None:
    data = rgbe.encode(np.ones((16, 32, 3)))
    with pytest.raises(InputError, match=r"truncated Radiance HDR data at scanline \d+ of 16"):
        E.read_image(data[:-20])
    with pytest.raises(InputError, match="orientation"):
        E.read_image(b"#?RADIANCE\n\n+Y 2 +X 4\n" + bytes(32))
    with pytest.raises(InputError, match="FORMAT"):
        E.probe(b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 2 +X 4\n")
    with pytest.raises(InputError, match="truncated"):
        E.probe(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n")
    with pytest.raises(InputError, match="overruns"):
        E.read_image(b"#?RADIANCE\n\n-Y 1 +X 8\n" + bytes([2, 2, 0, 8, 128 + 9, 1]) + bytes(40))
    with pytest.raises(InputError, match="non-finite"):
        E.write_hdr("unused.hdr", np.full((2, 4, 3), np.nan))


def worst_case_rle(width: int, height: int, value: int = 128) -> bytes:
    """A valid RLE file whose every packet is a one-byte literal (2 input bytes per output byte): the most packets
    a file of this size can have. Every texel decodes to RGBE (value, value, value, value)."""
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, width)
    row = bytes([2, 2, width >> 8, width & 255]) + bytes([1, value]) * (4 * width)
    return head + row * height


def test_worst_case_rle_decodes_within_the_outputs_memory() -> None:
    """Issue 12: at the pixel limit such a file killed both workers (the gather plan held ~60 bytes per texel in
    Python lists). Decoding now writes each packet into the output: the traced peak stays under 40 bytes per
    texel (planar RGBE 4 + float32 RGB 12 + NumPy's float temporaries of rgbe_to_float, 12 each), independent of
    the packet count. The values are checked against the closed form (RGBE 128: mantissa 128.5/256 * 2^0)."""
    import tracemalloc

    width, height = 256, 64  # 65536 packets: tracemalloc makes each Python step slow
    data = worst_case_rle(width, height)
    tracemalloc.start()
    try:
        rgb = E.rgbe.decode(data)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 40 * width * height, peak / (width * height)
    np.testing.assert_array_equal(rgb, np.full((height, width, 3), (128 + 0.5) / 256.0, np.float32))
