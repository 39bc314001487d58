"""Mitsuba 3 as an external oracle for relight's Torrance–Sparrow SHRM (seed 000 §4, §7.5).

Scene (``tests/mitsuba_scene.py`` has the conventions): a unit sphere, Mitsuba ``roughconductor`` with
``distribution="beckmann"``, ``material="none"`` (F = 1), ``alpha`` in {0.05, 0.2, 0.5}, under sample maps
area-averaged with ``relight.envmap.resample_latlong``; orthographic camera on +Z (V = +Z for every pixel), 64 x 64
pixels, 4096 samples per pixel, direct light only. relight renders the same sphere with
``create_shrm(..., TorranceSparrow(alpha, "beckmann", fresnel="none"))`` and ``render_sphere``.

Both renderers see the same radiance: the map is read as piecewise constant, handed to Mitsuba exactly
(``mitsuba_scene.mitsuba_bitmap``, 8 texels per pixel edge) and to relight split 4 x 4 (the same function on a
finer pixel grid, so relight's pixel quadrature integrates it more accurately). The conversion is checked
directly (the emitter's radiance equals relight's pixel values; the BSDF equals relight's model), and on an image
(a small light's highlight lands where relight puts it; a mirrored map does not).

Comparison on 8 x 8 blocks of Rec. 709 luminance, over the blocks whose whole area lies within image radius
``R_MAX`` = 0.8 (the angle between N and V at most 53 degrees, so theta_o = angle(R, V) <= 106 degrees). Outside it:
the outermost blocks straddle the silhouette, and toward grazing the reflection-vector reparameterised lobe
narrows like cos(theta_v) and needs unbounded orders (seed 000 §3.1 / App. C) — relight's own report, whose
predicted error is for all view angles up to grazing (``rms_brdf`` 0.2–0.3 at these orders), is dominated there.
Per block, ``|relight - Mitsuba| <= K * sigma + trunc + texel + foot`` where

* ``sigma``: the Monte Carlo standard deviation of Mitsuba's block mean, estimated from the render itself (the
  ``moment`` integrator's per-pixel second moments over 4096 samples; pixels are independent with a box filter);
  ``K = 4`` (two-sided 6e-5 per block for Gaussian noise; the variance estimate itself has 4096 x 64 samples).
* ``trunc``: relight's truncation (orders F, P) and output-map interpolation error on that block, measured against
  relight's brute-force angular reference (``reference_sphere``, eq. 1 summed over the map's pixels, no SH) at the
  same sample points. The report's predicted error is whole-light-field and far larger (see above); the test
  checks that every measured block error stays below it.
* ``texel``: the residual difference between Mitsuba's integral of the piecewise-constant map (with its bilinear
  seams) and relight's pixel-centre quadrature on the 4 x 4 split map. Both are second order in the pixel size:
  midpoint rule ``-h^2/24 rho''`` per axis, seams ``+w^2/24 rho''`` (box of width w = h/8 across columns and
  h/4 across rows). Estimated from the change between relight on the original and on the split map,
  ``S(h) - S(h/4) = -(15/16) h^2/24 rho''``: the residual is at most ``(1/16 + 1/16 + 1/64) / (15/16) < 1/6`` of
  it; ``texel = |S(h) - S(h/4)| / 4``.
* ``foot``: relight samples pixel centres, Mitsuba integrates pixel areas: relight is supersampled 8 x 8 per pixel;
  the residual (convergence as 1/ss^2) is ``|S_8 - S_4| / 3``.

A stricter check removes ``trunc`` by adding the measured truncation error back with its sign — i.e. relight's
brute-force reference, carried to the same sampling and quadrature with the SHRM's differences — and asks for
agreement within ``K sigma + texel + foot``. The pooled mean over all compared blocks is held to the same terms
with the pooled sigma (and the pooled signed truncation error), which is several times tighter than a block.
Measured numbers are printed (``pytest -s``) and collected in ``RESULTS``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

mi = pytest.importorskip("mitsuba", reason="Mitsuba 3 (pip install mitsuba) is the external oracle of this module")

from mitsuba_scene import (  # noqa: E402 - after the skip: the helper needs mitsuba at call time only
    block_far_radius,
    block_mean,
    bsdf_eval,
    choose_variant,
    emitter_radiance,
    mitsuba_bitmap,
    nearest_upsample,
    render_sphere_mitsuba,
    texel_dirs,
)

from relight.brdf.models import TorranceSparrow  # noqa: E402
from relight.conventions import latlong_dirs, luminance  # noqa: E402
from relight.envmap import read_envmap, resample_latlong  # noqa: E402
from relight.reference_view import reference_sphere  # noqa: E402
from relight.shrm import SHRM, create_shrm, render_sphere  # noqa: E402

FloatArray = NDArray[np.float64]

DATA = Path(__file__).resolve().parents[1] / "data" / "envmaps"
MAPS = ("studio", "sunset")  # indoor lights ~300x the mean; low sun ~500x the mean at 128 rows
ALPHAS = (0.05, 0.2, 0.5)
VIEW = np.array([0.0, 0.0, 1.0])
SIZE = 64  # image pixels
BLOCK = 8
SPP = 4096
SEED = 0
UP_MITSUBA = 8  # Mitsuba texels per relight pixel edge
SPLIT = 4  # relight's map: each pixel split SPLIT x SPLIT
SS = 8  # relight supersampling per pixel edge (Mitsuba's box filter integrates the pixel area)
R_MAX = 0.8
K = 4.0


@dataclass(frozen=True)
class Setup:
    """Per alpha: map rows H (F <= H - 1 and pixels well below the lobe width), orders (F, P), SHRM rows S, and
    the supersampling of the reference (2 for the sharp lobe, whose highlights are about a pixel wide)."""

    rows: int
    F: int
    P: int
    size: int
    ss_ref: int


# alpha = 0.05: the lobe (about 2 alpha = 0.1 rad wide in R) needs F ~ 64; a 128-row map (0.025 rad pixels)
# supports it and the 192-row SHRM samples it at 0.016 rad. alpha = 0.5 is smooth enough for a 32-row map.
SETUPS = {
    0.05: Setup(rows=128, F=64, P=8, size=192, ss_ref=2),
    0.2: Setup(rows=64, F=32, P=12, size=128, ss_ref=1),
    0.5: Setup(rows=32, F=16, P=8, size=64, ss_ref=1),
}

RESULTS: dict[str, dict[str, Any]] = {}


@pytest.fixture(scope="module")
def variant() -> str:
    return choose_variant()


@cache
def envmap(name: str) -> FloatArray:
    """The sample map as relight reads it (negative texels from lossy compression clamped to 0)."""
    return np.asarray(read_envmap(DATA / f"{name}.exr").pixels, dtype=np.float64)


def sphere_lum(shrm: SHRM, ss: int) -> FloatArray:
    """relight's sphere image (global SHRM for V, exact for an orthographic camera) averaged over ss x ss samples
    per pixel, as luminance (SIZE, SIZE)."""
    img = render_sphere(shrm, VIEW, SIZE * ss, local=False)
    return luminance(block_mean(img, ss))


# --------------------------------------------------------------------------------------- convention checks
def test_emitter_radiance_is_relight_pixels(variant: str) -> None:
    """Mitsuba's envmap radiance equals relight's pixel value (float32) in every direction away from the seams;
    an asymmetric random map, so any mirror, rotation or half-pixel shift fails."""
    rng = np.random.default_rng(1)
    h = 16
    p = rng.random((h, 2 * h, 3)) * np.array([1.0, 2.0, 3.0])
    bitmap = mitsuba_bitmap(p, UP_MITSUBA)
    assert bitmap.shape == (UP_MITSUBA * h + 1, UP_MITSUBA * 2 * h, 3)
    i, j = rng.integers(0, h, 4000), rng.integers(0, 2 * h, 4000)
    off = 0.5 - 2.0 / UP_MITSUBA  # stay 2 texels clear of the pixel edges (the bilinear seams)
    fy, fx = rng.uniform(-off, off, (2, 4000))
    theta = (i + 0.5 + fy) * np.pi / h
    phi = ((j + 0.5 + fx) / (2 * h) - 0.5) * 2.0 * np.pi
    d = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], axis=-1)
    got = emitter_radiance(bitmap, d)
    np.testing.assert_allclose(got, p[i, j], rtol=1e-6, atol=0)
    # and the texel directions of mitsuba_scene are Mitsuba's: texel centres read back their own values (to the
    # float32 rounding of Mitsuba's direction -> texel coordinates; half a texel off would mix in the neighbours)
    rnd = rng.random((h * UP_MITSUBA + 1, h * UP_MITSUBA * 2, 3)).astype(np.float32) + 0.5
    td = texel_dirs(*rnd.shape[:2])
    y, x = rng.integers(1, rnd.shape[0] - 1, 500), rng.integers(0, rnd.shape[1], 500)
    np.testing.assert_allclose(emitter_radiance(rnd, td[y, x]), rnd[y, x], rtol=2e-3, atol=0)


@pytest.mark.parametrize("alpha", ALPHAS)
def test_bsdf_is_torrance_sparrow(variant: str, alpha: float) -> None:
    """Mitsuba's roughconductor (Beckmann, material="none") eval = relight's f_r cos(theta_light), to float32."""
    rng = np.random.default_rng(2)
    n = 5000
    view = rng.normal(size=(n, 3))
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    view[:, 2] = np.abs(view[:, 2]) + 0.05
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    mirror = 2.0 * view[:, 2:3] * np.array([0.0, 0.0, 1.0]) - view
    light = mirror + 1.5 * alpha * rng.normal(size=(n, 3))  # around the lobe
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    keep = light[:, 2] > 0.02
    view, light = view[keep], light[keep]
    got = bsdf_eval(alpha, view, light)
    want = TorranceSparrow(alpha).f(light, view, np.array([0.0, 0.0, 1.0]))[:, 0] * light[:, 2]
    big = want > 1e-3 * want.max()
    assert big.sum() > 1000
    np.testing.assert_allclose(got[big], want[big], rtol=1e-4)


def _highlight_centroid(lum: FloatArray) -> FloatArray:
    c = (np.arange(lum.shape[0]) + 0.5) * 2.0 / lum.shape[0] - 1.0
    x, y = np.meshgrid(c, -c)  # image right = +x, image up = +y
    return np.array([np.sum(lum * x), np.sum(lum * y)]) / np.sum(lum)


def test_small_light_highlight_position(variant: str) -> None:
    """A map lit only in a small cap around an asymmetric direction: Mitsuba's highlight lands where relight's
    does (and near the half-vector's image position); with the map mirrored (u -> 1 - u) it does not."""
    h, alpha = 64, 0.2
    light = np.array([0.45, 0.35, 0.82])
    light /= np.linalg.norm(light)
    p = np.where((latlong_dirs(h, 2 * h) @ light > np.cos(0.12))[..., None], np.array([1.0, 0.8, 0.6]), 0.0)
    n = 48
    ours = render_sphere(create_shrm(p, TorranceSparrow(alpha), order=24, p_order=6, size=64), VIEW, n)
    c_relight = _highlight_centroid(luminance(ours))
    bitmap = mitsuba_bitmap(p, UP_MITSUBA)
    c_mitsuba = _highlight_centroid(render_sphere_mitsuba(bitmap, alpha, n, 256).luminance)
    half = (light + VIEW) / np.linalg.norm(light + VIEW)
    assert np.linalg.norm(c_mitsuba - c_relight) < 0.02, (c_mitsuba, c_relight)
    assert np.linalg.norm(c_relight - half[:2]) < 0.05, (c_relight, half)
    mirrored = render_sphere_mitsuba(np.ascontiguousarray(bitmap[:, ::-1]), alpha, n, 256).luminance
    assert np.linalg.norm(_highlight_centroid(mirrored) - c_relight) > 0.3
    flipped = render_sphere_mitsuba(np.ascontiguousarray(bitmap[::-1]), alpha, n, 256).luminance
    assert np.linalg.norm(_highlight_centroid(flipped) - c_relight) > 0.3


# ------------------------------------------------------------------------------------------ the comparison
@dataclass
class Case:
    """Block statistics of one (map, alpha) comparison; arrays are (SIZE / BLOCK)^2 blocks, luminance."""

    mitsuba: FloatArray
    sigma: FloatArray
    shrm: FloatArray
    trunc: FloatArray  # signed: SHRM - reference at the same samples
    texel: FloatArray
    foot: FloatArray
    mask: NDArray[np.bool_]
    report: dict[str, Any]
    seconds: dict[str, float] = field(default_factory=dict)


@cache
def run_case(name: str, alpha: float) -> Case:
    s = SETUPS[alpha]
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    p = np.asarray(resample_latlong(envmap(name), s.rows), dtype=np.float64)
    brdf = TorranceSparrow(alpha, "beckmann", fresnel="none")

    render = render_sphere_mitsuba(mitsuba_bitmap(p, UP_MITSUBA), alpha, SIZE, SPP, seed=SEED)
    seconds["mitsuba"] = render.seconds

    t = time.perf_counter()
    fine = create_shrm(nearest_upsample(p, SPLIT), brdf, order=s.F, p_order=s.P, size=s.size)
    coarse = create_shrm(p, brdf, order=s.F, p_order=s.P, size=s.size)
    seconds["create_shrm x2"] = time.perf_counter() - t
    t = time.perf_counter()
    fine_ss, fine_half = sphere_lum(fine, SS), sphere_lum(fine, SS // 2)
    fine_ref, coarse_ref = sphere_lum(fine, s.ss_ref), sphere_lum(coarse, s.ss_ref)
    seconds["render_sphere x4"] = time.perf_counter() - t
    t = time.perf_counter()
    ref = luminance(block_mean(reference_sphere(p, brdf, VIEW, SIZE * s.ss_ref), s.ss_ref))
    seconds["reference_sphere"] = time.perf_counter() - t

    b = BLOCK
    case = Case(
        mitsuba=block_mean(render.luminance, b),
        sigma=np.sqrt(block_mean(render.variance, b) / b**2),
        shrm=block_mean(fine_ss, b),
        trunc=block_mean(coarse_ref, b) - block_mean(ref, b),
        texel=np.abs(block_mean(coarse_ref, b) - block_mean(fine_ref, b)) / 4.0,
        foot=np.abs(block_mean(fine_ss, b) - block_mean(fine_half, b)) / 3.0,
        mask=block_far_radius(SIZE, b) <= R_MAX,
        report=fine.report["components"][0],
        seconds=seconds,
    )
    seconds["total"] = time.perf_counter() - t0
    return case


def _summary(name: str, alpha: float, c: Case) -> dict[str, Any]:
    m = c.mask
    y, sig = c.mitsuba[m], c.sigma[m]
    diff = c.shrm[m] - y
    tol = K * sig + np.abs(c.trunc[m]) + c.texel[m] + c.foot[m]
    strict = diff - c.trunc[m]
    tol_strict = K * sig + c.texel[m] + c.foot[m]
    n = int(m.sum())
    sig_pool = float(np.sqrt(np.sum(sig**2)) / n)
    mean_y = float(np.mean(y))
    out = {
        "blocks": n,
        "orders": {k: c.report["orders"][k] for k in ("F_B", "P_B")},
        "predicted_rms_brdf": c.report["predicted"]["rms_brdf"],
        "sigma_rel_median": float(np.median(sig / y)),
        "sigma_rel_max": float(np.max(sig / y)),
        "max_abs_z": float(np.max(np.abs(diff) / sig)),
        "max_rel_diff": float(np.max(np.abs(diff) / y)),
        "max_ratio_to_tol": float(np.max(np.abs(diff) / tol)),
        "max_abs_z_strict": float(np.max(np.abs(strict) / sig)),
        "max_ratio_to_tol_strict": float(np.max(np.abs(strict) / tol_strict)),
        "max_rel_trunc": float(np.max(np.abs(c.trunc[m]) / y)),
        "max_rel_texel": float(np.max(c.texel[m] / y)),
        "max_rel_foot": float(np.max(c.foot[m] / y)),
        "mean_rel_diff": float(np.mean(diff)) / mean_y,
        "mean_z": float(np.mean(diff)) / sig_pool,
        "mean_rel_diff_strict": float(np.mean(strict)) / mean_y,
        "mean_z_strict": float(np.mean(strict)) / sig_pool,
        "sigma_pool_rel": sig_pool / mean_y,
        "seconds": {k: round(v, 2) for k, v in c.seconds.items()},
    }
    RESULTS[f"{name}/alpha={alpha}"] = out
    print(f"\n{name} alpha={alpha}: " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                                for k, v in out.items()))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("name", MAPS)
def test_shrm_sphere_matches_mitsuba(variant: str, name: str, alpha: float) -> None:
    c = run_case(name, alpha)
    out = _summary(name, alpha, c)
    m = c.mask
    y, sig = c.mitsuba[m], c.sigma[m]
    assert out["blocks"] >= 20 and np.all(y > 0) and np.all(sig > 0)
    # relight's measured truncation error on these blocks stays below its own (whole light field) prediction
    assert out["max_rel_trunc"] < out["predicted_rms_brdf"]
    diff = c.shrm[m] - y
    trunc, texel, foot = c.trunc[m], c.texel[m], c.foot[m]
    # the check: SHRM vs Mitsuba within the noise plus relight's truncation, texel and footprint terms
    tol = K * sig + np.abs(trunc) + texel + foot
    bad = np.abs(diff) > tol
    assert not bad.any(), f"{name} alpha={alpha}: blocks {np.argwhere(bad).ravel()} exceed; {out}"
    # stricter: the measured truncation error put back with its sign (= relight's brute-force reference)
    strict = diff - trunc
    bad = np.abs(strict) > K * sig + texel + foot
    assert not bad.any(), f"{name} alpha={alpha}: reference blocks {np.argwhere(bad).ravel()} exceed; {out}"
    # pooled over the compared blocks: pooled noise, signed truncation, mean texel and footprint terms
    n = y.size
    sig_pool = np.sqrt(np.sum(sig**2)) / n
    assert abs(np.mean(diff)) <= K * sig_pool + abs(np.mean(trunc)) + np.mean(texel) + np.mean(foot), out
    assert abs(np.mean(strict)) <= K * sig_pool + np.mean(texel) + np.mean(foot), out
