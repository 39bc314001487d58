"""OpenEXR reading and writing through the OpenEXR 3.x Python bindings (``OpenEXR.File``).

Reading: every compression the library supports (the samples are DWAB), half/float/uint channels, RGB, RGBA
(A dropped) or Y (grey, replicated); multi-part files give part 0. Channels are always read separately
(``separate_channels=True``), never combined by the bindings. Writing: single-part scanline files, float32 or
half (:func:`to_half_safe`), with optional layers (``<name>.R/.G/.B``) and string attributes.

The header parser (:func:`parse_header`) is hand-written on purpose: it follows "OpenEXR File Layout" (Kainz
2013, components 1-3) so that the image size is known, and limited, *before* the bindings allocate anything.
The bindings have no way to read a header without decoding the file, and no size limit of their own; this
pre-decode bound is what protects an upload path from a crafted header claiming a 100000 x 100000 image.
"""

from __future__ import annotations

import io
import logging
import os
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import OpenEXR
from numpy.typing import NDArray

from relight.envmap.formats import (
    ImageHeader,
    NeedMoreData,
    Source,
    check_max_pixels,
    check_rgb_image,
    read_all,
    sniff,
)
from relight.errors import InputError

log = logging.getLogger("relight.envmap")

F32 = NDArray[np.float32]

#: Largest finite IEEE 754 binary16 value.
HALF_MAX: Final = 65504.0

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


# ----------------------------------------------------------------------------------------------------------------
# Header (pre-decode bound)


class _Cursor:
    """Bounds-checked little-endian reader over a bytes buffer; running off the end raises :class:`NeedMoreData`."""

    def __init__(self, buf: bytes, pos: int = 0) -> None:
        self.buf = buf
        self.pos = pos

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.buf):
            raise NeedMoreData
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def cstr(self, limit: int = 256) -> bytes:
        end = self.buf.find(b"\0", self.pos, self.pos + limit + 1)
        if end < 0:
            if len(self.buf) - self.pos <= limit:
                raise NeedMoreData
            raise InputError(f"corrupt EXR header: a name longer than {limit} bytes at offset {self.pos}")
        out = self.buf[self.pos:end]
        self.pos = end + 1
        return out

    def i32(self) -> int:
        return int(struct.unpack("<i", self.take(4))[0])


@dataclass(frozen=True)
class ExrChannel:
    name: str
    pixel_type: int  # 0 UINT, 1 HALF, 2 FLOAT
    x_sampling: int
    y_sampling: int


@dataclass(frozen=True)
class ExrPart:
    """One part's header: size, type and the pixels the decoder allocates for it (all levels of a tiled part)."""

    width: int
    height: int
    part_type: str
    decoded_pixels: int


@dataclass(frozen=True)
class ExrInfo:
    image: ImageHeader
    channels: tuple[ExrChannel, ...]
    part_type: str
    parts: tuple[ExrPart, ...] = ()


#: Parts read from a multi-part header at most (each costs a header walk; real files have a handful).
MAX_PARTS: Final = 64
#: Level modes of the ``tiledesc`` attribute (File Layout, "tiledesc"): pixels of all levels over level 0's, an
#: upper bound (mip-maps sum to 4/3 of level 0, rip-maps to 4; rounding levels up adds at most a row and a column
#: per level, covered by the factor 2 for mip-maps).
_LEVEL_FACTOR: Final = {0: 1, 1: 2, 2: 4}


def parse_header(buf: bytes) -> ExrInfo:
    """Parse the magic, the version and every part's header (OpenEXR File Layout, components 1-3).

    The decoder (``OpenEXR.File``) reads *every* part and every level of a tiled part, so the returned image
    header carries part 0's size and, as ``decoded_pixels``, the pixels of all parts and levels together: a
    16 x 8 part 0 cannot hide an 8192 x 4096 part 1. Deep parts (anywhere in the file) and more than
    :data:`MAX_PARTS` parts are refused here. Raises :class:`NeedMoreData` when ``buf`` ends inside the headers,
    :class:`InputError` for a corrupt one.
    """
    cur = _Cursor(buf, 4)
    version = cur.i32()
    if version & 0xFF != 2:
        raise InputError(f"unsupported EXR version {version & 0xFF} (only version 2 exists)")
    multipart = bool(version & 0x1000)
    single_type = "deepscanline" if version & 0x800 else "tiledimage" if version & 0x200 else "scanlineimage"
    parts: list[tuple[ExrPart, tuple[ExrChannel, ...]]] = []
    while True:
        if multipart and cur.take(1) == b"\0":  # an empty header ends the list
            break
        if multipart:
            cur.pos -= 1
        parts.append(_part_header(cur, len(parts), None if multipart else single_type))
        if not multipart:
            break
        if len(parts) > MAX_PARTS:
            raise InputError(f"EXR file has more than {MAX_PARTS} parts")
    if not parts:
        raise InputError("corrupt EXR header: a multi-part file with no part")
    first, channels = parts[0]
    bits = max(32 if c.pixel_type != 1 else 16 for c in channels)
    total = sum(p.decoded_pixels for p, _ in parts)
    image = ImageHeader("exr", first.width, first.height, len(channels), bits,
                        decoded_pixels=total if total > first.width * first.height else 0)
    return ExrInfo(image, channels, first.part_type, tuple(p for p, _ in parts))


def _part_header(cur: _Cursor, index: int, part_type: str | None) -> tuple[ExrPart, tuple[ExrChannel, ...]]:
    """One header: attributes up to the terminating null byte. ``part_type`` comes from the version field for
    single-part files, from the ``type`` attribute otherwise."""
    channels: tuple[ExrChannel, ...] | None = None
    window: tuple[int, int, int, int] | None = None
    level_mode = 0
    where = f"part {index}" if part_type is None else "the header"
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
            channels = _chlist(value)
        elif name == b"dataWindow" and type_name == b"box2i" and size == 16:
            xmin, ymin, xmax, ymax = struct.unpack("<4i", value)
            window = (xmin, ymin, xmax, ymax)
        elif name == b"type" and type_name == b"string" and part_type is None:
            part_type = value.decode("latin-1")
        elif name == b"tiles" and type_name == b"tiledesc" and size == 9:
            level_mode = value[8] & 0x0F
    if channels is None or window is None:
        missing = "channels" if channels is None else "dataWindow"
        raise InputError(f"corrupt EXR header: the required attribute {missing!r} is missing in {where}")
    part_type = part_type or "scanlineimage"
    if part_type.startswith("deep"):
        raise InputError(f"deep EXR images are not supported ({where} is {part_type})")
    xmin, ymin, xmax, ymax = window
    width, height = xmax - xmin + 1, ymax - ymin + 1
    if width <= 0 or height <= 0:
        raise InputError(f"empty EXR image: data window {window} of {where} is {max(width, 0)} x {max(height, 0)}")
    if not channels:
        raise InputError(f"EXR image has no channels in {where}")
    if level_mode not in _LEVEL_FACTOR:
        raise InputError(f"corrupt EXR header: level mode {level_mode} of {where}")
    decoded = width * height * _LEVEL_FACTOR[level_mode if part_type.startswith("tiled") else 0]
    return ExrPart(width, height, part_type, decoded), channels


def _chlist(value: bytes) -> tuple[ExrChannel, ...]:
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
            out.append(ExrChannel(name.decode("utf-8", "replace"), pixel_type, xs, ys))
    except NeedMoreData:
        raise InputError("corrupt EXR header: the channel list is cut short") from None
    return tuple(out)


# ----------------------------------------------------------------------------------------------------------------
# Decoding


def _decode_error(exc: Exception) -> str:
    """What went wrong, in words: the bindings report a damaged chunk by printing it and handing back a file with
    no parts (the ``IndexError`` of ``parts[0]``), and undecodable header text as ``UnicodeDecodeError``."""
    if isinstance(exc, IndexError):
        return ("corrupt or truncated EXR pixel data: the decoder could not read the image's chunks (a damaged chunk "
                "table, chunk header or compressed block)")
    if isinstance(exc, UnicodeDecodeError):
        return "corrupt EXR header: an attribute's text is not valid UTF-8"
    first = (str(exc).splitlines() or [""])[0]
    return f"cannot decode EXR file ({type(exc).__name__}){': ' + first if first else ''}"


def _open(buf: bytes) -> tuple[ExrInfo, dict[str, NDArray[Any]], dict[str, Any]]:
    """Read part 0 of a whole EXR file: the parsed header, channel arrays by name and the bindings' header dict."""
    try:
        info = parse_header(buf)
    except NeedMoreData:
        raise InputError(f"truncated EXR file: the header ends after {len(buf)} bytes") from None
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
        raise InputError(_decode_error(exc)) from exc
    shape = (info.image.height, info.image.width)
    for name, arr in pixels.items():
        if arr.shape != shape:
            raise InputError(f"cannot decode EXR file: channel {name!r} has shape {arr.shape}, expected {shape}")
    if set(pixels) != {c.name for c in info.channels}:
        raise InputError("cannot decode EXR file: channels decoded do not match the header (truncated file?)")
    return info, pixels, header


def decode(buf: bytes) -> F32:
    """Decode a whole EXR file to (H, W, 3) float32: channels R, G, B; or Y (grey); or one ``<layer>.R/G/B`` group."""
    _, ch, _ = _open(buf)
    names = set(ch)
    if {"R", "G", "B"} <= names:
        planes = [ch["R"], ch["G"], ch["B"]]
    elif "Y" in names and not names & {"RY", "BY", "R", "G", "B"}:
        planes = [ch["Y"]] * 3
    else:
        groups = _rgb_groups(names)
        if len(groups) != 1:
            raise InputError(f"EXR file has no single RGB, RGBA or Y image: channels are {sorted(names)}")
        p = groups[0]
        planes = [ch[p + "R"], ch[p + "G"], ch[p + "B"]]
    return np.stack([np.asarray(x, dtype=np.float32) for x in planes], axis=-1)


def _rgb_groups(names: set[str]) -> list[str]:
    """Channel-name prefixes (``"layer."``, or ``""``) that have R, G and B channels."""
    prefixes = {n[: len(n) - 1] for n in names if n.endswith(("R", "G", "B")) and (len(n) == 1 or n[-2] == ".")}
    return sorted(p for p in prefixes if all(p + c in names for c in "RGB"))


def read_exr_layers(src: Source, *, max_pixels: int | None = None) -> tuple[dict[str, F32], dict[str, str]]:
    """Inverse of :func:`write_exr_layers`: every RGB channel group as (H, W, 3) float32, and the string attributes.

    Channels ``<name>.R/.G/.B`` give layer ``<name>``; plain ``R, G, B`` give layer ``""``; other channels are
    ignored. Values are returned as stored (no clamping). The size is checked against ``max_pixels`` from the
    header before anything is decoded.
    """
    buf = read_all(src)
    if not buf:
        raise InputError("empty file (0 bytes): not an image")
    fmt = sniff(buf)
    if fmt != "exr":
        raise InputError(f"expected an EXR file, got {fmt or 'an unrecognised format'}")
    try:
        info = parse_header(buf)
    except NeedMoreData:
        raise InputError(f"truncated EXR file: the header ends after {len(buf)} bytes") from None
    check_max_pixels(info.image, max_pixels)
    _, ch, header = _open(buf)
    groups = _rgb_groups(set(ch))
    if not groups:
        raise InputError(f"EXR file has no RGB layers: channels are {sorted(ch)}")
    layers = {p[:-1] if p else "": np.stack([np.asarray(ch[p + c], dtype=np.float32) for c in "RGB"], axis=-1)
              for p in groups}
    attrs = {k: v for k, v in header.items() if isinstance(v, str) and k not in _RESERVED_ATTRIBUTES}
    return layers, attrs


# ----------------------------------------------------------------------------------------------------------------
# Writing


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


def _planes(rgb: NDArray[np.floating], half: bool, what: str) -> tuple[list[NDArray[Any]], int]:
    arr = check_rgb_image(rgb, what)
    if half:
        h, n = to_half_safe(arr)
        return [np.ascontiguousarray(h[..., c]) for c in range(3)], n
    f = np.asarray(arr, dtype=np.float32)
    return [np.ascontiguousarray(f[..., c]) for c in range(3)], 0


def _header_dict(compression: str, attributes: Mapping[str, str] | None) -> dict[str, Any]:
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


def _write_file(path: str | os.PathLike[str], header: dict[str, Any], channels: dict[str, NDArray[Any]]) -> None:
    with OpenEXR.File(header, channels) as exr:
        exr.write(os.fspath(path))


def write_exr(path: str | os.PathLike[str], rgb: NDArray[np.floating], *, half: bool = False,
              compression: str = "zip", attributes: Mapping[str, str] | None = None) -> None:
    """Write (H, W, 3) linear RGB as a single-part scanline EXR with channels R, G, B.

    float32 by default; ``half=True`` stores float16 through :func:`to_half_safe` (values beyond 65504 are
    clamped, and the count is logged as a warning). ``attributes`` become string header attributes.
    """
    planes, n = _planes(rgb, half, "the image")
    if n:
        log.warning("write_exr %s: %d values beyond the half-float range were clamped to +-%g", path, n, HALF_MAX)
    header = _header_dict(compression, attributes)
    _write_file(path, header, dict(zip("RGB", planes, strict=True)))


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
        planes, n = _planes(rgb, half, f"layer {name!r}")
        if shape is not None and planes[0].shape != shape:
            raise InputError(f"layer {name!r} has size {planes[0].shape}, other layers have {shape}")
        shape = planes[0].shape
        total += n
        prefix = f"{name}." if name else ""  # layer "" is the plain R, G, B channels
        channels.update({prefix + c: p for c, p in zip("RGB", planes, strict=True)})
    if total:
        log.warning("write_exr_layers %s: %d values beyond the half-float range were clamped to +-%g", path, total,
                    HALF_MAX)
    _write_file(path, _header_dict(compression, attributes), channels)
