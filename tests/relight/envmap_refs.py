"""Independent references for the relight.envmap tests (tests/relight/test_envmap_*.py).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import OpenEXR
from numpy.typing import NDArray

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
SAMPLES = ["city", "courtyard", "forest", "studio", "sunset"]
FloatArray = NDArray[np.float64]


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
    """Pixel-centre directions of an h x 2h map, from docs/conventions.md (three.js equirectUv, +Y up)."""
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
