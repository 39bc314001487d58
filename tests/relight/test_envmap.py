"""Tests for relight.envmap (and relight.hdr_rgbe): formats, validation, cube maps, resampling.

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import io
import logging
import struct
import time
import tracemalloc
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from numpy.typing import NDArray
from PIL import Image

from relight import envmap as E
from relight.errors import InputError

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
SAMPLES = ["city", "courtyard", "forest", "studio", "sunset"]
FloatArray = NDArray[np.float64]


# ------------------------------------------------------------------------------------------------------------------
# Independent reference helpers


def srgb_eotf(c: NDArray[np.floating]) -> FloatArray:
    """IEC 61966-2-1 sRGB decoding, written out again here."""
    c = np.asarray(c, dtype=np.float64)
    out = np.empty_like(c)
    low = c <= 0.04045
    out[low] = c[low] / 12.92
    out[~low] = ((c[~low] + 0.055) / 1.055) ** 2.4
    return out


def srgb_oetf(x: NDArray[np.floating]) -> FloatArray:
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    low = x <= 0.0031308
    out[low] = 12.92 * x[low]
    out[~low] = 1.055 * x[~low] ** (1 / 2.4) - 0.055
    return out


def latlong_dirs(h: int) -> FloatArray:
    """Pixel-centre directions of an h x 2h map, from FACTS.md (three.js equirectUv, +Y up)."""
    w = 2 * h
    elev = np.pi / 2 - (np.arange(h) + 0.5) * np.pi / h
    phi = ((np.arange(w) + 0.5) / w - 0.5) * 2 * np.pi
    el, ph = np.meshgrid(elev, phi, indexing="ij")
    return np.stack([np.cos(el) * np.cos(ph), np.sin(el), np.cos(el) * np.sin(ph)], axis=-1)


def row_solid_angles(h: int) -> FloatArray:
    w = 2 * h
    edges = np.arange(h + 1) * np.pi / h
    return (2 * np.pi / w) * (np.cos(edges[:-1]) - np.cos(edges[1:]))


def sphere_integral(latlong: NDArray[np.floating]) -> float:
    return float(np.sum(np.asarray(latlong, dtype=np.float64) * row_solid_angles(latlong.shape[0])[:, None, None]))


def gl_face_dirs(size: int) -> FloatArray:
    """OpenGL 4.6 table 8.19 inverted, re-typed: (6, S, S, 3) unit texel-centre directions."""
    g = (np.arange(size) + 0.5) / size * 2 - 1
    b, a = np.meshgrid(g, g, indexing="ij")  # b = 2t - 1 along rows, a = 2s - 1 along columns
    one = np.ones_like(a)
    faces = [(one, -b, -a), (-one, -b, a), (a, one, b), (a, -one, -b), (a, -b, one), (-a, -b, -one)]
    d = np.stack([np.stack(f, axis=-1) for f in faces])
    return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True), dtype=np.float64)


def texel_solid_angles(size: int) -> FloatArray:
    """Exact solid angle of each cube texel: the area-element integral atan2(xy, sqrt(x^2 + y^2 + 1))."""
    e = np.arange(size + 1) / size * 2 - 1

    def area(x: FloatArray, y: FloatArray) -> FloatArray:
        return np.arctan2(x * y, np.sqrt(x * x + y * y + 1))

    y0, x0 = np.meshgrid(e[:-1], e[:-1], indexing="ij")
    y1, x1 = np.meshgrid(e[1:], e[1:], indexing="ij")
    return np.broadcast_to(area(x0, y0) - area(x0, y1) - area(x1, y0) + area(x1, y1), (6, size, size))


def cube_integral(cube: NDArray[np.floating]) -> float:
    return float(np.sum(np.asarray(cube, dtype=np.float64) * texel_solid_angles(cube.shape[1])[..., None]))


def smooth_fn(d: FloatArray) -> FloatArray:
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([1 + 0.5 * x + 0.3 * y * y, 1 - 0.4 * x * z + 0.2 * y, 0.8 + 0.5 * np.exp(3 * (z - 1))], axis=-1)


def footprint_average(fn: Callable[[FloatArray], FloatArray], h: int, n: int = 8) -> FloatArray:
    """Solid-angle average of fn over each lat-long pixel, by direct equal-area supersampling (no cube)."""
    w = 2 * h
    z_edges = np.cos(np.arange(h + 1) * np.pi / h)
    frac = (np.arange(n) + 0.5) / n
    z = (z_edges[:-1, None] + np.diff(z_edges)[:, None] * frac).reshape(-1)
    phi = ((np.arange(w)[:, None] + frac).reshape(-1) / w - 0.5) * 2 * np.pi
    rho = np.sqrt(1 - z * z)[:, None]
    d = np.stack(np.broadcast_arrays(rho * np.cos(phi), z[:, None], rho * np.sin(phi)), axis=-1)
    v = fn(d)
    return np.asarray(v.reshape(h, n, w, n, -1).mean(axis=(1, 3)), dtype=np.float64)


def exr_bytes(channels: dict[str, NDArray[np.floating]], compression: int = OpenEXR.ZIP_COMPRESSION) -> bytes:
    buf = io.BytesIO()
    with OpenEXR.File({"compression": compression, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(buf)
    return buf.getvalue()


def rgb_exr_bytes(rgb: NDArray[np.floating]) -> bytes:
    a = np.asarray(rgb, dtype=np.float32)
    return exr_bytes({c: np.ascontiguousarray(a[..., i]) for i, c in enumerate("RGB")})


def crafted_exr_header(width: int, height: int) -> bytes:
    """A hand-written EXR header (OpenEXR File Layout) with no pixel data after it."""

    def attr(name: str, kind: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    return (b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
            + attr("channels", "chlist", chlist) + attr("compression", "compression", b"\0")
            + attr("dataWindow", "box2i", window) + attr("displayWindow", "box2i", window)
            + attr("lineOrder", "lineOrder", b"\0") + attr("pixelAspectRatio", "float", struct.pack("<f", 1))
            + attr("screenWindowCenter", "v2f", struct.pack("<2f", 0, 0))
            + attr("screenWindowWidth", "float", struct.pack("<f", 1)) + b"\0")


def png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png16_bytes(samples: NDArray[np.uint16], colour_type: int) -> bytes:
    """A 16-bit PNG (ISO/IEC 15948) whose rows cycle through all five filter types (encoded vectorised)."""
    h, w, c = samples.shape
    raw = samples.astype(">u2").view(np.uint8).reshape(h, w * c * 2).astype(np.int64)
    bpp = 2 * c
    left = np.zeros_like(raw)
    left[:, bpp:] = raw[:, :-bpp]
    up = np.zeros_like(raw)
    up[1:] = raw[:-1]
    upleft = np.zeros_like(raw)
    upleft[1:, bpp:] = raw[:-1, :-bpp]
    p = left + up - upleft
    pa, pb, pc = np.abs(p - left), np.abs(p - up), np.abs(p - upleft)
    paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, upleft))
    predictions = [np.zeros_like(raw), left, up, (left + up) // 2, paeth]
    ftype = np.arange(h) % 5
    pred = np.choose(ftype[:, None], predictions)
    rows = np.concatenate([ftype[:, None], (raw - pred) % 256], axis=1).astype(np.uint8)
    ihdr = struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", zlib.compress(rows.tobytes()))
            + png_chunk(b"IEND", b""))


# ------------------------------------------------------------------------------------------------------------------
# Sample maps


@pytest.mark.parametrize("name", SAMPLES)
def test_sample_exrs(name: str) -> None:
    path = DATA / f"{name}.exr"
    env = E.read_envmap(path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.parts[0].channels
        ref = np.stack([ch[c].pixels for c in "RGB"], axis=-1).astype(np.float32)
    assert env.pixels.shape == (512, 1024, 3) and env.pixels.dtype == np.float32
    assert (env.height, env.width, env.source_format, env.layout) == (512, 1024, "exr", "latlong")
    assert np.isfinite(env.pixels).all() and env.pixels.min() >= 0
    assert env.negatives_clamped == int(np.sum(ref < 0)) > 0
    assert -0.01 < env.min_negative == float(ref.min()) < 0
    np.testing.assert_array_equal(env.pixels, np.maximum(ref, 0))
    assert E.probe(path) == E.ImageHeader("exr", 1024, 512, 3, 32)
    if name == "city":
        assert env.pixels.max() > 1e4


def test_read_envmap_from_bytes_matches_path() -> None:
    path = DATA / "studio.exr"
    a = E.read_envmap(path)
    b = E.read_envmap(path.read_bytes())
    np.testing.assert_array_equal(a.pixels, b.pixels)


# ------------------------------------------------------------------------------------------------------------------
# EXR writing and reading


def test_exr_float_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(42)
    rgb = (rng.random((16, 32, 3)) * 10.0 ** rng.integers(-30, 5, (16, 32, 3))).astype(np.float32)
    rgb[0, 0] = [3.4e4, 1e-30, 0.0]
    path = tmp_path / "f.exr"
    E.write_exr(path, rgb, attributes={"relight:note": "hello"})
    back, fmt = E.read_image(path)
    assert fmt == "exr" and back.dtype == np.float32
    np.testing.assert_array_equal(back, rgb)
    with OpenEXR.File(str(path)) as f:  # independent reader
        assert f.header()["relight:note"] == "hello"
        assert f.parts[0].channels["RGB"].pixels.dtype == np.float32


def test_exr_half_round_trip_and_overflow_clamp(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    rng = np.random.default_rng(42)
    rgb = (rng.random((8, 16, 3)) * 100).astype(np.float32)
    rgb[0, 0] = [7e4, 1e9, np.inf]
    rgb[0, 1] = [-1e6, 65504.0, 65000.0]
    path = tmp_path / "h.exr"
    with caplog.at_level(logging.WARNING, logger="relight.envmap"):
        E.write_exr(path, rgb, half=True)
    assert "4 values" in caplog.text
    with OpenEXR.File(str(path), separate_channels=True) as f:
        assert f.parts[0].channels["R"].pixels.dtype == np.float16
    back, _ = E.read_image(path)
    assert np.isfinite(back).all()
    np.testing.assert_array_equal(back[0, 0], [65504.0, 65504.0, 65504.0])
    np.testing.assert_array_equal(back[0, 1, :2], [-65504.0, 65504.0])
    assert back[0, 1, 2] == np.float16(65000.0) == 64992.0  # in range: ordinary rounding to half
    rest = np.s_[1:]
    np.testing.assert_allclose(back[rest], rgb[rest], rtol=2.0**-11, atol=2.0**-24)


def test_to_half_safe() -> None:
    half, n = E.to_half_safe(np.array([1.0, 65504.0, 65505.0, 1e30, -np.inf, np.nan], dtype=np.float32))
    assert half.dtype == np.float16 and n == 3
    assert half[2] == half[3] == 65504.0 and half[4] == -65504.0 and np.isnan(half[5])


@pytest.mark.parametrize("compression", ["none", "rle", "zips", "zip", "piz"])
def test_exr_lossless_compressions(tmp_path: Path, compression: str) -> None:
    rgb = np.random.default_rng(1).random((20, 40, 3)).astype(np.float32)
    E.write_exr(tmp_path / "c.exr", rgb, compression=compression)
    np.testing.assert_array_equal(E.read_image(tmp_path / "c.exr")[0], rgb)


@pytest.mark.parametrize("compression", ["pxr24", "dwaa", "dwab", "b44"])
def test_exr_lossy_compressions(tmp_path: Path, compression: str) -> None:
    rgb = (1 + np.random.default_rng(1).random((32, 64, 3))).astype(np.float32)
    E.write_exr(tmp_path / "c.exr", rgb, compression=compression, half=True)
    np.testing.assert_allclose(E.read_image(tmp_path / "c.exr")[0], rgb, rtol=0.05)


def test_exr_rgba_grey_multipart_and_single_layer() -> None:
    rng = np.random.default_rng(3)
    a, b, c, alpha = (rng.random((4, 8)).astype(np.float32) for _ in range(4))
    rgba = exr_bytes({"R": a, "G": b, "B": c, "A": alpha})
    np.testing.assert_array_equal(E.read_image(rgba)[0], np.stack([a, b, c], -1))
    assert E.probe(rgba).channels == 4
    grey = exr_bytes({"Y": a.astype(np.float16)})
    np.testing.assert_array_equal(E.read_image(grey)[0], np.stack([a.astype(np.float16).astype(np.float32)] * 3, -1))
    layer = exr_bytes({"beauty.R": a, "beauty.G": b, "beauty.B": c})
    np.testing.assert_array_equal(E.read_image(layer)[0], np.stack([a, b, c], -1))
    parts = [OpenEXR.Part({"type": OpenEXR.scanlineimage}, {"R": a, "G": b, "B": c}, "first"),
             OpenEXR.Part({"type": OpenEXR.scanlineimage}, {"R": c, "G": c, "B": c}, "second")]
    buf = io.BytesIO()
    with OpenEXR.File(parts) as f:
        f.write(buf)
    np.testing.assert_array_equal(E.read_image(buf.getvalue())[0], np.stack([a, b, c], -1))


def test_exr_layers_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    layers = {"diffuse": rng.random((6, 12, 3)).astype(np.float32),
              "spec.l2": (rng.random((6, 12, 3)) * 1e5).astype(np.float32)}
    attrs = {"relight:spec": '{"kind": "phong", "s": 64}', "relight:version": "1"}
    path = tmp_path / "layers.exr"
    E.write_exr_layers(path, layers, attributes=attrs)
    with OpenEXR.File(str(path), separate_channels=True) as f:  # the channel names, independently
        assert set(f.parts[0].channels) == {f"{n}.{c}" for n in layers for c in "RGB"}
    back, back_attrs = E.read_exr_layers(path)
    assert set(back) == set(layers)
    for name in layers:
        np.testing.assert_array_equal(back[name], layers[name])
    assert back_attrs == attrs
    E.write_exr_layers(path, {"": layers["diffuse"], **layers}, half=True)
    back, _ = E.read_exr_layers(path)
    assert set(back) == {"", "diffuse", "spec.l2"}
    assert back["spec.l2"].max() == 65504.0
    np.testing.assert_allclose(back["diffuse"], layers["diffuse"], rtol=2.0**-11, atol=2.0**-24)


def test_exr_writer_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="reserved"):
        E.write_exr(tmp_path / "x.exr", np.zeros((2, 4, 3)), attributes={"channels": "x"})
    with pytest.raises(InputError, match=r"\(H, W, 3\)"):
        E.write_exr(tmp_path / "x.exr", np.zeros((2, 4)))
    with pytest.raises(InputError, match="compression"):
        E.write_exr(tmp_path / "x.exr", np.zeros((2, 4, 3)), compression="lzw")


# ------------------------------------------------------------------------------------------------------------------
# Radiance HDR


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


def test_hdr_reader_is_fast() -> None:
    rgb = np.random.default_rng(6).random((512, 1024, 3)) ** 4 * 100
    from relight.envmap import rgbe as hdr_rgbe

    data = hdr_rgbe.encode(rgb)
    t0 = time.perf_counter()
    back, _ = E.read_image(data)
    assert time.perf_counter() - t0 < 1.0
    assert back.shape == (512, 1024, 3)


def test_hdr_bad_files() -> None:
    from relight.envmap import rgbe as hdr_rgbe

    data = hdr_rgbe.encode(np.ones((16, 32, 3)))
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


# ------------------------------------------------------------------------------------------------------------------
# PNG / JPEG


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


# ------------------------------------------------------------------------------------------------------------------
# Cube maps


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


# ------------------------------------------------------------------------------------------------------------------
# Lat-long resampling


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


# ------------------------------------------------------------------------------------------------------------------
# Bad input


def test_truncated_exr() -> None:
    data = (DATA / "studio.exr").read_bytes()
    with pytest.raises(InputError, match="EXR"):
        E.read_envmap(data[: len(data) // 2])
    with pytest.raises(InputError, match="truncated EXR"):
        E.probe(data[:100])


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


def test_wrong_magic_and_empty(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"unrecognised image format .*OpenEXR.*Radiance.*PNG.*JPEG"):
        E.probe(b"GIF89a" + bytes(100))
    with pytest.raises(InputError, match="empty file"):
        E.read_envmap(b"")
    with pytest.raises(InputError, match="cannot read"):
        E.read_envmap(tmp_path / "missing.exr")


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


def test_zero_size_images() -> None:
    with pytest.raises(InputError, match="empty EXR image"):
        E.probe(crafted_exr_header(0, 0))
    with pytest.raises(InputError, match="empty Radiance HDR image"):
        E.probe(b"#?RADIANCE\n\n-Y 0 +X 0\n")
    with pytest.raises(InputError, match="empty or unsupported PNG image"):  # a complete file, zero width
        E.probe(b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", 0, 10, 8, 2, 0, 0, 0))
                + png_chunk(b"IDAT", zlib.compress(b"")) + png_chunk(b"IEND", b""))
    with pytest.raises(InputError, match="truncated PNG file"):  # the file ends after IHDR
        E.probe(b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", 0, 10, 8, 2, 0, 0, 0)))
    with pytest.raises(InputError, match="cannot be empty|width"):
        E.envmap_from_array(np.zeros((0, 0, 3)))


@pytest.mark.parametrize("header", [crafted_exr_header(100_000, 100_000),
                                    b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n"])
def test_huge_header_rejected_without_allocation(header: bytes) -> None:
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        hdr = E.probe(header)
        assert (hdr.width, hdr.height) == (100_000, 100_000)
        with pytest.raises(InputError, match="100000 x 100000 = 10000000000 pixels, more than the limit of 8388608"):
            E.read_envmap(header, max_pixels=4096 * 2048)
        with pytest.raises(InputError, match="more than the limit"):
            E.read_envmap(header)  # the hard limit applies without max_pixels too
        elapsed = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert elapsed < 0.5
    assert peak < 1 << 20


def test_probe_reads_only_the_header_of_a_file(tmp_path: Path) -> None:
    path = tmp_path / "huge.exr"
    path.write_bytes(crafted_exr_header(100_000, 100_000) + bytes(1 << 20))
    assert E.probe(path).pixels == 10**10


def test_envmap_from_array_clamps_and_counts() -> None:
    rgb = np.ones((4, 8, 3))
    rgb[1, 2] = [-0.5, -0.25, 0.5]
    env = E.envmap_from_array(rgb)
    assert (env.negatives_clamped, env.min_negative, env.source_format) == (2, -0.5, "array")
    assert env.pixels.min() == 0.0 and rgb.min() == -0.5  # the caller's array is untouched


def test_cube_face_dirs_match_gl_table() -> None:
    np.testing.assert_allclose(E.cube_face_dirs(5), gl_face_dirs(5), atol=1e-15)
