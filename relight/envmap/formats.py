"""Image formats: the one format-sniff table (magic bytes -> format), the header record and the size limits.

Signatures: OpenEXR "magic number" ``76 2f 31 01`` (OpenEXR File Layout, Kainz 2013); Radiance's program line
``#?`` (Radiance reference manual, "Picture file format"); the PNG signature (ISO/IEC 15948, section 5.2);
JPEG's SOI marker followed by the first marker's ``ff`` (ITU-T T.81, B.1.1.3). :func:`sniff` is what both
:func:`relight.envmap.headers.probe` and the server's upload path use to recognise a file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError

#: Anything a reader accepts: a path or the file's bytes.
Source = str | os.PathLike[str] | bytes | bytearray | memoryview

#: Magic bytes -> format name, in the order they are tested.
MAGIC: Final = {b"\x76\x2f\x31\x01": "exr", b"#?": "hdr", b"\x89PNG\r\n\x1a\n": "png", b"\xff\xd8\xff": "jpeg"}
#: Bytes :func:`sniff` needs to decide (the longest signature).
SNIFF_BYTES: Final = max(len(m) for m in MAGIC)
#: Formats the readers recognise (the ``format`` of an :class:`ImageHeader`).
FORMATS: Final = tuple(MAGIC.values())
#: The accepted formats in words, for error messages.
ACCEPTED: Final = "OpenEXR (.exr), Radiance RGBE (.hdr), PNG or JPEG"

#: Pixel limit applied even when a caller passes ``max_pixels=None``: 2^28 (16384 x 16384), 3 GiB as float32 RGB.
#: A crafted header can claim any size; nothing larger is handed to a decoder.
HARD_MAX_PIXELS: Final = 1 << 28


def sniff(head: bytes | bytearray | memoryview) -> str | None:
    """The format whose signature ``head`` starts with (``"exr"``, ``"hdr"``, ``"png"``, ``"jpeg"``), or None.

    ``head`` needs at most :data:`SNIFF_BYTES` bytes; a shorter one can only match a shorter signature.
    """
    start = bytes(head[:SNIFF_BYTES])
    return next((fmt for magic, fmt in MAGIC.items() if start.startswith(magic)), None)


class NeedMoreData(Exception):
    """Internal: a header parser ran past the end of the bytes it was given (the caller may read more)."""


@dataclass(frozen=True)
class ImageHeader:
    """What a file's header says, read without decoding pixels (see :func:`relight.envmap.headers.probe`)."""

    format: str  # "exr" | "hdr" | "png" | "jpeg"
    width: int
    height: int
    channels: int  # channels stored in the file (EXR: all channels of part 0)
    bit_depth: int = 8  # bits per channel (EXR: 16 or 32; HDR: 8-bit mantissas with a shared exponent)
    #: Pixels the decoder allocates (EXR: every part and every level of a tiled part); 0: just this image's.
    decoded_pixels: int = 0

    @property
    def pixels(self) -> int:
        return self.width * self.height

    @property
    def allocated_pixels(self) -> int:
        """The pixels decoding allocates: this image's, or more (EXR parts and levels)."""
        return max(self.pixels, self.decoded_pixels)


def check_max_pixels(hdr: ImageHeader, max_pixels: int | None) -> None:
    """Raise :class:`InputError` if the header's size exceeds ``max_pixels`` (or :data:`HARD_MAX_PIXELS`)."""
    limit = HARD_MAX_PIXELS if max_pixels is None else min(max_pixels, HARD_MAX_PIXELS)
    if hdr.pixels > limit:
        raise InputError(f"image is {hdr.width} x {hdr.height} = {hdr.pixels} pixels, more than the limit of "
                         f"{limit} pixels")
    if hdr.allocated_pixels > limit:
        raise InputError(f"the file's parts and levels hold {hdr.allocated_pixels} pixels in all (the first image is "
                         f"{hdr.width} x {hdr.height}), more than the limit of {limit} pixels: every part is decoded")


def read_all(src: Source) -> bytes:
    """The whole file (or a copy of the bytes given); an unreadable path is an :class:`InputError`."""
    if isinstance(src, bytes | bytearray | memoryview):
        return bytes(src)
    path = os.fspath(src)
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise InputError(f"cannot read {path!r}: {exc.strerror or exc}") from exc


def check_rgb_image(rgb: object, what: str) -> NDArray[Any]:
    """An (H, W, 3) numeric array with H, W > 0 (what the writers accept), else :class:`InputError` naming ``what``."""
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[-1] != 3 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{what} must have shape (H, W, 3) with H, W > 0, got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.floating) and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{what} must be a numeric array, got dtype {arr.dtype}")
    return arr
