"""The OpenEXR header parser: every part's size, channels and type, read *before* the decoder allocates anything.

Hand-written on purpose: it follows "OpenEXR File Layout" (Kainz 2013, components 1-3) so that the image size is
known, and limited, before decoding. The OpenEXR bindings (``relight.envmap.exr``) have no way to read a header
without decoding the file, and no size limit of their own; this pre-decode bound is what protects an upload path
from a crafted header claiming a 100000 x 100000 image.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final

from relight.envmap.formats import ImageHeader, NeedMoreData
from relight.errors import InputError


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
#: Largest tile edge accepted beyond the part's own size. The decoder's working memory grows with the tile's size,
#: not the image's (measured, OpenEXR 3.5.3: a 16 x 8 image with 16 x 16,000,000 tiles takes 3 GB and 25 s from a
#: 2 KB file), so a tile edge may exceed the part's size in that direction by no more than this (real files use 16
#: to 256; a 4096-row tile of a 16 x 8 image costs the decoder under 1 MB).
MAX_TILE_EDGE: Final = 4096


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
    tile: tuple[int, int] | None = None
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
        elif name == b"tiles" and type_name == b"tiledesc":
            if size != 9:
                raise InputError(f"corrupt EXR header: the tile description of {where} has {size} bytes, not 9")
            x_size, y_size = struct.unpack("<2I", value[:8])
            tile = (x_size, y_size)
            level_mode = value[8] & 0x0F
            if value[8] >> 4 not in (0, 1):
                raise InputError(f"corrupt EXR header: level rounding mode {value[8] >> 4} of {where}")
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
    if part_type.startswith("tiled"):
        _check_tile(tile, width, height, where)
    decoded = width * height * _LEVEL_FACTOR[level_mode if part_type.startswith("tiled") else 0]
    return ExrPart(width, height, part_type, decoded), channels


def _check_tile(tile: tuple[int, int] | None, width: int, height: int, where: str) -> None:
    """Bound a tiled part's tile size before the decoder sizes its buffers by it (:data:`MAX_TILE_EDGE`)."""
    if tile is None:
        raise InputError(f"corrupt EXR header: the tiled {where} has no tile description ('tiles')")
    x_size, y_size = tile
    if x_size == 0 or y_size == 0:
        raise InputError(f"corrupt EXR header: tile size {x_size} x {y_size} of {where}")
    if x_size > max(width, MAX_TILE_EDGE) or y_size > max(height, MAX_TILE_EDGE):
        raise InputError(f"EXR tile size {x_size} x {y_size} is too large ({where}): a tile may exceed the "
                         f"image ({width} x {height}) only up to {MAX_TILE_EDGE} texels a side")


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
