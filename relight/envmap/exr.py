"""OpenEXR reading and writing through the OpenEXR 3.x Python bindings (``OpenEXR.File``).

Reading: every compression the library supports (the samples are DWAB), half/float/uint channels, RGB, RGBA
(A dropped) or Y (grey, replicated); multi-part files give part 0. Channels are always read separately
(``separate_channels=True``), never combined by the bindings. Writing: single-part scanline files, float32 or
half (:func:`to_half_safe`), with optional layers (``<name>.R/.G/.B``) and string attributes.

The header is parsed before decoding by the hand-written :func:`relight.envmap.exr_header.parse_header` (the
pre-decode size bound; the bindings cannot read a header without decoding the file).
"""

from __future__ import annotations

import io
import logging
import os
from collections.abc import Mapping
from typing import Any, Final

import numpy as np
import OpenEXR
from numpy.typing import NDArray

from relight.envmap.exr_header import ExrInfo, parse_header
from relight.envmap.formats import (
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
