"""Sun extraction and clamping with energy accounting (issue 17, item 6): ``--sun extract|clamp=V|keep``.

A sun is a handful of pixels holding a large share of a map's energy (city.exr: 12 pixels, 24 %): it costs a
frequency-space prefilter its highest orders and an engine's chain its sharpest levels, while a renderer handles
it exactly as a directional light.

* ``extract``: the sun's core is every pixel within ``SEARCH_DEG`` of the brightest pixel whose Rec. 709
  luminance is at least ``REL_THRESHOLD`` of that peak; the region removed is the disc ``HALO_DEG`` wider than the
  core's reach (its aureole: on city.exr pixels of 30-290 x the sky's luminance lie just below the threshold and,
  left in, held 38 % of the residual's squared energy). The region is refilled with the harmonic interpolant of the
  pixels around it (:func:`harmonic_fill`: continuous with the sky, smooth inside, between the boundary's extremes),
  so the residual carries no ring and no hard-edged hole, both of which cost high orders. The sun is what was
  removed: irradiance ``E = sum_k (L_k - L_fill,k) dOmega_k`` (RGB, at normal incidence) over the region, its
  luminance the illuminance, direction the centroid ``normalize(sum_k max(Y_k - Y_fill,k, 0) dOmega_k w_k)``,
  angular radius that of the disc of the core's solid angle. ``residual + sun`` holds exactly the map's energy
  (per channel, by construction; tests/relight/test_sun.py checks it to 0.1 %).
* ``clamp=V``: every pixel's RGB is scaled so that its luminance is at most V (hue kept, cmgen ``--clamp``'s
  purpose); the removed fraction of the map's luminous energy is recorded.
* ``keep``: the map as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg
from numpy.typing import NDArray

from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, pixel_solid_angles, require_rgb_latlong
from relight.errors import InputError

FloatArray = NDArray[np.float64]
#: Sun pixels: luminance at least this fraction of the peak (city.exr: 1 % takes its 12-pixel disc and aureole,
#: 23.7 % of the map's energy; 0.1 % adds 16 pixels and 0.5 % of the energy).
REL_THRESHOLD = 0.01
#: How far from the brightest pixel the region may reach (degrees): the sun's disc is 0.27 deg, bright aureoles
#: a few degrees.
SEARCH_DEG = 10.0
#: The removed disc reaches this much beyond the core (degrees). On city.exr (core reach 1.2 deg) the residual's
#: planned order for microfacet sigma = 0.2 at epsilon = 1e-3 held to its own energy (per view band,
#: ``relight.planning.sun_orders``: ``order_residual_alone``) is 20 at 1 deg, 18 at 2 deg, 17 at 7 deg and beyond,
#: against 25 with the core alone and a flat fill; held to the original map's output energy (the residual's error
#: alone, no point-light error) it is 8 at 0, 2 and 5 deg (the skyline, not the sun's glow, sets it).
HALO_DEG = 2.0
#: A map has a sun only if its peak luminance is at least this many times the mean (city.exr: 3.3e4).
MIN_PEAK_OVER_MEAN = 100.0


@dataclass(frozen=True)
class SunResult:
    """The map after the sun step and what the manifest records."""

    pixels: FloatArray
    report: dict[str, Any]


def parse_sun(text: str) -> tuple[str, float | None]:
    """``extract``, ``keep`` or ``clamp=V`` (V > 0) -> (mode, value)."""
    t = text.strip().lower()
    if t in ("extract", "keep"):
        return t, None
    if t.startswith("clamp="):
        try:
            v = float(t.split("=", 1)[1])
        except ValueError:
            raise InputError(f"--sun clamp=V needs a number, got {text!r}") from None
        if not (math.isfinite(v) and v > 0.0):
            raise InputError(f"--sun clamp=V needs V > 0, got {text!r}")
        return "clamp", v
    raise InputError(f"--sun must be extract, keep or clamp=V, got {text!r}")


def harmonic_fill(env: FloatArray, region: NDArray[np.bool_]) -> FloatArray:
    """``env`` with the pixels of ``region`` replaced by the solution of Laplace's equation on the sphere (the
    lat-long grid's 5-point stencil with its metric: east-west weight ``1 / sin^2 theta``) whose boundary values
    are the pixels around the region (longitude wraps; a pole row is a closed edge). By the discrete maximum
    principle every filled value lies between the boundary's extremes."""
    h, w = env.shape[:2]
    rows, cols = np.nonzero(region)
    n = rows.size
    index = np.full((h, w), -1, dtype=np.int64)
    index[rows, cols] = np.arange(n)
    sin_t = np.sin((np.arange(h) + 0.5) * math.pi / h)
    k = np.arange(n)
    diag = np.zeros(n)
    rhs = np.zeros((n, env.shape[2]))
    mat_rows: list[NDArray[np.int64]] = []
    mat_cols: list[NDArray[np.int64]] = []
    mat_vals: list[FloatArray] = []
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        r2, c2 = rows + dr, (cols + dc) % w
        inside = (r2 >= 0) & (r2 < h)
        wgt = np.where(inside, 1.0 if dr else 1.0 / sin_t[rows] ** 2, 0.0)
        diag += wgt
        r2c = np.clip(r2, 0, h - 1)
        j = np.where(inside, index[r2c, c2], -1)
        own = j >= 0
        mat_rows.append(k[own])
        mat_cols.append(j[own])
        mat_vals.append(-wgt[own])
        edge = inside & ~own
        rhs[edge] += wgt[edge, None] * env[r2c[edge], c2[edge]]
    a = sparse.csr_matrix((np.concatenate([diag, *mat_vals]), (np.concatenate([k, *mat_rows]),
                                                               np.concatenate([k, *mat_cols]))), shape=(n, n))
    out = env.copy()
    out[rows, cols] = np.asarray(sparse_linalg.spsolve(a.tocsc(), rhs)).reshape(n, -1)
    return out


def extract_sun(pixels: NDArray[np.floating]) -> SunResult:
    """Split a lat-long map (H, W, 3) into a residual map and a directional sun (module docstring)."""
    env = np.array(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    lum = env @ LUMINANCE_WEIGHTS
    d_omega = np.broadcast_to(pixel_solid_angles(h, w)[:, None], (h, w))
    mean = float(np.sum(lum * d_omega) / (4.0 * math.pi))
    peak_idx = np.unravel_index(int(np.argmax(lum)), lum.shape)
    peak = float(lum[peak_idx])
    if not peak >= MIN_PEAK_OVER_MEAN * mean:
        raise InputError(f"no sun to extract: the brightest pixel is {peak / max(mean, 1e-300):.3g} x the mean "
                         f"luminance (a sun needs >= {MIN_PEAK_OVER_MEAN:g} x)")
    dirs = latlong_dirs(h, w)
    angle = np.degrees(np.arccos(np.clip(dirs @ dirs[peak_idx], -1.0, 1.0)))
    core = (lum >= REL_THRESHOLD * peak) & (angle <= SEARCH_DEG)
    reach = float(angle[core].max())
    region = angle <= reach + HALO_DEG
    if region.all():
        raise InputError("no sky around the sun region (the map is too small)")
    residual = harmonic_fill(env, region)
    excess = (env[region] - residual[region]) * d_omega[region, None]
    e_sun = excess.sum(axis=0)
    weight = np.clip(excess @ LUMINANCE_WEIGHTS, 0.0, None)
    centroid = (dirs[region] * weight[:, None]).sum(axis=0)
    direction = centroid / np.linalg.norm(centroid)
    solid = float(d_omega[core].sum())
    total = np.sum(env * d_omega[..., None], axis=(0, 1))
    report = {
        "mode": "extract", "direction": [float(x) for x in direction], "irradiance_rgb": [float(x) for x in e_sun],
        "illuminance": float(e_sun @ LUMINANCE_WEIGHTS), "solid_angle_sr": solid,
        "angular_radius_deg": math.degrees(math.acos(1.0 - solid / (2.0 * math.pi))), "pixels": int(core.sum()),
        "energy_fraction": float((e_sun @ LUMINANCE_WEIGHTS) / (total @ LUMINANCE_WEIGHTS)),
        "region_deg": reach + HALO_DEG, "region_pixels": int(region.sum()), "threshold": REL_THRESHOLD * peak,
    }
    return SunResult(pixels=residual, report=report)


def clamp_map(pixels: NDArray[np.floating], value: float) -> SunResult:
    """Scale every pixel whose luminance exceeds ``value`` down to it (hue kept); record the removed energy."""
    env = np.array(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    lum = env @ LUMINANCE_WEIGHTS
    scale = np.where(lum > value, value / np.where(lum > 0.0, lum, 1.0), 1.0)
    out = env * scale[..., None]
    d_omega = pixel_solid_angles(h, w)[:, None]
    before = float(np.sum(lum * d_omega))
    after = float(np.sum((out @ LUMINANCE_WEIGHTS) * d_omega))
    report = {"mode": "clamp", "value": value, "pixels": int(np.sum(lum > value)),
              "removed_energy_fraction": (before - after) / before if before > 0.0 else 0.0}
    return SunResult(pixels=out, report=report)


def apply_sun(pixels: NDArray[np.floating], spec: str) -> SunResult:
    """The ``--sun`` step: extract, clamp or keep."""
    mode, value = parse_sun(spec)
    if mode == "extract":
        return extract_sun(pixels)
    if mode == "clamp":
        assert value is not None
        return clamp_map(pixels, value)
    return SunResult(pixels=np.asarray(pixels, dtype=np.float64), report={"mode": "keep"})
