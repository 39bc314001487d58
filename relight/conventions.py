"""The project's direction and pixel conventions, written once.

See ``docs/conventions.md`` for the prose version. Summary:

* Lat-long (equirectangular) maps follow three.js ``equirectUv``, +Y up. For an ``H x W`` map, row ``i``
  (0 = top row of the file) and column ``j``::

      elev = pi/2 - (i + 0.5) * pi / H        phi = ((j + 0.5) / W - 0.5) * 2 pi
      d    = (cos(elev) cos(phi), sin(elev), cos(elev) sin(phi))

* Spherical-harmonic angles: polar angle ``theta`` is measured from +Y (``theta = pi/2 - elev``), so row ``i``
  is the ring ``theta_i = (i + 0.5) pi / H`` (ducc0 geometry ``F1``); azimuth ``phi`` as above, so column ``j``
  sits at ``phi_j = -pi + (j + 0.5) 2 pi / W`` (ducc0 ``phi0 = pi / W - pi``).
  Equivalently the SH frame is ``(x', y', z') = (X, Z, Y)``: ``x' = sin(theta) cos(phi)``,
  ``y' = sin(theta) sin(phi)``, ``z' = cos(theta)``.
* The paper's (alpha, beta) for the reflection vector R are exactly these (theta, phi) of R.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: Largest accepted texel magnitude: energies (squares summed over ~1e8 texels) stay far inside float64's range
#: (1e308). Every float32 value (EXR files: at most 3.4e38) is accepted.
MAX_RADIANCE = 1e100

#: Rec. 709 / sRGB luminance weights (ITU-R BT.709-6, item 3.2).
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def ring_thetas(height: int) -> FloatArray:
    """Polar angle from +Y of each row's centre: ``theta_i = (i + 0.5) pi / H``."""
    validate.positive_int("height", height)
    return (np.arange(height) + 0.5) * np.pi / height


def column_phis(width: int) -> FloatArray:
    """Azimuth of each column's centre: ``phi_j = ((j + 0.5) / W - 0.5) 2 pi``."""
    validate.positive_int("width", width)
    return ((np.arange(width) + 0.5) / width - 0.5) * 2.0 * np.pi


def phi0(width: int) -> float:
    """ducc0's ``phi0`` (azimuth of the first column) for a pixel-centred row of ``width`` pixels."""
    return float(np.pi / width - np.pi)


def angles_to_dirs(theta: NDArray[np.floating], phi: NDArray[np.floating]) -> FloatArray:
    """World directions (..., 3) for SH angles (theta from +Y, phi as in the lat-long map)."""
    theta = np.asarray(theta, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    st = np.sin(theta)
    return np.stack(np.broadcast_arrays(st * np.cos(phi), np.cos(theta), st * np.sin(phi)), axis=-1)


def dirs_to_angles(d: NDArray[np.floating]) -> tuple[FloatArray, FloatArray]:
    """(theta, phi) of world directions (..., 3); they need not be normalised."""
    d = np.asarray(d, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"directions must have a trailing axis of length 3, got shape {d.shape}")
    n = np.linalg.norm(d, axis=-1)
    if np.any(n == 0):
        raise ValueError("zero-length direction")
    # atan2 keeps full precision next to the poles, where arccos(d.y) loses half the digits
    theta = np.arctan2(np.hypot(d[..., 0], d[..., 2]), d[..., 1])
    phi = np.arctan2(d[..., 2], d[..., 0])
    return theta, phi


def latlong_dirs(height: int, width: int) -> FloatArray:
    """Unit direction of every pixel centre of an ``H x W`` lat-long map, shape (H, W, 3)."""
    t = ring_thetas(height)[:, None]
    p = column_phis(width)[None, :]
    return angles_to_dirs(t, p)


def dirs_to_pixel(d: NDArray[np.floating], height: int, width: int) -> tuple[FloatArray, FloatArray]:
    """Continuous pixel coordinates (row, col) of directions, pixel centres at integer + 0.5 - 0.5.

    Returns ``(y, x)`` such that pixel ``(i, j)``'s centre maps to ``(i, j)`` exactly.
    """
    theta, phi = dirs_to_angles(d)
    y = theta / np.pi * height - 0.5
    x = (phi / (2.0 * np.pi) + 0.5) * width - 0.5
    return y, x


def bilinear_latlong(image: NDArray[np.floating], y: NDArray[np.floating], x: NDArray[np.floating]) -> FloatArray:
    """Bilinear lookup of an (H, W, ...) lat-long image at continuous pixel coordinates (``y``, ``x``), broadcast.

    Pixel centres are at integer coordinates (:func:`dirs_to_pixel`); columns wrap around in ``phi``, rows clamp
    at the poles. Returns ``broadcast(y, x).shape + image.shape[2:]``.
    """
    h, w = image.shape[:2]
    y, x = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    shape, tail = y.shape, image.shape[2:]
    y = np.clip(y.ravel(), 0.0, h - 1.0)
    y0 = np.minimum(y.astype(np.intp), max(h - 2, 0))  # y >= 0: the cast is the floor
    fy = (y - y0)[:, None]
    y1 = np.minimum(y0 + 1, h - 1)
    x0f = np.floor(x.ravel())
    fx = (x.ravel() - x0f)[:, None]
    x0 = np.mod(x0f.astype(np.intp), w)
    x1 = x0 + 1
    x1[x1 == w] = 0
    # gathers from the flattened image (one index per texel, rows of the trailing channels) are 2-3x faster than
    # fancy indexing on two axes
    flat = np.asarray(image).reshape(h * w, -1)
    r0, r1 = y0 * w, y1 * w
    top = flat.take(r0 + x0, axis=0) * (1.0 - fx) + flat.take(r0 + x1, axis=0) * fx
    bot = flat.take(r1 + x0, axis=0) * (1.0 - fx) + flat.take(r1 + x1, axis=0) * fx
    return np.asarray(top * (1.0 - fy) + bot * fy, dtype=np.float64).reshape(shape + tail)


def sample_latlong(maps: NDArray[np.floating], dirs: NDArray[np.floating]) -> FloatArray:
    """The lat-long sampler: bilinear lookup of lat-long maps (K, H, W, C) at directions (N, 3) -> (N, K, C).

    Directions map to pixel coordinates by :func:`dirs_to_pixel`; :func:`bilinear_latlong` interpolates.
    """
    _, h, w, _ = maps.shape
    y, x = dirs_to_pixel(dirs, h, w)
    return bilinear_latlong(np.moveaxis(maps, 0, 2), y, x)


def pixel_solid_angles(height: int, width: int) -> FloatArray:
    """Exact solid angle of each row's pixels (H,): ``(2 pi / W) (cos theta_top - cos theta_bottom)``."""
    edges = np.arange(height + 1) * np.pi / height
    return (2.0 * np.pi / width) * (np.cos(edges[:-1]) - np.cos(edges[1:]))


def luminance(rgb: NDArray[np.floating]) -> FloatArray:
    """Rec. 709 luminance of (..., 3) linear RGB (a single channel (...,) passes through)."""
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.ndim >= 1 and rgb.shape[-1] == 3:
        return np.asarray(rgb @ LUMINANCE_WEIGHTS, dtype=np.float64)
    return np.asarray(rgb, dtype=np.float64)


def check_latlong_shape(shape: tuple[int, ...]) -> tuple[int, int]:
    """Validate an (H, W[, C]) lat-long shape with W = 2H; return (H, W). Raises InputError (a ValueError)."""
    if len(shape) < 2:
        raise InputError(f"a lat-long map needs at least 2 dimensions, got shape {shape}")
    h, w = int(shape[0]), int(shape[1])
    if h == 0 or w == 0:
        raise InputError(f"a lat-long map cannot be empty, got {w} x {h}")
    if w != 2 * h:
        raise InputError(f"a lat-long map must have width = 2 x height, got {w} x {h}")
    return h, w


def require_rgb_latlong(pixels: NDArray[np.floating]) -> NDArray[np.floating]:
    """The environment-map array every prefilter accepts: (H, W, 3), W = 2H, real and finite.

    Raises InputError quoting the shape, or the count and first position of non-finite texels.
    """
    a = np.asarray(pixels)
    check_latlong_shape(a.shape)
    if a.ndim != 3 or a.shape[2] != 3:
        raise InputError(f"expected an (H, W, 3) RGB lat-long map, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.floating) and not np.issubdtype(a.dtype, np.integer):
        raise InputError(f"environment-map pixels must be real numbers, got dtype {a.dtype}")
    bad = ~np.isfinite(a)
    if bad.any():
        i, j, _ = np.argwhere(bad)[0]
        raise InputError(
            f"{int(bad.sum())} non-finite pixel values (NaN/Inf), first at row {int(i)}, column {int(j)}"
        )
    wide = a.dtype.kind == "f" and a.dtype.itemsize >= 8  # narrower types cannot hold such values
    huge = np.abs(a) > MAX_RADIANCE if wide else np.zeros(a.shape, bool)
    if huge.any():
        i, j, _ = np.argwhere(huge)[0]
        raise InputError(
            f"{int(huge.sum())} pixel values beyond {MAX_RADIANCE:g} (not radiance: their energy would overflow), "
            f"first at row {int(i)}, column {int(j)}"
        )
    return a
