"""Mitsuba 3 as the oracle at the rim (issue 18): spheres with GGX and Beckmann microfacet lobes (exact Mitsuba twins,
``relight.mitsuba_twin``) seen along +Z, compared pixel by pixel over the ring 0.1 <= N.V <= 0.3 and the interior
N.V >= 0.3 — the views ``tests/relight/test_mitsuba_oracle.py`` leaves out (it keeps N.V >= 0.6).

Scene: courtyard area-averaged to 32 x 64 rows, shown to Mitsuba piecewise constant (``mitsuba_bitmap``, 8 texels
per pixel edge); a 64 x 64 orthographic image, 1024 samples per pixel (``moment`` integrator: per-pixel variances).
Pixels count when their centre's N.V lies in the band and their whole footprint is on the sphere. relight's images
average 4 x 4 samples per pixel (Mitsuba's box filter integrates the pixel: at the rim N changes across a pixel).

Checks, on relative RMS over a band's pixels (luminance):

1. the angular brute force (``reflected_radiance``, the reference of the view-band tests) agrees with Mitsuba within
   ``2 noise + 1 %``: ``noise`` is the relative RMS of Mitsuba's per-pixel standard deviations (its expected error
   against the truth); 1 % is the texel allowance the block oracle measured for Mitsuba's bilinear seams against
   relight's pixel-centre quadrature (0.1–0.6 % at these map sizes);
2. the SHRM at the orders of epsilon = 0.01 (clamped radiance, never negative) is within its predicted error per
   band (``predicted_by_view``'s ``rms``) of Mitsuba, with the same noise and texel terms added in quadrature, and
   within it of the brute force (no noise).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pytest

from relight.brdf.spec import parse_brdf
from relight.conventions import luminance
from relight.envmap import read_envmap, resample_latlong
from relight.mitsuba_twin import mitsuba_bitmap, render_sphere_mitsuba, texels_per_pixel, twin
from relight.prefilter import project_lighting
from relight.reference_view import reflected_radiance
from relight.resources import sample_envmaps
from relight.shrm import create_shrm, order_search, render_sphere, sphere_geometry
from relight.shrm.creation import spectrum_order
from relight.shrm.view_bands import predicted_by_view
from relight.shrm.view_spectrum import band_edges

SIZE, SS, SPP, ROWS = 64, 4, 1024, 32
VIEW = np.array([0.0, 0.0, 1.0])
BANDS = ((0.1, 0.3), (0.3, 1.0))
TEXEL = 0.01  # module docstring, check 1


@cache
def courtyard() -> np.ndarray:
    root = sample_envmaps()
    assert root is not None, "the sample maps are package data (relight.data)"
    return np.asarray(resample_latlong(read_envmap(root / "courtyard.exr").pixels, ROWS), dtype=np.float64)


def _band_masks() -> list[np.ndarray]:
    n, on = sphere_geometry(VIEW, SIZE)
    c = (np.arange(SIZE) + 0.5) * 2.0 / SIZE - 1.0
    x, y = np.meshgrid(c, -c)
    far = np.hypot(np.abs(x) + 1.0 / SIZE, np.abs(y) + 1.0 / SIZE)  # the pixel's farthest corner
    ndv = n[..., 2]
    return [on & (far < 1.0) & (ndv >= lo) & (ndv <= hi) for lo, hi in BANDS]


def _area_mean(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(SIZE*SS)^2 samples averaged per pixel, read at the pixels of ``mask``."""
    return values.reshape(SIZE, SS, SIZE, SS).mean(axis=(1, 3))[mask]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.sum((a - b) ** 2) / np.sum(b**2)))


@pytest.mark.slow
@pytest.mark.parametrize("spec", ["ggx:alpha=0.3", "torrance-sparrow:alpha=0.3,distribution=beckmann"])
def test_rim_against_mitsuba(spec: str) -> None:
    px = courtyard()
    lobe = parse_brdf(spec)
    bsdf: dict[str, Any] | None = twin(lobe)
    assert bsdf is not None and bsdf["type"] == "roughconductor"
    render = render_sphere_mitsuba(mitsuba_bitmap(px, texels_per_pixel(px.shape[1])), bsdf, SIZE, SPP, view=VIEW)
    sm = create_shrm(px, lobe, epsilon=0.01, size=64)
    comp = sm.components[0]
    img = render_sphere(sm, VIEW, SIZE * SS)
    assert img.min() >= 0.0  # clamped radiance (relight.shrm.evaluation)
    vs = order_search.cached_spectrum(lobe, spectrum_order(comp.F, ROWS - 1), comp.P, band_edges(0.1))
    pred = predicted_by_view(vs, project_lighting(px, min(vs.F, ROWS - 1)), comp.F, comp.P, bands=BANDS)
    n_fine, on_fine = sphere_geometry(VIEW, SIZE * SS)
    for band, mask, p in zip(BANDS, _band_masks(), pred, strict=True):
        assert mask.sum() >= 100, (band, int(mask.sum()))
        truth = render.luminance[mask]
        noise = float(np.sqrt(np.sum(render.variance[mask]) / np.sum(truth**2)))
        pix = np.zeros((SIZE * SS, SIZE * SS))
        pick = np.repeat(np.repeat(mask, SS, axis=0), SS, axis=1) & on_fine
        pix[pick] = luminance(reflected_radiance(px, lobe, n_fine[pick], VIEW))
        ref = _area_mean(pix, mask)
        shrm = _area_mean(luminance(img), mask)
        err_ref, err_shrm, err_trunc = _rel(ref, truth), _rel(shrm, truth), _rel(shrm, ref)
        print(f"{spec} N.V in {band}: {int(mask.sum())} px, noise {noise:.4f}, brute force vs Mitsuba {err_ref:.4f}, "
              f"SHRM (F={comp.F}, P={comp.P}) vs Mitsuba {err_shrm:.4f}, vs brute force {err_trunc:.4f}, "
              f"predicted {p.rms:.4f} (average {p.rms_average:.4f})")
        assert err_ref <= 2.0 * noise + TEXEL, (band, err_ref, noise)
        assert err_shrm <= float(np.hypot(p.rms, 2.0 * noise + TEXEL)), (band, err_shrm, p.rms, noise)
        assert err_trunc <= p.rms, (band, err_trunc, p.rms)
