"""Environment maps: decode any supported file, validate it and bring it to the project's lat-long layout.

An :class:`EnvMap` is a lat-long map in the project convention (:mod:`relight.conventions`, three.js
``equirectUv``, +Y up, W = 2H). Files may hold a lat-long map or a cube map in one of the single-image layouts
(:func:`relight.envmap.cubemap.cube_faces_from_image`), which is resampled
(:func:`relight.envmap.cubemap.cube_to_latlong`). Non-finite pixels are rejected; negative texels (lossy
compression leaves some) are clamped to 0 and counted.

Every decoder returns linear float32 RGB, shape (H, W, 3), row 0 at the top of the image. The size is checked
against ``max_pixels`` from the header (:mod:`relight.envmap.headers`) before any pixel is decoded.

A lat-long EXR *file* above :data:`STREAM_ABOVE_PIXELS` (Poly Haven's 8k and 16k) is not decoded whole: it is
streamed in scanline chunks into its area-exact downsample to :data:`STREAM_ROWS` rows
(:mod:`relight.envmap.stream`, memory independent of the file's height), orders up to ``STREAM_ROWS - 1``, more
than any chain, reflection map or SHRM of the project asks for. ``max_rows`` asks for a smaller map.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final

import numpy as np
from numpy.typing import NDArray

from relight.conventions import check_latlong_shape
from relight.envmap import exr, rgbe
from relight.envmap.cubemap import (
    CUBE_LAYOUTS,
    FACE_NAMES,
    cube_faces_from_image,
    cube_to_latlong,
    faces_array,
    layout_for_size,
)
from relight.envmap.formats import ImageHeader, Source, check_max_pixels, read_all
from relight.envmap.headers import probe, probe_bytes
from relight.errors import InputError

F32 = NDArray[np.float32]

#: Lat-long EXR files with more pixels than this are streamed and downsampled (module docstring): 4096 x 2048.
STREAM_ABOVE_PIXELS: Final = 4096 * 2048
#: Rows of the downsample of a streamed map.
STREAM_ROWS: Final = 2048
#: Layouts :func:`read_envmap` accepts.
LAYOUTS: Final = ("auto", "latlong", *CUBE_LAYOUTS)


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


def read_image(src: Source, *, max_pixels: int | None = None) -> tuple[F32, str]:
    """Decode an EXR, HDR, PNG or JPEG image to raw (H, W, 3) float32 linear RGB and its format name.

    No layout or value checks (used for lat-long maps and cube-map images alike); the size is checked
    against ``max_pixels`` from the header before any pixel is decoded.
    """
    hdr = probe(src)
    check_max_pixels(hdr, max_pixels)
    return _decode(src, hdr), hdr.format


def _decode(src: Source, hdr: ImageHeader) -> F32:
    buf = read_all(src)
    if probe_bytes(buf) != hdr:  # the checked header must be the one decoded
        raise InputError(f"{src if isinstance(src, str) else 'the file'} changed while it was being read")
    if hdr.format == "exr":
        rgb = exr.decode(buf)
    elif hdr.format == "hdr":
        rgb = rgbe.decode(buf, rgbe.parse_header(buf))
    else:
        from relight.envmap import ldr  # Pillow loads only for PNG / JPEG (an EXR job's start-up skips it)

        rgb = ldr.decode(buf, hdr)
    if rgb.shape != (hdr.height, hdr.width, 3):
        raise InputError(f"decoded image has shape {rgb.shape}, but its header says {hdr.width} x {hdr.height}")
    return rgb


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
    check_latlong_shape(arr.shape)
    pixels, count, mn = _validate(arr)
    return EnvMap(pixels, source_format, count, mn)


def envmap_from_cube(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating], height: int | None = None,
                     *, source_format: str = "cube") -> EnvMap:
    """Validate in-memory cube faces (see :func:`relight.envmap.cubemap.cube_to_latlong`) and resample them to an
    :class:`EnvMap`. ``height`` defaults to twice the face size.
    """
    cube = faces_array(faces)
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


def read_envmap(src: Source, *, max_pixels: int | None = None, layout: str = "auto",
                max_rows: int | None = None) -> EnvMap:
    """Read and validate an environment map from a file path or its bytes.

    ``layout``: ``"latlong"`` (W = 2H), a cube-map layout (see :func:`cube_faces_from_image`: ``"strip-h"`` 6:1,
    ``"strip-v"`` 1:6, ``"cross-h"`` 4:3, ``"cross-v"`` 3:4), or ``"auto"`` to choose from the aspect ratio.
    Cube maps are resampled to a lat-long map of height 2 x face size (:func:`cube_to_latlong`).
    ``max_pixels`` limits the file's pixel count; it is checked from the header before decoding (and
    :data:`relight.envmap.formats.HARD_MAX_PIXELS` always applies). A lat-long EXR file above
    :data:`STREAM_ABOVE_PIXELS`, or taller than ``max_rows``, is streamed into its area-exact downsample to
    ``min(max_rows, STREAM_ROWS)`` rows (module docstring).
    """
    if layout not in LAYOUTS:
        raise InputError(f"unknown layout {layout!r}: expected one of {', '.join(LAYOUTS)}")
    hdr = probe(src)
    check_max_pixels(hdr, max_pixels)
    w, h = hdr.width, hdr.height
    if layout == "auto":
        layout = "latlong" if w == 2 * h else layout_for_size(w, h) or ""
        if not layout:
            raise InputError(f"image is {w} x {h}: an environment map must be a lat-long map with width = 2 x "
                             "height, or a cube map (6:1 or 1:6 strip, 4:3 or 3:4 cross)")
    elif layout == "latlong" and w != 2 * h:
        raise InputError(f"image is {w} x {h}: a lat-long map must have width = 2 x height")
    if max_rows is not None and max_rows < 1:
        raise InputError(f"max_rows must be positive, got {max_rows}")
    big = hdr.pixels > STREAM_ABOVE_PIXELS or (max_rows is not None and h > max_rows)
    if big and layout == "latlong" and hdr.format == "exr" and not isinstance(src, (bytes, bytearray, memoryview)):
        from relight.envmap.stream import stream_latlong

        s = stream_latlong(src, min(h, STREAM_ROWS, max_rows or STREAM_ROWS))
        return EnvMap(s.pixels, "exr", s.negatives_clamped, s.min_negative)
    rgb, fmt = _decode(src, hdr), hdr.format
    if layout == "latlong":
        pixels, count, mn = _validate(rgb)
        return EnvMap(pixels, fmt, count, mn)
    cube = cube_faces_from_image(rgb, layout)
    return _cube_envmap(cube, 2 * cube.shape[1], fmt, layout)
