"""2-D maps of the view hemisphere for per-view SH tables (seed 003 §3: "a parabolic parameterization of the
hemisphere of directions v ... 128 x 128 textures").

Texel ``(i, j)`` of an R x R map sits at ``px = 2 (j + 1/2) / R - 1`` (columns, local x increasing) and
``py = 2 (i + 1/2) / R - 1`` (rows, local y increasing), i.e. texture coordinates ``u = (px + 1) / 2``,
``v = (py + 1) / 2`` with row 0 at v = 0 (``docs/conventions.md``, "SH tables").

* ``parabolic`` (Heidrich & Seidel 1999, the paper's choice): ``(x, y, z) -> (x, y) / (1 + z)``; a texel centre
  inside the unit disk is ``v = (2 px, 2 py, 1 - r^2) / (1 + r^2)``; the 21.5 % of texels outside it are *rim
  texels*, filled from the rim direction ``(px, py) / r`` raised to ``z = RIM_Z`` (so that bilinear filtering next
  to the rim mixes only rim values; ``valid`` is False there).
* ``hemi-octahedral``: the upper half of the octahedral map folded onto the square rotated by 45 degrees,
  ``a = (px + py) / 2``, ``b = (px - py) / 2``, ``v = normalize(a, b, 1 - |a| - |b|)``; the square's border is the
  rim, every texel is valid and texel solid angles vary by a factor ~2 instead of 4.

Views below the horizon (interpolated normals) are clamped to the rim before the lookup (:func:`view_to_texel`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.errors import InputError

FloatArray = NDArray[np.float64]
Layout = Literal["parabolic", "hemi-octahedral"]
LAYOUTS: tuple[Layout, ...] = ("parabolic", "hemi-octahedral")

#: z of the "rim direction": 1e-3 (0.057 degrees above the horizon). At exactly z = 0 every BRDF here is 0 by its
#: hemisphere test although its limit is not (Smith G1 / cos -> 2 / alpha), so the rim is taken just above it.
RIM_Z = 1e-3


def check_layout(layout: str) -> Layout:
    if layout not in LAYOUTS:
        raise InputError(f"unknown view-map layout {layout!r}; valid layouts are {list(LAYOUTS)}")
    return layout


def texel_coords(resolution: int) -> tuple[FloatArray, FloatArray]:
    """(px, py) of every texel centre, each (R, R) indexed [row, column]."""
    c = 2.0 * (np.arange(resolution) + 0.5) / resolution - 1.0
    py, px = np.meshgrid(c, c, indexing="ij")
    return px, py


def _rim(x: FloatArray, y: FloatArray) -> FloatArray:
    r = np.hypot(x, y)
    safe = np.where(r > 0.0, r, 1.0)
    s = np.sqrt(1.0 - RIM_Z * RIM_Z)
    return np.stack([np.where(r > 0.0, x / safe, 1.0) * s, np.where(r > 0.0, y / safe, 0.0) * s,
                     np.full_like(x, RIM_Z)], axis=-1)


def map_views(layout: str, resolution: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Unit local view direction of every texel (R, R, 3) and the mask of texels inside the map's domain (R, R)."""
    layout = check_layout(layout)
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or not 2 <= resolution <= 4096:
        raise InputError(f"the view-map resolution must be an integer in [2, 4096], got {resolution!r}")
    px, py = texel_coords(int(resolution))
    if layout == "parabolic":
        r2 = px * px + py * py
        inside = r2 <= 1.0
        v = np.stack([2.0 * px, 2.0 * py, 1.0 - r2], axis=-1) / (1.0 + r2)[..., None]
        v = np.where((inside & (v[..., 2] >= RIM_Z))[..., None], v, _rim(px, py))
        return np.asarray(v, dtype=np.float64), np.asarray(inside)
    a, b = 0.5 * (px + py), 0.5 * (px - py)
    v = np.stack([a, b, 1.0 - np.abs(a) - np.abs(b)], axis=-1)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return np.asarray(v, dtype=np.float64), np.ones(px.shape, dtype=bool)


def clamp_to_hemisphere(views: ArrayLike) -> FloatArray:
    """Unit views with z < RIM_Z moved to the rim direction of their azimuth (z = RIM_Z); (0, 0, -1) -> +x rim."""
    v = np.asarray(views, dtype=np.float64)
    v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)
    low = v[..., 2] < RIM_Z
    return np.asarray(np.where(low[..., None], _rim(v[..., 0], v[..., 1]), v), dtype=np.float64)


def view_to_texel(layout: str, resolution: int, views: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Continuous texel coordinates (column x, row y) of local views (..., 3) (texel centres at integers)."""
    layout = check_layout(layout)
    v = clamp_to_hemisphere(views)
    if layout == "parabolic":
        px, py = v[..., 0] / (1.0 + v[..., 2]), v[..., 1] / (1.0 + v[..., 2])
    else:
        s = np.abs(v[..., 0]) + np.abs(v[..., 1]) + v[..., 2]
        a, b = v[..., 0] / s, v[..., 1] / s
        px, py = a + b, a - b
    return (px + 1.0) * 0.5 * resolution - 0.5, (py + 1.0) * 0.5 * resolution - 0.5


def bilinear(grid: FloatArray, x: FloatArray, y: FloatArray) -> FloatArray:
    """Bilinear lookup of ``grid`` (R, R, ...) at continuous texel coordinates (clamped to the edge texels)."""
    r = grid.shape[0]
    x = np.clip(x, 0.0, r - 1.0)
    y = np.clip(y, 0.0, r - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.intp), r - 2)
    y0 = np.minimum(np.floor(y).astype(np.intp), r - 2)
    fx, fy = x - x0, y - y0
    extra = (None,) * (grid.ndim - 2)
    fx, fy = fx[(...,) + extra], fy[(...,) + extra]
    top = grid[y0, x0] * (1.0 - fx) + grid[y0, x0 + 1] * fx
    bot = grid[y0 + 1, x0] * (1.0 - fx) + grid[y0 + 1, x0 + 1] * fx
    return np.asarray(top * (1.0 - fy) + bot * fy, dtype=np.float64)
