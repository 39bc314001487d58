"""Measured error of an SHRM per view band against the angular brute force (issue 18; the project's metric,
``relight.metrics``, restricted to the texels whose view cosine falls in a band).

For a distant view V, texel R of the eq. 12 map (``relight.shrm.reflect``) and of the brute force
(``relight.reference_view.reference_view``, eq. 1 summed over the environment's pixels, independent of every SH
routine) belongs to the surface with normal ``N = normalize(R + V)``, so ``N.V = sqrt((1 + R.V) / 2)``. A band's
measured error is ``sqrt(sum dOmega (Y - Y_ref)^2 / sum dOmega Y_ref^2)`` over the texels of all the views given
with N.V in the band (solid-angle weighted, Rec. 709 luminance): the same average over orientations of the lighting
that ``relight.shrm.view_bands`` predicts when the views cover the sphere.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.conventions import latlong_dirs, luminance, pixel_solid_angles

FloatArray = NDArray[np.float64]


def spread_views(n: int, seed: int = 0) -> FloatArray:
    """``n`` unit view directions spread over the sphere (a Fibonacci lattice, rotated by ``seed``), (n, 3)."""
    if n < 1:
        raise ValueError(f"need at least one view, got {n}")
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5.0**0.5) * i + 2.0 * np.pi * (seed * 0.618033988749895 % 1.0)
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=-1)


@dataclass(frozen=True)
class BandSums:
    """Per band: ``sum dOmega (Y - Y_ref)^2`` (``err``), ``sum dOmega Y_ref^2`` (``ref``), texels, most negative
    luminance of the SHRM's texels (``min_value``; 0 when none is negative) and negative texels."""

    bands: tuple[tuple[float, float], ...]
    err: FloatArray
    ref: FloatArray
    texels: NDArray[np.intp]
    min_value: FloatArray
    negatives: NDArray[np.intp]
    #: Per band and view: the two sums (:func:`sample_by_view`), for :meth:`standard_error`.
    err_views: FloatArray | None = None
    ref_views: FloatArray | None = None

    def standard_error(self) -> FloatArray:
        """Jackknife standard error of :attr:`rms` over the views (leave one view out), per band; 0 without
        per-view sums. The measured figure is an average over orientations of the lighting: this is its noise."""
        if self.err_views is None or self.ref_views is None:
            return np.zeros(len(self.bands))
        e, r = self.err_views, self.ref_views
        n = e.shape[1]
        with np.errstate(invalid="ignore", divide="ignore"):
            loo = np.sqrt((e.sum(axis=1, keepdims=True) - e) / (r.sum(axis=1, keepdims=True) - r))
        loo = np.nan_to_num(loo)
        return np.asarray(np.sqrt((n - 1) / n * np.sum((loo - loo.mean(axis=1, keepdims=True)) ** 2, axis=1)),
                          dtype=np.float64)

    def merged(self, other: BandSums) -> BandSums:
        """These sums and ``other``'s (more views of the same bands) as one measurement."""
        if other.bands != self.bands:
            raise ValueError(f"cannot merge measurements of bands {self.bands} and {other.bands}")

        def cat(a: FloatArray | None, b: FloatArray | None) -> FloatArray | None:
            return None if a is None or b is None else np.concatenate([a, b], axis=1)

        return BandSums(bands=self.bands, err=self.err + other.err, ref=self.ref + other.ref,
                        texels=self.texels + other.texels, min_value=np.minimum(self.min_value, other.min_value),
                        negatives=self.negatives + other.negatives, err_views=cat(self.err_views, other.err_views),
                        ref_views=cat(self.ref_views, other.ref_views))

    @property
    def rms(self) -> FloatArray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.asarray(np.where(self.ref > 0.0, np.sqrt(self.err / self.ref), 0.0), dtype=np.float64)

    def as_dict(self) -> list[dict[str, Any]]:
        return [{"ndotv": list(b), "rms": float(r), "texels": int(n), "min_value": float(m), "negatives": int(k)}
                for b, r, n, m, k in zip(self.bands, self.rms, self.texels, self.min_value, self.negatives,
                                         strict=True)]


def band_sums(maps: Sequence[NDArray[np.floating]], refs: Sequence[NDArray[np.floating]],
              views: NDArray[np.floating], bands: Sequence[tuple[float, float]]) -> BandSums:
    """Accumulate :class:`BandSums` over pairs (SHRM map, reference map) of the given views, S x 2S each."""
    nb = len(bands)
    err, ref = np.zeros(nb), np.zeros(nb)
    cnt, neg = np.zeros(nb, dtype=np.intp), np.zeros(nb, dtype=np.intp)
    mins = np.zeros(nb)
    for a, r_map, v in zip(maps, refs, np.asarray(views, dtype=np.float64), strict=True):
        s = a.shape[0]
        r = latlong_dirs(s, 2 * s)
        v = v / np.linalg.norm(v)
        ndv = np.sqrt(np.clip((1.0 + r @ v) / 2.0, 0.0, 1.0))
        dom = np.broadcast_to(pixel_solid_angles(s, 2 * s)[:, None], (s, 2 * s))
        ya, yr = luminance(np.asarray(a, dtype=np.float64)), luminance(np.asarray(r_map, dtype=np.float64))
        for b, (lo, hi) in enumerate(bands):
            m = (ndv >= lo) & ((ndv < hi) if hi < 1.0 else (ndv <= hi))
            err[b] += float(np.sum(dom[m] * (ya[m] - yr[m]) ** 2))
            ref[b] += float(np.sum(dom[m] * yr[m] ** 2))
            cnt[b] += int(np.count_nonzero(m))
            if np.any(m):
                mins[b] = min(mins[b], float(np.min(np.asarray(a, dtype=np.float64)[m])))
                neg[b] += int(np.count_nonzero(np.min(np.asarray(a)[m], axis=-1) < 0.0))
    return BandSums(bands=tuple((float(lo), float(hi)) for lo, hi in bands), err=err, ref=ref, texels=cnt,
                    min_value=mins, negatives=neg)


def measure_by_view(shrm: Any, pixels: NDArray[np.floating], brdf: Any, views: NDArray[np.floating],
                    bands: Sequence[tuple[float, float]], *, size: int | None = None, clamp: bool = True) -> BandSums:
    """The SHRM's error per band against ``reference_view`` over ``views`` (module docstring); ``clamp`` as in
    ``relight.shrm.reflect``."""
    from relight.reference_view import reference_view
    from relight.shrm import reflect

    s = shrm.height if size is None else int(size)
    vs = np.asarray(views, dtype=np.float64).reshape(-1, 3)
    maps = [reflect(shrm, v, size=s, clamp=clamp) for v in vs]
    refs = [reference_view(pixels, brdf, v, s) for v in vs]
    return band_sums(maps, refs, vs, bands)


def sample_by_view(shrm: Any, pixels: NDArray[np.floating], brdf: Any, bands: Sequence[tuple[float, float]], *,
                   views: int = 100, per_view: int = 24, seed: int = 0, clamp: bool = True) -> BandSums:
    """Like :func:`measure_by_view` at a fraction of the cost, for orientation averages: ``views`` directions spread
    over the sphere and, for each view and band, ``per_view`` texels of the SHRM's own grid drawn at random among
    those whose N.V lies in the band (weighted by their solid angle). The SHRM is read at texel centres (eq. 12,
    no interpolation) once per view; the brute force is one ``reflected_radiance`` call per view at the normals of
    every band's texels.

    The defaults (2400 texels per band) keep the jackknife standard error within about a quarter of the measured
    figure on a map whose lamps are single pixels (city at 64 rows: 48 views of 6 texels left it above the figure
    itself, the error being carried by the few orientations that put a lamp in the lobe).
    """
    from relight.reference_view import reflected_radiance
    from relight.shrm import reflect
    from relight.shrm.geometry import halfway_normals

    s = shrm.height
    r = latlong_dirs(s, 2 * s).reshape(-1, 3)
    dom = np.broadcast_to(pixel_solid_angles(s, 2 * s)[:, None], (s, 2 * s)).reshape(-1)
    rng = np.random.default_rng(seed)
    nb = len(bands)
    cnt, neg = np.zeros(nb, dtype=np.intp), np.zeros(nb, dtype=np.intp)
    mins = np.zeros(nb)
    err_v, ref_v = np.zeros((nb, views)), np.zeros((nb, views))
    for j, v in enumerate(spread_views(views, seed=seed + 1)):
        ndv = np.sqrt(np.clip((1.0 + r @ v) / 2.0, 0.0, 1.0))
        picks, owner = [], []
        for b, (lo, hi) in enumerate(bands):
            cand = np.nonzero((ndv >= lo) & ((ndv < hi) if hi < 1.0 else (ndv <= hi)) & (ndv > 1e-6))[0]
            if cand.size:
                picks.append(rng.choice(cand, size=min(per_view, cand.size), replace=False))
                owner.append(np.full(picks[-1].size, b))
        if not picks:
            continue
        pick, band = np.concatenate(picks), np.concatenate(owner)
        a = reflect(shrm, v, clamp=clamp).reshape(-1, 3)[pick]
        n, _ = halfway_normals(r[pick], v)
        t = reflected_radiance(pixels, brdf, n, v)
        ya, yr = luminance(a), luminance(t)
        np.add.at(err_v[:, j], band, dom[pick] * (ya - yr) ** 2)
        np.add.at(ref_v[:, j], band, dom[pick] * yr**2)
        np.add.at(cnt, band, 1)
        np.minimum.at(mins, band, a.min(axis=-1))
        np.add.at(neg, band, (a.min(axis=-1) < 0.0).astype(np.intp))
    return BandSums(bands=tuple((float(lo), float(hi)) for lo, hi in bands), err=err_v.sum(axis=1),
                    ref=ref_v.sum(axis=1), texels=cnt, min_value=np.minimum(mins, 0.0), negatives=neg,
                    err_views=err_v, ref_views=ref_v)
