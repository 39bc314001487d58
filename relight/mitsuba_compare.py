"""relight's maps against the Mitsuba 3 sphere (``relight.mitsuba_twin``): block means of the sphere image,
relight's own sphere image of an output map, and the relative RMS of one against the other with Mitsuba's Monte
Carlo noise floor (:class:`TwinSettings`, :func:`compare_sphere`). ``relight.tradeoff`` records each point's error
this way; the mesh and PRT oracle tests use the block helpers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import luminance
from relight.errors import InputError, RelightError
from relight.mitsuba_twin import (
    SphereRender,
    check_bitmap_shape,
    mitsuba_bitmap,
    render_sphere_mitsuba,
    texels_per_pixel,
)

FloatArray = NDArray[np.float64]


# ------------------------------------------------------------------------------------------------- blocks
def block_mean(img: NDArray[np.floating], b: int) -> FloatArray:
    """Means over b x b blocks of an (n, n, ...) image (n divisible by b)."""
    a = np.asarray(img, dtype=np.float64)
    n = a.shape[0] // b
    return np.asarray(a.reshape((n, b, n, b) + a.shape[2:]).mean(axis=(1, 3)), dtype=np.float64)


def block_far_radius(size: int, b: int) -> FloatArray:
    """For each b x b block of a ``size``-pixel image of the frame [-1, 1]^2: the largest distance of its area
    from the centre (its farthest corner), i.e. the largest ``sin`` of the angle between N and V on it."""
    edges = np.arange(0, size + 1, b) * 2.0 / size - 1.0
    far = np.maximum(np.abs(edges[:-1]), np.abs(edges[1:]))
    return np.asarray(np.hypot(far[:, None], far[None, :]), dtype=np.float64)


def sphere_from_map(latlong: NDArray[np.floating], view: NDArray[np.floating] | tuple[float, float, float],
                    size: int, *, center: str = "R", supersample: int = 1) -> FloatArray:
    """relight's sphere image (size, size, C) of an output map: what ``relight.shrm.render_sphere`` shows.

    ``latlong`` is an (S, 2S, C) map indexed by the lobe's centre direction (``docs/conventions.md``): R for R-centred
    maps and for every view map of ``relight.shrm.reflect`` / ``relight.reference_view`` (they are indexed by R
    whatever the lobe's centre), N for the N-centred map of a Lambertian lobe. Each sub-pixel of the
    :func:`relight.shrm.sphere_geometry` camera at ``size * supersample`` takes its normal N, ``R = 2 (N.V) N - V``
    and the bilinear lookup ``relight.conventions.sample_latlong`` at its centre; the ``supersample x supersample``
    sub-pixels of each pixel are averaged (Mitsuba's box filter averages over the pixel's area). Off the sphere: 0.
    """
    from relight.conventions import sample_latlong
    from relight.shrm import lobe_centres, reflect_dirs, sphere_geometry, unit_view

    m = np.asarray(latlong, dtype=np.float64)
    if m.ndim != 3 or m.shape[1] != 2 * m.shape[0]:
        raise InputError(f"need an (S, 2S, C) lat-long map, got shape {m.shape}")
    validate.at_least("size", size, 1)
    validate.at_least("supersample", supersample, 1)
    v = unit_view(view)
    n, mask = sphere_geometry(v, size * supersample)
    nn = n[mask]
    c = lobe_centres(center, nn, reflect_dirs(nn, v))
    img = np.zeros(mask.shape + (m.shape[2],))
    img[mask] = sample_latlong(m[None], c)[:, 0]
    return block_mean(img, supersample)


# ------------------------------------------------------------------------------------------------ comparison
@dataclass(frozen=True)
class TwinSettings:
    """How relight's maps are compared with Mitsuba's sphere image (``relight.tradeoff``'s defaults).

    ``size`` x ``size`` pixels, ``spp`` samples per pixel (seed ``seed``), compared on ``block`` x ``block`` means of
    luminance over the blocks lying entirely within image radius ``radius`` (the angle between N and V at most
    ``asin(radius)``: 53 degrees for 0.8; grazing is excluded), relight's image supersampled ``supersample`` x
    ``supersample`` per pixel, the map shown to Mitsuba with ``texels`` texels per pixel edge (at most; see
    :func:`texels_per_pixel`). The defaults put the noise floor (:attr:`SphereComparison.noise`) at 1.5–5.5e-3 on
    the sample maps at 64 rows (``relight.tradeoff``) for 2–6 s of ``llvm_ad_rgb`` on 2 cores; the floor falls as
    ``1 / sqrt(spp * block^2)`` and the time grows as ``spp * size^2``.
    """

    size: int = 64
    block: int = 4
    spp: int = 8192
    radius: float = 0.8
    supersample: int = 4
    texels: int = 8
    seed: int = 0

    def __post_init__(self) -> None:
        if self.size < 1 or self.block < 1 or self.size % self.block:
            raise InputError(f"the Mitsuba image size must be a multiple of the block, got {self.size}, {self.block}")
        validate.at_least("spp", self.spp, 1)
        validate.at_least("supersample", self.supersample, 1)
        validate.at_least("texels", self.texels, 2)
        validate.in_range("the compared radius", self.radius, 0.0, 1.0, lo_open=True)

    def mask(self) -> NDArray[np.bool_]:
        """The compared blocks: those whose whole area lies within the radius."""
        return np.asarray(block_far_radius(self.size, self.block) <= self.radius)

    def crop(self) -> tuple[int, int, int, int]:
        """The smallest pixel window ``(x, y, width, height)`` holding every compared block (rendered alone)."""
        idx = np.flatnonzero(self.mask().any(axis=0))
        if idx.size == 0:
            raise InputError(f"no {self.block} x {self.block} block of a {self.size}-pixel image lies within radius "
                             f"{self.radius:g}")
        lo, hi = int(idx[0]) * self.block, (int(idx[-1]) + 1) * self.block
        return lo, lo, hi - lo, hi - lo


@dataclass(frozen=True)
class SphereComparison:
    """Mitsuba's sphere image reduced to the compared blocks, and relative RMS errors of relight maps against it.

    ``truth`` and ``sigma`` are the compared blocks' Mitsuba luminance means and their Monte Carlo standard deviations
    (from the ``moment`` integrator: with a box filter the pixels are independent, so a block's variance is the sum
    of its pixels' over ``block^4``).
    """

    settings: TwinSettings
    bsdf: dict[str, Any]
    view: FloatArray
    texels: int
    truth: FloatArray
    sigma: FloatArray
    render: SphereRender

    @property
    def noise(self) -> float:
        """Relative RMS of the blocks' Monte Carlo standard deviations: the expected error of a perfect relight map
        (the noise floor), in the metric of :meth:`error`."""
        return float(np.sqrt(np.sum(self.sigma**2) / np.sum(self.truth**2)))

    def blocks(self, latlong: NDArray[np.floating], center: str = "R") -> FloatArray:
        """relight's image of ``latlong`` (:func:`sphere_from_map`) reduced to the compared blocks' luminance."""
        s = self.settings
        img = sphere_from_map(latlong, self.view, s.size, center=center, supersample=s.supersample)
        return block_mean(luminance(img), s.block)[s.mask()]

    def error(self, latlong: NDArray[np.floating], center: str = "R") -> float:
        """Relative RMS over the compared blocks of relight's image of ``latlong`` against Mitsuba's
        (:func:`block_rms`)."""
        return block_rms(self.blocks(latlong, center), self.truth)


def block_rms(blocks: NDArray[np.floating], truth: NDArray[np.floating]) -> float:
    """Relative RMS of block means against the true ones: ``sqrt(sum (blocks - truth)^2 / sum truth^2)``."""
    a = np.asarray(blocks, dtype=np.float64)
    t = np.asarray(truth, dtype=np.float64)
    return float(np.sqrt(np.sum((a - t) ** 2) / np.sum(t * t)))


def compare_sphere(pixels: NDArray[np.floating], bsdf: dict[str, Any],
                   view: NDArray[np.floating] | tuple[float, float, float],
                   settings: TwinSettings | None = None) -> SphereComparison:
    """Render ``bsdf`` on the unit sphere under the lat-long map ``pixels`` (negative texels clamped to 0) seen along
    V and keep the compared blocks (:class:`SphereComparison`). InputError for a map :func:`mitsuba_bitmap` cannot
    show exactly; RelightError when Mitsuba cannot run here."""
    from relight.shrm import unit_view

    s = settings or TwinSettings()
    p = np.maximum(np.asarray(pixels, dtype=np.float64), 0.0)
    reason = check_bitmap_shape(p.shape)
    if reason is not None:
        raise InputError(reason)
    up = texels_per_pixel(p.shape[1], s.texels)
    v = unit_view(view)
    render = render_sphere_mitsuba(mitsuba_bitmap(p, up), bsdf, s.size, s.spp, view=v, seed=s.seed, crop=s.crop())
    mask = s.mask()
    truth = block_mean(render.luminance, s.block)[mask]
    sigma = np.sqrt(block_mean(render.variance, s.block)[mask] / s.block**2)
    if not np.all(np.isfinite(truth)) or not np.any(truth > 0.0):
        raise RelightError("Mitsuba's sphere image is black or not finite on the compared blocks")
    return SphereComparison(settings=s, bsdf=bsdf, view=v, texels=up, truth=truth, sigma=sigma, render=render)

