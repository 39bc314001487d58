"""Header probing: format, size and channel count of an image file without decoding a pixel.

The format comes from the magic bytes (:func:`relight.envmap.formats.sniff`); the header from the format's
reader: :func:`relight.envmap.exr_header.parse_header` (hand-written, the pre-decode bound), the Radiance header
parser (:func:`relight.envmap.rgbe.parse_header`), or Pillow's lazy PNG / JPEG plugins
(:func:`relight.envmap.ldr.read_header`). Upload safety: call :func:`probe` and check the size
(:func:`relight.envmap.formats.check_max_pixels`) before decoding anything untrusted.
"""

from __future__ import annotations

import io
import os
from typing import IO, Final

from relight.envmap import exr_header, rgbe
from relight.envmap.formats import ACCEPTED, ImageHeader, NeedMoreData, Source, sniff
from relight.errors import InputError

#: Bytes read first when probing an EXR or HDR file; more is read (up to _PROBE_MAX) only if the header is longer.
_PROBE_FIRST: Final = 1 << 16
_PROBE_MAX: Final = 1 << 26


def probe(data: Source) -> ImageHeader:
    """Format, size and channel count from the header only: no pixel is decoded, nothing big is allocated.

    ``data`` is the file's bytes or a path (only the first bytes of the file are read, more only when the
    header is longer). Raises :class:`InputError` for an empty file, an unknown magic number (the message lists
    the accepted formats), a truncated header or a zero-size image.
    """
    if isinstance(data, bytes | bytearray | memoryview):
        return probe_bytes(bytes(data))
    path = os.fspath(data)
    try:
        with open(path, "rb") as fh:
            return _probe_file(fh, path)
    except OSError as exc:
        raise InputError(f"cannot read {path!r}: {exc.strerror or exc}") from exc


def probe_bytes(buf: bytes) -> ImageHeader:
    """:func:`probe` for a whole file's bytes."""
    if not buf:
        raise InputError("empty file (0 bytes): not an image")
    fmt = _sniff_or_raise(buf)
    if fmt in ("png", "jpeg"):
        from relight.envmap import ldr  # Pillow loads only for PNG / JPEG (an EXR job's start-up skips it)

        return ldr.read_header(io.BytesIO(buf), fmt)
    try:
        return _parse(buf, fmt, complete=True)
    except NeedMoreData:
        raise InputError(f"truncated {fmt.upper()} file: the header ends after {len(buf)} bytes") from None


def _probe_file(fh: IO[bytes], path: str) -> ImageHeader:
    size = _PROBE_FIRST
    buf = fh.read(size)
    if not buf:
        raise InputError("empty file (0 bytes): not an image")
    fmt = _sniff_or_raise(buf)
    if fmt in ("png", "jpeg"):
        from relight.envmap import ldr  # Pillow loads only for PNG / JPEG (an EXR job's start-up skips it)

        fh.seek(0)
        return ldr.read_header(fh, fmt)  # Pillow reads only as far as the header
    while True:
        complete = len(buf) < size
        try:
            return _parse(buf, fmt, complete=complete)
        except NeedMoreData:
            if complete:
                raise InputError(f"truncated {fmt.upper()} file: the header ends after {len(buf)} bytes") from None
            if size >= _PROBE_MAX:
                raise InputError(f"{path}: image header longer than {_PROBE_MAX} bytes") from None
            buf += fh.read(size)
            size *= 2


def _sniff_or_raise(buf: bytes) -> str:
    fmt = sniff(buf)
    if fmt is None:
        raise InputError(f"unrecognised image format (file starts with {buf[:8].hex(' ')}): accepted formats "
                         f"are {ACCEPTED}")
    return fmt


def _parse(buf: bytes, fmt: str, *, complete: bool) -> ImageHeader:
    """EXR or HDR header; :class:`NeedMoreData` when ``buf`` ends inside it."""
    if fmt == "exr":
        return exr_header.parse_header(buf).image
    return rgbe.parse_header(buf, complete=complete).image
