"""A complete structural check of a PNG stream (PNG specification, 3rd ed., §5 chunks, §7.3 filtering, §8 Adam7
interlacing) before a C decoder sees it.

Why: imagecodecs' libpng decoder (2026.3.6, used for 16-bit PNG, :mod:`relight.envmap.ldr`) drops one reference to
``None`` every time it raises; on Python 3.11 (``None`` is not immortal before 3.12) enough malformed 16-bit PNGs
in one worker process abort it ("Fatal Python error: none_dealloc"), found by ``bench/fuzz.py``. A stream that
passes this check — every chunk's CRC, IHDR first and valid, IDAT data that inflates to exactly the filtered
image's size with valid filter bytes, IEND last — does not make libpng raise, so the decoder's error path is never
taken.
"""

from __future__ import annotations

import struct
import zlib
from typing import Final

import numpy as np

from relight.errors import InputError

SIGNATURE: Final = b"\x89PNG\r\n\x1a\n"
#: Samples per pixel of each colour type (§6.1); 16-bit files have no palette type (3).
CHANNELS: Final = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
#: Adam7 passes (§8.2): first column, first row, column step, row step.
ADAM7: Final = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))
#: Largest filter type byte (§7.3: None, Sub, Up, Average, Paeth).
MAX_FILTER: Final = 4


def _passes(width: int, height: int, interlaced: bool) -> list[tuple[int, int]]:
    """(columns, rows) of each reduced image (one for a non-interlaced file; empty passes left out)."""
    if not interlaced:
        return [(width, height)]
    dims = [(-(-(width - x0) // dx) if width > x0 else 0, -(-(height - y0) // dy) if height > y0 else 0)
            for x0, y0, dx, dy in ADAM7]
    return [(w, h) for w, h in dims if w and h]


def check_png_stream(buf: bytes, *, what: str = "PNG file") -> None:
    """Raise :class:`InputError` naming the first structural fault of ``buf`` (module docstring)."""
    if not buf.startswith(SIGNATURE):
        raise InputError(f"{what}: no PNG signature")
    pos, first, idat, ended = len(SIGNATURE), True, [], False
    header: tuple[int, int, int, int, int] | None = None
    while pos < len(buf):
        if len(buf) - pos < 12:
            raise InputError(f"{what}: truncated chunk at byte {pos}")
        length, ctype = struct.unpack(">I4s", buf[pos:pos + 8])
        end = pos + 12 + length
        if length > 0x7FFFFFFF or end > len(buf):
            raise InputError(f"{what}: chunk {ctype!r} at byte {pos} runs past the end of the file")
        data = buf[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", buf[end - 4:end])
        if zlib.crc32(ctype + data) != crc:
            raise InputError(f"{what}: chunk {ctype!r} at byte {pos} fails its CRC (corrupt data)")
        if first and ctype != b"IHDR":
            raise InputError(f"{what}: the first chunk is {ctype!r}, not IHDR")
        if ctype == b"IHDR":
            if not first or length != 13:
                raise InputError(f"{what}: misplaced or malformed IHDR chunk")
            width, height, depth, colour, comp, filt, inter = struct.unpack(">IIBBBBB", data)
            if not (0 < width < 1 << 31 and 0 < height < 1 << 31) or colour not in CHANNELS or comp or filt \
                    or inter > 1 or depth not in (1, 2, 4, 8, 16) or (colour == 3 and depth == 16):
                raise InputError(f"{what}: invalid IHDR ({width} x {height}, bit depth {depth}, colour type "
                                 f"{colour}, compression {comp}, filter {filt}, interlace {inter})")
            header = (width, height, depth, colour, inter)
        elif ctype == b"IDAT":
            idat.append(data)
        elif ctype == b"IEND":
            ended = end == len(buf)
            if not ended:
                raise InputError(f"{what}: {len(buf) - end} bytes after IEND")
        first = False
        pos = end
    if header is None or not ended or not idat:
        raise InputError(f"{what}: truncated (IHDR, IDAT or IEND missing)")
    width, height, depth, colour, inter = header
    bits = CHANNELS[colour] * depth
    sizes = [rows * (1 + -(-cols * bits // 8)) for cols, rows in _passes(width, height, bool(inter))]
    expected = sum(sizes)
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(b"".join(idat), expected + 1)
    except zlib.error as exc:
        raise InputError(f"{what}: corrupt compressed image data ({exc})") from None
    if len(raw) != expected or not inflater.eof:
        raise InputError(f"{what}: the image data inflates to {len(raw)}{'+' if len(raw) > expected else ''} bytes, "
                         f"{width} x {height} needs {expected}")
    offset = 0
    arr = np.frombuffer(raw, dtype=np.uint8)
    for (_, rows), size in zip(_passes(width, height, bool(inter)), sizes, strict=True):
        stride = size // rows
        if rows and int(arr[offset:offset + size:stride].max()) > MAX_FILTER:
            raise InputError(f"{what}: invalid row filter type (more than {MAX_FILTER})")
        offset += size


__all__ = ["check_png_stream"]
