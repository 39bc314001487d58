"""Environment-map input and output: decode, validate, convert to the project's lat-long layout, write.

Formats
-------
* **OpenEXR** through the OpenEXR 3.x Python bindings (``OpenEXR.File``): every compression the library
  supports (the samples are DWAB), half/float/uint channels, RGB, RGBA (A dropped) or Y (grey, replicated);
  multi-part files give part 0. The header is parsed here first (OpenEXR file layout, "OpenEXR File Layout",
  Kainz 2013) so that the size is known, and limited, before the library allocates anything.
* **Radiance RGBE** ``.hdr``: :mod:`relight.hdr_rgbe` (own reader and writer).
* **PNG / JPEG** through Pillow, 8 or 16 bits, decoded from sRGB to linear with the exact piecewise sRGB
  EOTF (IEC 61966-2-1:1999, section 5.2); ICC profiles and PNG ``gAMA`` are ignored (sRGB is assumed).

Every decoder returns linear float32 RGB, shape (H, W, 3), row 0 at the top of the image.

Environment maps (:func:`read_envmap`) are lat-long maps in the project convention (:mod:`relight.conventions`,
three.js ``equirectUv``, +Y up, W = 2H), or cube maps that are resampled to one (:func:`cube_to_latlong`).
Non-finite pixels are rejected; negative texels (lossy compression leaves some) are clamped to 0 and counted.

Upload safety (``shared/FACTS.md``): call :func:`probe` (header only) and pass ``max_pixels`` before decoding
anything untrusted; EXR channels are read separately (``separate_channels=True``), never combined by the
bindings. Run untrusted decodes in a worker process under memory and time limits.
"""

from __future__ import annotations

import io
import logging
import math
import os
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np
import OpenEXR
from numpy.typing import NDArray
from PIL import Image, ImageFile

from relight import hdr_rgbe
from relight.conventions import check_latlong_shape
from relight.errors import InputError

log = logging.getLogger(__name__)

F32 = NDArray[np.float32]
Source = str | os.PathLike[str] | bytes | bytearray | memoryview

#: Formats :func:`probe` recognises (the ``format`` of an :class:`ImageHeader`).
FORMATS: Final = ("exr", "hdr", "png", "jpeg")
_ACCEPTED = "OpenEXR (.exr), Radiance RGBE (.hdr), PNG or JPEG"

#: Pixel limit applied even when a caller passes ``max_pixels=None``: 2^28 (16384 x 16384), 3 GiB as float32 RGB.
#: A crafted header can claim any size; nothing larger is handed to a decoder.
HARD_MAX_PIXELS: Final = 1 << 28

#: Largest finite IEEE 754 binary16 value.
HALF_MAX: Final = 65504.0

#: Cube-map face order (OpenGL: GL_TEXTURE_CUBE_MAP_POSITIVE_X + i).
FACE_NAMES: Final = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
#: Cube-map layouts :func:`read_envmap` and :func:`cube_faces_from_image` know, with their aspect (W, H) in faces.
CUBE_LAYOUTS: Final = {"strip-h": (6, 1), "strip-v": (1, 6), "cross-h": (4, 3), "cross-v": (3, 4)}
LAYOUTS: Final = ("auto", "latlong", *CUBE_LAYOUTS)

_EXR_MAGIC = b"\x76\x2f\x31\x01"
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_JPEG_MAGIC = b"\xff\xd8\xff"
#: Bytes read first when probing a file; more is read (up to _PROBE_MAX) only if the header is longer.
_PROBE_FIRST = 1 << 16
_PROBE_MAX = 1 << 26


# ----------------------------------------------------------------------------------------------------------------
# Data types


@dataclass(frozen=True)
class ImageHeader:
    """What a file's header says, read without decoding pixels (see :func:`probe`)."""

    format: str  # "exr" | "hdr" | "png" | "jpeg"
    width: int
    height: int
    channels: int  # channels stored in the file (EXR: all channels of part 0)
    bit_depth: int = 8  # bits per channel (EXR: 16 or 32; HDR: 8-bit mantissas with a shared exponent)

    @property
    def pixels(self) -> int:
        return self.width * self.height


@dataclass(frozen=True)
class EnvMap:
    """A validated lat-long environment map.

    ``pixels`` is (H, W, 3) float32 linear RGB in the :mod:`relight.conventions` layout, W = 2H, all finite and
    non-negative. ``source_format`` is the file codec ("exr", "hdr", "png", "jpeg"), ``"cube"`` for a map made
    from in-memory cube faces (:func:`envmap_from_cube`) or ``"array"`` for one made from an array;
    ``layout`` says whether the source was a lat-long map or which cube-map layout was resampled.
    ``negatives_clamped`` counts the channel values below 0 that were set to 0, ``min_negative`` is the most
    negative of them (0.0 if none).
    """

    pixels: F32 = field(repr=False)
    source_format: str
    negatives_clamped: int = 0
    min_negative: float = 0.0
    layout: str = "latlong"

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])


# ----------------------------------------------------------------------------------------------------------------
# Sources and header probing


class _NeedMore(Exception):
    """Internal: a header parser ran past the end of the bytes it was given."""


def _read_all(src: Source) -> bytes:
    if isinstance(src, bytes | bytearray | memoryview):
        return bytes(src)
    path = os.fspath(src)
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise InputError(f"cannot read {path!r}: {exc.strerror or exc}") from exc


def _check_max_pixels(hdr: ImageHeader, max_pixels: int | None) -> None:
    limit = HARD_MAX_PIXELS if max_pixels is None else min(max_pixels, HARD_MAX_PIXELS)
    if hdr.pixels > limit:
        raise InputError(f"image is {hdr.width} x {hdr.height} = {hdr.pixels} pixels, more than the limit of "
                         f"{limit} pixels")


def probe(data: Source) -> ImageHeader:
    """Format, size and channel count from the header only: no pixel is decoded, nothing big is allocated.

    ``data`` is the file's bytes or a path (only the first bytes of the file are read, more only when the
    header is longer). Raises :class:`InputError` for an empty file, an unknown magic number (the message lists
    the accepted formats), a truncated header or a zero-size image.
    """
    if isinstance(data, bytes | bytearray | memoryview):
        return _probe_bytes(bytes(data), complete=True)
    path = os.fspath(data)
    try:
        with open(path, "rb") as fh:
            size = _PROBE_FIRST
            buf = fh.read(size)
            while True:
                try:
                    return _probe_bytes(buf, complete=len(buf) < size)
                except _NeedMore:
                    if size >= _PROBE_MAX:
                        raise InputError(f"{path}: image header longer than {_PROBE_MAX} bytes") from None
                    more = fh.read(size)
                    size *= 2
                    buf += more
    except OSError as exc:
        raise InputError(f"cannot read {path!r}: {exc.strerror or exc}") from exc


def _probe_bytes(buf: bytes, *, complete: bool) -> ImageHeader:
    try:
        if not buf:
            raise InputError("empty file (0 bytes): not an image")
        if buf.startswith(_EXR_MAGIC):
            return _exr_header(buf).image
        if buf.startswith(b"#?"):
            try:
                h = hdr_rgbe.parse_header(buf, complete=complete)
            except hdr_rgbe.NeedMoreData:
                raise _NeedMore from None
            return ImageHeader("hdr", h.width, h.height, 3, 8)
        if buf.startswith(_PNG_MAGIC):
            return _png_header(buf)[0]
        if buf.startswith(_JPEG_MAGIC):
            return _jpeg_header(buf)
        if len(buf) < 8 and not complete:
            raise _NeedMore
        raise InputError(f"unrecognised image format (file starts with {buf[:8].hex(' ')}): accepted formats "
                         f"are {_ACCEPTED}")
    except _NeedMore:
        if complete:
            kind = "EXR" if buf.startswith(_EXR_MAGIC) else "PNG" if buf.startswith(_PNG_MAGIC) else (
                "JPEG" if buf.startswith(_JPEG_MAGIC) else "image")
            raise InputError(f"truncated {kind} file: the header ends after {len(buf)} bytes") from None
        raise


class _Cursor:
    """Bounds-checked little reader over a bytes buffer; running off the end raises :class:`_NeedMore`."""

    def __init__(self, buf: bytes, pos: int = 0) -> None:
        self.buf = buf
        self.pos = pos

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.buf):
            raise _NeedMore
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def cstr(self, limit: int = 256) -> bytes:
        end = self.buf.find(b"\0", self.pos, self.pos + limit + 1)
        if end < 0:
            if len(self.buf) - self.pos <= limit:
                raise _NeedMore
            raise InputError(f"corrupt EXR header: a name longer than {limit} bytes at offset {self.pos}")
        out = self.buf[self.pos:end]
        self.pos = end + 1
        return out

    def i32(self) -> int:
        return int(struct.unpack("<i", self.take(4))[0])


@dataclass(frozen=True)
class _ExrChannel:
    name: str
    pixel_type: int  # 0 UINT, 1 HALF, 2 FLOAT
    x_sampling: int
    y_sampling: int


@dataclass(frozen=True)
class _ExrInfo:
    image: ImageHeader
    channels: tuple[_ExrChannel, ...]
    part_type: str


def _exr_header(buf: bytes) -> _ExrInfo:
    """Parse the magic, version and the first part's header (OpenEXR File Layout, components 1-3)."""
    cur = _Cursor(buf, 4)
    version = cur.i32()
    if version & 0xFF != 2:
        raise InputError(f"unsupported EXR version {version & 0xFF} (only version 2 exists)")
    multipart = bool(version & 0x1000)
    part_type = "deepscanline" if version & 0x800 else "tiledimage" if version & 0x200 else "scanlineimage"
    channels: tuple[_ExrChannel, ...] | None = None
    window: tuple[int, int, int, int] | None = None
    while True:
        name = cur.cstr()
        if not name:
            break
        type_name = cur.cstr()
        size = cur.i32()
        if size < 0:
            raise InputError(f"corrupt EXR header: attribute {name.decode('latin-1')!r} has size {size}")
        value = cur.take(size)
        if name == b"channels" and type_name == b"chlist":
            channels = _exr_chlist(value)
        elif name == b"dataWindow" and type_name == b"box2i" and size == 16:
            xmin, ymin, xmax, ymax = struct.unpack("<4i", value)
            window = (xmin, ymin, xmax, ymax)
        elif name == b"type" and type_name == b"string" and multipart:
            part_type = value.decode("latin-1")
    if channels is None or window is None:
        missing = "channels" if channels is None else "dataWindow"
        raise InputError(f"corrupt EXR header: the required attribute {missing!r} is missing")
    xmin, ymin, xmax, ymax = window
    width, height = xmax - xmin + 1, ymax - ymin + 1
    if width <= 0 or height <= 0:
        raise InputError(f"empty EXR image: data window {window} is {max(width, 0)} x {max(height, 0)}")
    if not channels:
        raise InputError("EXR image has no channels")
    bits = max(32 if c.pixel_type != 1 else 16 for c in channels)
    image = ImageHeader("exr", width, height, len(channels), bits)
    return _ExrInfo(image, channels, part_type)


def _exr_chlist(value: bytes) -> tuple[_ExrChannel, ...]:
    cur = _Cursor(value)
    out = []
    try:
        while True:
            name = cur.cstr()
            if not name:
                break
            pixel_type = cur.i32()
            cur.take(4)  # pLinear + 3 reserved bytes
            xs, ys = cur.i32(), cur.i32()
            if pixel_type not in (0, 1, 2):
                raise InputError(f"corrupt EXR header: channel {name.decode('latin-1')!r} has pixel type "
                                 f"{pixel_type}")
            out.append(_ExrChannel(name.decode("utf-8", "replace"), pixel_type, xs, ys))
    except _NeedMore:
        raise InputError("corrupt EXR header: the channel list is cut short") from None
    return tuple(out)


_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}


def _png_header(buf: bytes) -> tuple[ImageHeader, int]:
    """IHDR (PNG spec, ISO/IEC 15948 section 11.2.2). Returns the header and the PNG colour type."""
    cur = _Cursor(buf, 8)
    length = struct.unpack(">I", cur.take(4))[0]
    if cur.take(4) != b"IHDR" or length != 13:
        raise InputError("corrupt PNG file: the first chunk is not a 13-byte IHDR")
    width, height, depth, colour = struct.unpack(">IIBB", cur.take(10))
    if width == 0 or height == 0:
        raise InputError(f"empty PNG image: {width} x {height}")
    if colour not in _PNG_CHANNELS:
        raise InputError(f"corrupt PNG file: colour type {colour}")
    return ImageHeader("png", width, height, _PNG_CHANNELS[colour], depth), colour


def _jpeg_header(buf: bytes) -> ImageHeader:
    """Walk JPEG marker segments to the first SOFn (ITU-T T.81, B.2.2)."""
    cur = _Cursor(buf, 2)
    while True:
        b = cur.take(1)[0]
        if b != 0xFF:
            raise InputError(f"corrupt JPEG file: expected a marker at offset {cur.pos - 1}")
        marker = cur.take(1)[0]
        while marker == 0xFF:  # fill bytes
            marker = cur.take(1)[0]
        if marker in (0x01, *range(0xD0, 0xD8)):
            continue
        if marker in (0xD9, 0xDA):
            raise InputError("corrupt JPEG file: no frame header (SOF) before the image data")
        length = struct.unpack(">H", cur.take(2))[0]
        if length < 2:
            raise InputError(f"corrupt JPEG file: segment length {length} at offset {cur.pos - 2}")
        seg = cur.take(length - 2)
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if len(seg) < 6:
                raise InputError("corrupt JPEG file: frame header too short")
            depth, height, width, comps = struct.unpack(">BHHB", seg[:6])
            if width == 0 or height == 0:
                raise InputError(f"empty JPEG image: {width} x {height}")
            return ImageHeader("jpeg", width, height, comps, depth)


# ----------------------------------------------------------------------------------------------------------------
# Decoding


def srgb_to_linear(c: NDArray[np.floating]) -> NDArray[np.float64]:
    """sRGB EOTF, IEC 61966-2-1:1999 eq. (5.2): ``c / 12.92`` for ``c <= 0.04045``, else ``((c+0.055)/1.055)^2.4``."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: NDArray[np.floating]) -> NDArray[np.float64]:
    """sRGB OETF, IEC 61966-2-1:1999 eq. (5.1) inverted: ``12.92 x`` for ``x <= 0.0031308``, else
    ``1.055 x^(1/2.4) - 0.055``."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)


def read_image(src: Source, *, max_pixels: int | None = None) -> tuple[F32, str]:
    """Decode an EXR, HDR, PNG or JPEG image to raw (H, W, 3) float32 linear RGB and its format name.

    No layout or value checks (used for lat-long maps and cube-map images alike); the size is checked
    against ``max_pixels`` from the header before any pixel is decoded.
    """
    hdr = probe(src)
    _check_max_pixels(hdr, max_pixels)
    return _decode(src, hdr), hdr.format


def _decode(src: Source, hdr: ImageHeader) -> F32:
    buf = _read_all(src)
    if _probe_bytes(buf, complete=True) != hdr:  # the checked header must be the one decoded
        raise InputError(f"{src if isinstance(src, str) else 'the file'} changed while it was being read")
    if hdr.format == "exr":
        rgb = _decode_exr(buf)
    elif hdr.format == "hdr":
        rgb = hdr_rgbe.decode(buf, hdr_rgbe.parse_header(buf))
    else:
        rgb = _decode_pillow(buf, hdr)
    if rgb.shape != (hdr.height, hdr.width, 3):
        raise InputError(f"decoded image has shape {rgb.shape}, but its header says {hdr.width} x {hdr.height}")
    return rgb


def _open_exr(buf: bytes) -> tuple[_ExrInfo, dict[str, NDArray[Any]], dict[str, Any]]:
    """Read part 0 of an EXR: the parsed header, channel arrays by name and the bindings' header dict."""
    info = _exr_header(buf)
    if info.part_type.startswith("deep"):
        raise InputError(f"deep EXR images ({info.part_type}) are not supported")
    for ch in info.channels:
        if ch.x_sampling != 1 or ch.y_sampling != 1:
            raise InputError(f"subsampled EXR channel {ch.name!r} ({ch.x_sampling} x {ch.y_sampling}) is not "
                             "supported")
    try:
        # Third-party decoder boundary: any failure (truncation, corrupt chunk, unsupported feature) is bad input.
        with OpenEXR.File(io.BytesIO(buf), separate_channels=True) as exr:
            part = exr.parts[0]
            pixels = {name: np.asarray(ch.pixels) for name, ch in part.channels.items()}
            header = dict(part.header)
    except Exception as exc:
        raise InputError(f"cannot decode EXR file: {type(exc).__name__}: {exc}".splitlines()[0]) from exc
    shape = (info.image.height, info.image.width)
    for name, arr in pixels.items():
        if arr.shape != shape:
            raise InputError(f"cannot decode EXR file: channel {name!r} has shape {arr.shape}, expected {shape}")
    if set(pixels) != {c.name for c in info.channels}:
        raise InputError("cannot decode EXR file: channels decoded do not match the header (truncated file?)")
    return info, pixels, header


def _decode_exr(buf: bytes) -> F32:
    _, ch, _ = _open_exr(buf)
    names = set(ch)
    if {"R", "G", "B"} <= names:
        planes = [ch["R"], ch["G"], ch["B"]]
    elif "Y" in names and not names & {"RY", "BY", "R", "G", "B"}:
        planes = [ch["Y"]] * 3
    else:
        groups = _exr_rgb_groups(names)
        if len(groups) != 1:
            raise InputError(f"EXR file has no single RGB, RGBA or Y image: channels are {sorted(names)}")
        p = groups[0]
        planes = [ch[p + "R"], ch[p + "G"], ch[p + "B"]]
    return np.stack([np.asarray(x, dtype=np.float32) for x in planes], axis=-1)


def _exr_rgb_groups(names: set[str]) -> list[str]:
    """Channel-name prefixes (``"layer."``, or ``""``) that have R, G and B channels."""
    prefixes = {n[: len(n) - 1] for n in names if n.endswith(("R", "G", "B")) and (len(n) == 1 or n[-2] == ".")}
    return sorted(p for p in prefixes if all(p + c in names for c in "RGB"))


def _decode_pillow(buf: bytes, hdr: ImageHeader) -> F32:
    """8/16-bit PNG and JPEG through Pillow, then the sRGB EOTF."""
    try:
        # Third-party decoder boundary: any failure (truncation, corrupt data, bomb check) is bad input.
        with Image.open(io.BytesIO(buf)) as im:
            if hdr.format == "png" and hdr.bit_depth == 16 and im.mode in ("RGB", "RGBA"):
                value = _png16_rgb(buf, im)
            elif im.mode.startswith("I"):  # 16-bit grey PNG (Pillow mode I;16)
                grey = np.asarray(im, dtype=np.float64) / 65535.0
                value = np.repeat(grey[..., None], 3, axis=-1)
            else:
                value = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except InputError:
        raise
    except Exception as exc:
        kind = hdr.format.upper()
        raise InputError(f"cannot decode {kind} file: {type(exc).__name__}: {exc}".splitlines()[0]) from exc
    return srgb_to_linear(value).astype(np.float32)


def _png16_rgb(buf: bytes, im: ImageFile.ImageFile) -> NDArray[np.float64]:
    """16-bit colour PNG at full precision.

    Pillow has no 16-bit RGB mode: it unfilters the data (PNG filters work on bytes, with a 6- or 8-byte pixel
    stride) and then keeps only the high byte of each sample. Decoding the same tile a second time with the
    little-endian raw mode keeps the other (low) byte instead, so ``value = 256 hi + lo`` exactly. Grey + alpha
    (Pillow mode RGBA, raw mode ``LA;16B``) is decoded as plain 8-bit RGBA, whose four bytes are L and A.
    """
    tile = im.tile[0]
    rawmode = tile.args if isinstance(tile.args, str) else tile.args[0] if tile.args else ""

    def with_rawmode(mode: str) -> NDArray[np.uint16]:
        im2 = Image.open(io.BytesIO(buf))
        t = im2.tile[0]
        args = mode if isinstance(t.args, str) or not t.args else (mode, *t.args[1:])
        im2.tile = [t._replace(args=args)]
        return np.asarray(im2, dtype=np.uint16)

    if rawmode == "LA;16B":
        b = with_rawmode("RGBA")
        grey = (b[..., 0] * 256 + b[..., 1]).astype(np.float64) / 65535.0
        return np.repeat(grey[..., None], 3, axis=-1)
    if rawmode not in ("RGB;16B", "RGBA;16B"):
        raise InputError(f"unsupported 16-bit PNG raw mode {rawmode!r}")
    hi = np.asarray(im, dtype=np.uint16)
    lo = with_rawmode(rawmode.replace(";16B", ";16L"))
    return (hi[..., :3] * 256 + lo[..., :3]).astype(np.float64) / 65535.0


# ----------------------------------------------------------------------------------------------------------------
# Validation and environment maps


def _validate(rgb: NDArray[np.floating], where: str = "") -> tuple[F32, int, float]:
    """Reject non-finite values (count and first position); clamp negatives to 0 and count them."""
    arr = np.array(rgb, dtype=np.float32)  # a copy: clamping never touches the caller's array
    finite = np.isfinite(arr)
    if not finite.all():
        bad = ~finite
        first = np.unravel_index(int(np.argmax(bad)), bad.shape)
        raise InputError(f"{int(bad.sum())} non-finite pixel values (NaN/Inf), first at {where}row {first[-3]}, "
                         f"column {first[-2]}")
    neg = arr < 0
    count = int(neg.sum())
    min_negative = float(arr.min()) if count else 0.0
    np.maximum(arr, np.float32(0.0), out=arr)
    return arr, count, min_negative


def envmap_from_array(rgb: NDArray[np.floating], *, source_format: str = "array") -> EnvMap:
    """Validate an in-memory (H, 2H, 3) lat-long map into an :class:`EnvMap` (same checks as :func:`read_envmap`)."""
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise InputError(f"an environment map must have shape (H, W, 3), got {arr.shape}")
    try:
        check_latlong_shape(arr.shape)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    pixels, count, mn = _validate(arr)
    return EnvMap(pixels, source_format, count, mn)


def envmap_from_cube(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating], height: int | None = None,
                     *, source_format: str = "cube") -> EnvMap:
    """Validate in-memory cube faces (see :func:`cube_to_latlong`) and resample them to an :class:`EnvMap`.

    ``height`` defaults to twice the face size.
    """
    cube = _faces_array(faces)
    if cube.shape[-1] != 3:
        raise InputError(f"cube faces must have 3 channels, got shape {cube.shape}")
    return _cube_envmap(cube, 2 * cube.shape[1] if height is None else height, source_format, "cube")


def _cube_envmap(cube: NDArray[np.float32], height: int, source_format: str, layout: str) -> EnvMap:
    """Validate each face (positions reported per face), clamp negatives, resample to lat-long."""
    count, mn = 0, 0.0
    checked = []
    for i, name in enumerate(FACE_NAMES):
        face, c, m = _validate(cube[i], f"face {name} ")
        checked.append(face)
        count += c
        mn = min(mn, m)
    return EnvMap(cube_to_latlong(np.stack(checked), height), source_format, count, mn, layout)


def read_envmap(src: Source, *, max_pixels: int | None = None, layout: str = "auto") -> EnvMap:
    """Read and validate an environment map from a file path or its bytes.

    ``layout``: ``"latlong"`` (W = 2H), a cube-map layout (see :func:`cube_faces_from_image`: ``"strip-h"`` 6:1,
    ``"strip-v"`` 1:6, ``"cross-h"`` 4:3, ``"cross-v"`` 3:4), or ``"auto"`` to choose from the aspect ratio.
    Cube maps are resampled to a lat-long map of height 2 x face size (:func:`cube_to_latlong`).
    ``max_pixels`` limits the file's pixel count; it is checked from the header before decoding (and
    :data:`HARD_MAX_PIXELS` always applies).
    """
    if layout not in LAYOUTS:
        raise InputError(f"unknown layout {layout!r}: expected one of {', '.join(LAYOUTS)}")
    hdr = probe(src)
    _check_max_pixels(hdr, max_pixels)
    w, h = hdr.width, hdr.height
    if layout == "auto":
        layout = "latlong" if w == 2 * h else next(
            (name for name, (a, b) in CUBE_LAYOUTS.items() if w * b == h * a and w % a == 0), "")
        if not layout:
            raise InputError(f"image is {w} x {h}: an environment map must be a lat-long map with width = 2 x "
                             "height, or a cube map (6:1 or 1:6 strip, 4:3 or 3:4 cross)")
    elif layout == "latlong" and w != 2 * h:
        raise InputError(f"image is {w} x {h}: a lat-long map must have width = 2 x height")
    rgb, fmt = _decode(src, hdr), hdr.format
    if layout == "latlong":
        pixels, count, mn = _validate(rgb)
        return EnvMap(pixels, fmt, count, mn)
    cube = cube_faces_from_image(rgb, layout)
    return _cube_envmap(cube, 2 * cube.shape[1], fmt, layout)


# ----------------------------------------------------------------------------------------------------------------
# EXR writing and layered files

_COMPRESSIONS: Final = {
    "none": "NO_COMPRESSION", "rle": "RLE_COMPRESSION", "zips": "ZIPS_COMPRESSION", "zip": "ZIP_COMPRESSION",
    "piz": "PIZ_COMPRESSION", "pxr24": "PXR24_COMPRESSION", "b44": "B44_COMPRESSION", "b44a": "B44A_COMPRESSION",
    "dwaa": "DWAA_COMPRESSION", "dwab": "DWAB_COMPRESSION", "zstd": "ZSTD_COMPRESSION",
}
#: Header attributes the writer sets itself (and the library's structural ones); not accepted in ``attributes``.
_RESERVED_ATTRIBUTES: Final = frozenset({
    "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio", "screenWindowCenter",
    "screenWindowWidth", "type", "tiles", "name", "version", "chunkCount", "view",
})


def to_half_safe(arr: NDArray[np.floating]) -> tuple[NDArray[np.float16], int]:
    """Convert to float16 without overflow: values beyond +-65504 (the largest finite half, IEEE 754 binary16)
    are clamped to +-65504 instead of becoming infinite. Returns the half array and how many values were clamped.
    NaN stays NaN.
    """
    a = np.asarray(arr, dtype=np.float32)
    over = np.abs(a) > HALF_MAX  # NaN compares False
    n = int(over.sum())
    if n:
        a = np.clip(a, -HALF_MAX, HALF_MAX)
    return a.astype(np.float16), n


def _rgb_planes(rgb: NDArray[np.floating], what: str) -> NDArray[np.floating]:
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[-1] != 3 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{what} must have shape (H, W, 3) with H, W > 0, got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.floating) and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{what} must be a numeric array, got dtype {arr.dtype}")
    return arr


def _exr_planes(rgb: NDArray[np.floating], half: bool, what: str) -> tuple[list[NDArray[Any]], int]:
    arr = _rgb_planes(rgb, what)
    if half:
        h, n = to_half_safe(arr)
        return [np.ascontiguousarray(h[..., c]) for c in range(3)], n
    f = np.asarray(arr, dtype=np.float32)
    return [np.ascontiguousarray(f[..., c]) for c in range(3)], 0


def _exr_header_dict(compression: str, attributes: Mapping[str, str] | None) -> dict[str, Any]:
    if compression not in _COMPRESSIONS or not hasattr(OpenEXR, _COMPRESSIONS[compression]):
        known = ", ".join(k for k, v in _COMPRESSIONS.items() if hasattr(OpenEXR, v))
        raise InputError(f"unknown EXR compression {compression!r}: expected one of {known}")
    header: dict[str, Any] = {"compression": getattr(OpenEXR, _COMPRESSIONS[compression]),
                              "type": OpenEXR.scanlineimage}
    for key, value in (attributes or {}).items():
        if not isinstance(key, str) or not key or key in _RESERVED_ATTRIBUTES:
            raise InputError(f"EXR attribute name {key!r} is empty or reserved")
        if not isinstance(value, str):
            raise InputError(f"EXR attribute {key!r} must be a string, got {type(value).__name__}")
        header[key] = value
    return header


def _write_exr_file(path: str | os.PathLike[str], header: dict[str, Any], channels: dict[str, NDArray[Any]]) -> None:
    with OpenEXR.File(header, channels) as exr:
        exr.write(os.fspath(path))


def write_exr(path: str | os.PathLike[str], rgb: NDArray[np.floating], *, half: bool = False,
              compression: str = "zip", attributes: Mapping[str, str] | None = None) -> None:
    """Write (H, W, 3) linear RGB as a single-part scanline EXR with channels R, G, B.

    float32 by default; ``half=True`` stores float16 through :func:`to_half_safe` (values beyond 65504 are
    clamped, and the count is logged as a warning). ``attributes`` become string header attributes.
    """
    planes, n = _exr_planes(rgb, half, "the image")
    if n:
        log.warning("write_exr %s: %d values beyond the half-float range were clamped to +-%g", path, n, HALF_MAX)
    header = _exr_header_dict(compression, attributes)
    _write_exr_file(path, header, dict(zip("RGB", planes, strict=True)))


def write_exr_layers(path: str | os.PathLike[str], layers: Mapping[str, NDArray[np.floating]], *, half: bool = False,
                     compression: str = "zip", attributes: Mapping[str, str] | None = None) -> None:
    """Write several RGB images of one size into one EXR, channels ``<name>.R``, ``<name>.G``, ``<name>.B``.

    The layer named ``""`` is stored as plain ``R, G, B``. ``half`` and ``attributes`` as in :func:`write_exr`.
    """
    if not layers:
        raise InputError("write_exr_layers needs at least one layer")
    channels: dict[str, NDArray[Any]] = {}
    shape: tuple[int, ...] | None = None
    total = 0
    for name, rgb in layers.items():
        if not isinstance(name, str) or name.endswith(".") or "\0" in name:
            raise InputError(f"bad EXR layer name {name!r}: it must be a string not ending in '.'")
        planes, n = _exr_planes(rgb, half, f"layer {name!r}")
        if shape is not None and planes[0].shape != shape:
            raise InputError(f"layer {name!r} has size {planes[0].shape}, other layers have {shape}")
        shape = planes[0].shape
        total += n
        prefix = f"{name}." if name else ""  # layer "" is the plain R, G, B channels
        channels.update({prefix + c: p for c, p in zip("RGB", planes, strict=True)})
    if total:
        log.warning("write_exr_layers %s: %d values beyond the half-float range were clamped to +-%g", path, total,
                    HALF_MAX)
    _write_exr_file(path, _exr_header_dict(compression, attributes), channels)


def read_exr_layers(src: Source, *, max_pixels: int | None = None) -> tuple[dict[str, F32], dict[str, str]]:
    """Inverse of :func:`write_exr_layers`: every RGB channel group as (H, W, 3) float32, and the string attributes.

    Channels ``<name>.R/.G/.B`` give layer ``<name>``; plain ``R, G, B`` give layer ``""``; other channels are
    ignored. Values are returned as stored (no clamping).
    """
    hdr = probe(src)
    if hdr.format != "exr":
        raise InputError(f"expected an EXR file, got {hdr.format}")
    _check_max_pixels(hdr, max_pixels)
    _, ch, header = _open_exr(_read_all(src))
    groups = _exr_rgb_groups(set(ch))
    if not groups:
        raise InputError(f"EXR file has no RGB layers: channels are {sorted(ch)}")
    layers = {p[:-1] if p else "": np.stack([np.asarray(ch[p + c], dtype=np.float32) for c in "RGB"], axis=-1)
              for p in groups}
    attrs = {k: v for k, v in header.items() if isinstance(v, str) and k not in _RESERVED_ATTRIBUTES}
    return layers, attrs


# ----------------------------------------------------------------------------------------------------------------
# Radiance HDR, tone mapping, previews


def write_hdr(path: str | os.PathLike[str], rgb: NDArray[np.floating]) -> None:
    """Write (H, W, 3) linear RGB as Radiance RGBE with new-style RLE scanlines (:mod:`relight.hdr_rgbe`).

    RGBE has no sign: negative values are written as 0 (the count is logged). Non-finite values are an error.
    """
    arr = np.asarray(_rgb_planes(rgb, "the image"), dtype=np.float64)
    if not np.isfinite(arr).all():
        raise InputError(f"cannot write {int(np.sum(~np.isfinite(arr)))} non-finite values to a Radiance HDR file")
    n = int(np.sum(arr < 0))
    if n:
        log.warning("write_hdr %s: %d negative values written as 0", path, n)
    hdr_rgbe.write(path, np.maximum(arr, 0.0))


#: Narkowicz's ACES fit coefficients (K. Narkowicz, "ACES Filmic Tone Mapping Curve", blog post, 6 Jan 2016).
_ACES_A, _ACES_B, _ACES_C, _ACES_D, _ACES_E = 2.51, 0.03, 2.43, 0.59, 0.14
TONEMAP_OPERATORS: Final = ("aces", "reinhard")


def tonemap(rgb: NDArray[np.floating], *, exposure: float = 0.0, operator: str = "aces") -> NDArray[np.uint8]:
    """Linear HDR RGB to 8-bit sRGB for display.

    ``x = rgb 2^exposure`` (exposure in stops; negatives and NaN count as 0), then per channel

    * ``"aces"``: Narkowicz's fit of the ACES RRT + sRGB ODT, ``x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)``,
      as published (pre-exposed: 1 maps to about 0.8);
    * ``"reinhard"``: ``x / (1 + x)`` (Reinhard et al. 2002, eq. 3),

    clamped to [0, 1], encoded with the sRGB OETF (IEC 61966-2-1) and rounded to 8 bits.
    """
    if operator not in TONEMAP_OPERATORS:
        raise InputError(f"unknown tone-mapping operator {operator!r}: expected one of {', '.join(TONEMAP_OPERATORS)}")
    if not math.isfinite(exposure):
        raise InputError(f"exposure must be finite, got {exposure}")
    x = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=np.inf, neginf=0.0)
    x = np.maximum(x, 0.0) * 2.0 ** exposure
    if operator == "aces":
        with np.errstate(invalid="ignore"):
            y = np.where(np.isinf(x), 1.0, x * (_ACES_A * x + _ACES_B) / (x * (_ACES_C * x + _ACES_D) + _ACES_E))
    else:
        with np.errstate(invalid="ignore"):
            y = np.where(np.isinf(x), 1.0, x / (1.0 + x))
    return np.round(linear_to_srgb(np.clip(y, 0.0, 1.0)) * 255.0).astype(np.uint8)


def write_png_preview(path: str | os.PathLike[str], rgb: NDArray[np.floating], *, exposure: float = 0.0,
                      operator: str = "aces") -> None:
    """Tone-map (:func:`tonemap`) an (H, W, 3) image and save it as an 8-bit sRGB PNG."""
    Image.fromarray(tonemap(_rgb_planes(rgb, "the image"), exposure=exposure, operator=operator), "RGB").save(
        os.fspath(path), format="PNG")


# ----------------------------------------------------------------------------------------------------------------
# Cube maps


def cube_face_dirs(size: int) -> NDArray[np.float64]:
    """Unit directions of every texel centre of a cube map, shape (6, size, size, 3), faces in FACE_NAMES order.

    Texel (row r, column c) has ``s = (c + 0.5) / size``, ``t = (r + 0.5) / size`` and, with ``a = 2 s - 1``,
    ``b = 2 t - 1``, the direction given by inverting OpenGL 4.6 table 8.19 (see :func:`cube_to_latlong`).
    """
    if size <= 0:
        raise InputError(f"cube face size must be positive, got {size}")
    g = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    return _face_uv_to_dirs(g[None, :, None], g[None, None, :], np.arange(6)[:, None, None])


def _face_uv_to_dirs(b: NDArray[np.float64], a: NDArray[np.float64], face: NDArray[np.int_]) -> NDArray[np.float64]:
    """Inverse of table 8.19: face, ``a = 2s - 1`` (columns), ``b = 2t - 1`` (rows) -> unit direction."""
    a, b, face = np.broadcast_arrays(a, b, face)
    one = np.ones_like(a)
    x = np.choose(face, [one, -one, a, a, a, -a])
    y = np.choose(face, [-b, -b, one, -one, -b, -b])
    z = np.choose(face, [-a, a, b, -b, one, -one])
    d = np.stack([x, y, z], axis=-1)
    return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True), dtype=np.float64)


def _dirs_to_face_uv(x: NDArray[Any], y: NDArray[Any], z: NDArray[Any]) -> tuple[NDArray[np.intp], NDArray[Any],
                                                                             NDArray[Any]]:
    """OpenGL 4.6 table 8.19: direction components -> (face, s, t), ``s, t`` in [0, 1]. Ties go to x, then y.

    Written per axis: ``+-X``: ``sc = -sign(rx) rz``, ``tc = -ry``; ``+-Y``: ``sc = rx``, ``tc = sign(ry) rz``;
    ``+-Z``: ``sc = sign(rz) rx``, ``tc = -ry``; ``ma`` is the major component.
    """
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    is_x = (ax >= ay) & (ax >= az)
    is_y = ~is_x & (ay >= az)
    is_z = ~is_x & ~is_y
    neg = np.where(is_x, x < 0, np.where(is_y, y < 0, z < 0))
    face = (np.where(is_x, 0, np.where(is_y, 2, 4)) + neg).astype(np.intp)
    sign = np.where(neg, -1.0, 1.0).astype(x.dtype)
    ma = np.maximum(np.where(is_x, ax, np.where(is_y, ay, az)), np.finfo(x.dtype).tiny)
    sc = np.where(is_x, -sign * z, np.where(is_z, sign * x, x))
    tc = np.where(is_y, sign * z, -y)
    half = x.dtype.type(0.5)
    return face, (sc / ma + 1) * half, (tc / ma + 1) * half


def _faces_array(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating]) -> NDArray[np.float32]:
    if isinstance(faces, Mapping):
        missing = [n for n in FACE_NAMES if n not in faces]
        extra = [n for n in faces if n not in FACE_NAMES]
        if missing or extra:
            raise InputError(f"cube faces must be named {', '.join(FACE_NAMES)}; missing {missing}, unknown {extra}")
        arrs = [np.asarray(faces[n], dtype=np.float32) for n in FACE_NAMES]
        if len({a.shape for a in arrs}) != 1:
            raise InputError(f"cube faces differ in shape: {[a.shape for a in arrs]}")
        cube = np.stack(arrs)
    else:
        cube = np.asarray(faces, dtype=np.float32)
    if cube.ndim == 3:
        cube = cube[..., None]
    if cube.ndim != 4 or cube.shape[0] != 6 or cube.shape[1] != cube.shape[2] or cube.shape[1] == 0:
        raise InputError(f"cube faces must have shape (6, S, S[, C]) with S > 0, got {cube.shape}")
    return cube


def cube_faces_from_image(image: NDArray[np.floating], layout: str = "auto") -> NDArray[np.float32]:
    """Cut one image holding a cube map into faces, shape (6, S, S, C) in FACE_NAMES order.

    Layouts (each cell is one S x S face, stored exactly as an OpenGL face image, row 0 = ``t = 0``):

    * ``"strip-h"`` (6S x S): +X, -X, +Y, -Y, +Z, -Z from left to right;
    * ``"strip-v"`` (S x 6S): the same order from top to bottom;
    * ``"cross-h"`` (4S x 3S): middle row -X, +Z, +X, -Z; +Y above +Z, -Y below +Z (the faces fold edge to edge
      without rotation under the table-8.19 convention);
    * ``"cross-v"`` (3S x 4S): the horizontal cross with -Z moved below -Y and turned 180 degrees so that its
      edges still meet their neighbours: rows ``+Y`` / ``-X +Z +X`` / ``-Y`` / ``-Z`` (rotated), in column 1.

    ``"auto"`` picks the layout from the aspect ratio.
    """
    img = np.asarray(image, dtype=np.float32)
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3:
        raise InputError(f"a cube-map image must have shape (H, W[, C]), got {img.shape}")
    h, w = img.shape[:2]
    if layout == "auto":
        layout = next((n for n, (a, b) in CUBE_LAYOUTS.items() if w * b == h * a and w % a == 0), "")
    if layout not in CUBE_LAYOUTS:
        raise InputError(f"image is {w} x {h}: not a cube-map layout ({', '.join(CUBE_LAYOUTS)}), or unknown "
                         f"layout {layout!r}")
    a, b = CUBE_LAYOUTS[layout]
    s = w // a
    if s == 0 or w != a * s or h != b * s:
        raise InputError(f"image is {w} x {h}: a {layout} cube map must be {a}S x {b}S pixels")
    cells = {
        "strip-h": [(0, i) for i in range(6)],
        "strip-v": [(i, 0) for i in range(6)],
        "cross-h": [(1, 2), (1, 0), (0, 1), (2, 1), (1, 1), (1, 3)],
        "cross-v": [(1, 2), (1, 0), (0, 1), (2, 1), (1, 1), (3, 1)],
    }[layout]
    faces = np.stack([img[r * s:(r + 1) * s, c * s:(c + 1) * s] for r, c in cells])
    if layout == "cross-v":
        faces[5] = faces[5, ::-1, ::-1]
    return faces


def cube_to_latlong(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating], height: int, *,
                    samples: int | None = None) -> F32:
    """Resample a cube map to a lat-long map of shape (height, 2 height, C), solid-angle aware.

    Faces: a dict keyed ``"+X", "-X", "+Y", "-Y", "+Z", "-Z"`` or an array (6, S, S[, C]) in that order
    (``GL_TEXTURE_CUBE_MAP_POSITIVE_X`` + i). Each face is an image whose row 0 is ``t = 0`` and column 0 is
    ``s = 0``; texel centres sit at ``(i + 0.5) / S``.

    Face selection and coordinates follow the OpenGL 4.6 core specification, section 8.13, table 8.19: for a
    direction ``r = (rx, ry, rz)`` the major axis picks the face and ``(sc, tc, ma)``

    ======  =====  =====  =====
    face     sc     tc     ma
    ======  =====  =====  =====
    +X      -rz    -ry    rx
    -X      +rz    -ry    rx
    +Y      +rx    +rz    ry
    -Y      +rx    -rz    ry
    +Z      +rx    -ry    rz
    -Z      -rx    -ry    rz
    ======  =====  =====  =====

    then ``s = (sc / |ma| + 1) / 2``, ``t = (tc / |ma| + 1) / 2``. The direction ``r`` is taken literally as a
    project direction (:mod:`relight.conventions`, +Y up), so the lat-long pixel for ``d`` holds what an OpenGL
    ``texture(samplerCube, d)`` lookup returns. (Table 8.19 is a left-handed, RenderMan-style frame: a face image
    looks mirrored from the cube's centre. That is the standard for cube-map files; no flip is applied.)

    Notes
    -----
    Each output pixel is the average of the cube map over the pixel's footprint on the sphere, weighted by solid
    angle. The footprint is split into ``n x n`` cells of equal solid angle (uniform in ``cos theta`` and in
    ``phi``); the cube map is sampled bilinearly at each cell centre (across face edges, from the neighbouring
    face, as OpenGL seamless cube maps do) and the ``n^2`` samples are averaged::

        L(i, j) = (1 / n^2) sum_{k,l} L_cube(d(z_k, phi_l)),   z_k uniform in [cos theta_i+, cos theta_i-]

    ``n`` (``samples``) defaults to about twice the ratio of output pixel size to cube texel size, so every
    texel is seen by several samples and the radiance integral is preserved to well under 1 %.
    """
    cube = _faces_array(faces)
    if not np.isfinite(cube).all():
        raise InputError(f"cube faces contain {int(np.sum(~np.isfinite(cube)))} non-finite values (NaN/Inf)")
    if height <= 0:
        raise InputError(f"output height must be positive, got {height}")
    size, channels = cube.shape[1], cube.shape[3]
    width = 2 * height
    n = int(samples) if samples is not None else max(2, math.ceil(8.0 * size / height))
    if n <= 0:
        raise InputError(f"samples must be positive, got {samples}")
    planes = np.ascontiguousarray(_pad_cube(cube).reshape(-1, channels).T, dtype=np.float32)
    # Equal-area sub-sample grid: z = cos(theta) uniform in each row band, phi uniform in each column.
    z_edges = np.cos(np.arange(height + 1) * np.pi / height)
    frac = (np.arange(n) + 0.5) / n
    z = (z_edges[:-1, None] + (z_edges[1:] - z_edges[:-1])[:, None] * frac[None, :]).reshape(-1)
    phi = ((np.arange(width)[:, None] + frac[None, :]).reshape(-1) / width - 0.5) * 2.0 * np.pi
    cos_phi, sin_phi = np.cos(phi).astype(np.float32), np.sin(phi).astype(np.float32)
    out = np.empty((height, width, channels), dtype=np.float32)
    rows_per_chunk = max(1, (1 << 19) // (width * n * n))
    for r0 in range(0, height, rows_per_chunk):  # chunks of output rows, to bound memory
        r1 = min(height, r0 + rows_per_chunk)
        zc = z[r0 * n:r1 * n, None]
        rho = np.sqrt(np.maximum(0.0, 1.0 - zc * zc)).astype(np.float32)
        dy = np.broadcast_to(zc.astype(np.float32), (zc.shape[0], cos_phi.size))
        vals = _sample_padded(planes, size, rho * cos_phi, dy, rho * sin_phi)
        out[r0:r1] = vals.reshape(r1 - r0, n, width, n, channels).mean(axis=(1, 3))
    return out


def _pad_cube(cube: NDArray[np.float32]) -> NDArray[np.float32]:
    """Faces with a one-texel border copied from the neighbouring faces: shape (6, S + 2, S + 2, C).

    Border texel centres lie just past the face edge (``a`` or ``b`` = +-(1 + 1/S)); their direction falls on the
    neighbouring face, where the nearest texel is taken. This makes bilinear lookups seamless across edges.
    """
    size = cube.shape[1]
    g = (np.arange(-1, size + 1) + 0.5) / size * 2.0 - 1.0
    d = _face_uv_to_dirs(g[None, :, None], g[None, None, :], np.arange(6)[:, None, None])
    face, s, t = _dirs_to_face_uv(d[..., 0], d[..., 1], d[..., 2])
    col = np.clip(np.floor(s * size), 0, size - 1).astype(np.intp)
    row = np.clip(np.floor(t * size), 0, size - 1).astype(np.intp)
    padded = cube[face, row, col]
    padded[:, 1:-1, 1:-1] = cube  # interior texels are the faces themselves
    # Corners: three faces meet, so there is no fourth texel; seamless cube-map filtering (ARB_seamless_cube_map,
    # core since OpenGL 3.2) recommends the average of the three available ones.
    for r, c, dr, dc in ((0, 0, 1, 1), (0, -1, 1, -1), (-1, 0, -1, 1), (-1, -1, -1, -1)):
        padded[:, r, c] = (padded[:, r + dr, c] + padded[:, r, c + dc] + padded[:, r + dr, c + dc]) / 3.0
    return np.asarray(padded, dtype=np.float32)


def _sample_padded(planes: NDArray[np.float32], size: int, x: NDArray[np.float32], y: NDArray[np.float32],
                   z: NDArray[np.float32]) -> NDArray[np.float32]:
    """Bilinear lookup of directions in a padded cube stored as channel planes (C, 6 (S+2)^2); returns (..., C)."""
    face, s, t = _dirs_to_face_uv(x, y, z)
    p = size + 2
    fsize = np.float32(size)
    u = np.clip(s * fsize + np.float32(0.5), 0.0, fsize + 1)  # texel-centre coordinates in the padded face
    v = np.clip(t * fsize + np.float32(0.5), 0.0, fsize + 1)
    u0 = np.minimum(u.astype(np.intp), size)  # u >= 0, so truncation is floor
    v0 = np.minimum(v.astype(np.intp), size)
    fu = u - u0
    fv = v - v0
    base = face * (p * p) + v0 * p + u0
    w00, w01 = (1 - fu) * (1 - fv), fu * (1 - fv)
    w10, w11 = (1 - fu) * fv, fu * fv
    out = np.empty(x.shape + (planes.shape[0],), dtype=np.float32)
    for c, plane in enumerate(planes):  # a handful of channels
        out[..., c] = (w00 * plane.take(base) + w01 * plane.take(base + 1) + w10 * plane.take(base + p)
                       + w11 * plane.take(base + p + 1))
    return out


# ----------------------------------------------------------------------------------------------------------------
# Lat-long resampling


def resample_latlong(rgb: NDArray[np.floating], height: int) -> F32:
    """Resample an (H, 2H[, C]) lat-long map to (height, 2 height[, C]).

    Downsampling is an exact area average: each output pixel is the solid-angle-weighted mean of the input
    pixels it overlaps (fractional overlaps for non-integer factors). Rows weigh by ``cos theta_top -
    cos theta_bottom`` of the overlap, columns by the overlapping ``phi`` length, so ``sum L Omega`` over the
    sphere is preserved exactly (to rounding) for any factor. Upsampling is bilinear between pixel centres
    (wrapping in ``phi``, clamped at the poles).
    """
    arr = np.asarray(rgb, dtype=np.float64)
    squeeze = arr.ndim == 2
    if squeeze:
        arr = arr[..., None]
    if arr.ndim != 3:
        raise InputError(f"a lat-long map must have shape (H, W[, C]), got {arr.shape}")
    try:
        h_in, w_in = check_latlong_shape(arr.shape)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if height <= 0:
        raise InputError(f"output height must be positive, got {height}")
    if height == h_in:
        out = arr
    elif height < h_in:
        rows = _area_weights(h_in, height, lambda k: np.cos(np.pi * k / (h_in * height)))
        cols = _area_weights(w_in, 2 * height, lambda k: k / (w_in * 2 * height))
        out = _apply_weights(cols, _apply_weights(rows, arr, axis=0), axis=1)
    else:
        out = _bilinear_latlong(arr, height)
    result = np.asarray(out, dtype=np.float32)
    return result[..., 0] if squeeze else result


Weights = tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64], int]


def _area_weights(n_in: int, n_out: int, measure: Callable[[NDArray[np.intp]], NDArray[np.float64]]) -> Weights:
    """Sparse overlap weights for area-averaging ``n_in`` equal cells into ``n_out`` (``n_out < n_in``).

    Boundaries are integers in a common unit (input cell ``i`` spans ``[i n_out, (i+1) n_out]``, output cell
    ``o`` spans ``[o n_in, (o+1) n_in]``), so overlaps are found exactly; ``measure(k)`` maps a boundary to the
    measure coordinate (``cos theta`` for rows, ``phi`` for columns). Each input cell meets at most two
    output cells. Returns (output index, input index, weight, n_out), weights normalised per output cell.
    """
    i = np.arange(n_in)
    lo, hi = i * n_out, (i + 1) * n_out
    first = lo // n_in  # output cell holding the start of input cell i
    second = (hi - 1) // n_in  # output cell holding its end (the same one, or the next)

    split = second != first
    o_all = np.concatenate([first, second[split]])
    i_all = np.concatenate([i, i[split]])
    a = np.maximum(lo[i_all], o_all * n_in)
    b = np.minimum(hi[i_all], (o_all + 1) * n_in)
    w_all = np.asarray(np.abs(measure(b) - measure(a)), dtype=np.float64)
    total = np.bincount(o_all, weights=w_all, minlength=n_out)
    return o_all, i_all, w_all / total[o_all], n_out


def _apply_weights(weights: Weights, arr: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    o, i, w, n_out = weights
    moved = np.moveaxis(arr, axis, 0)
    out = np.zeros((n_out,) + moved.shape[1:], dtype=np.float64)
    np.add.at(out, o, moved[i] * w.reshape((-1,) + (1,) * (moved.ndim - 1)))
    return np.moveaxis(out, 0, axis)


def _bilinear_latlong(arr: NDArray[np.float64], height: int) -> NDArray[np.float64]:
    h_in, w_in = arr.shape[:2]
    width = 2 * height
    y = np.clip((np.arange(height) + 0.5) * h_in / height - 0.5, 0.0, h_in - 1.0)
    x = (np.arange(width) + 0.5) * w_in / width - 0.5
    y0 = np.minimum(np.floor(y).astype(np.intp), h_in - 2) if h_in > 1 else np.zeros(height, np.intp)
    fy = (y - y0)[:, None, None] if h_in > 1 else np.zeros((height, 1, 1))
    x0 = np.floor(x).astype(np.intp)
    fx = (x - x0)[None, :, None]
    x0 %= w_in
    x1 = (x0 + 1) % w_in
    y1 = np.minimum(y0 + 1, h_in - 1)
    top = arr[y0][:, x0] * (1 - fx) + arr[y0][:, x1] * fx
    bot = arr[y1][:, x0] * (1 - fx) + arr[y1][:, x1] * fx
    return np.asarray(top * (1 - fy) + bot * fy, dtype=np.float64)
