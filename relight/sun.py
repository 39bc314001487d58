"""Sun extraction and clamping with energy accounting (issue 17, item 6): ``--sun extract|clamp=V|keep``.

A sun is a handful of pixels holding a large share of a map's energy (city.exr: 12 pixels, 24 %): it costs a
frequency-space prefilter its highest orders and an engine's chain its sharpest levels, while a renderer handles
it exactly as a directional light.

* ``extract``: the sun region is every pixel within ``SEARCH_DEG`` of the brightest pixel whose Rec. 709 luminance
  is at least ``REL_THRESHOLD`` of that peak. Its pixels are replaced by the background (the mean RGB of the
  ring ``RING_DEG`` wide just outside the region, pixels above the threshold left out), and the sun is what was
  removed: irradiance ``E = sum_k (L_k - L_bg) dOmega_k`` (RGB, at normal incidence), its luminance the
  illuminance, direction the luminance-weighted centroid ``normalize(sum_k Y_k dOmega_k w_k)`` of the region's
  pixels, angular radius that of the disc of the region's solid angle. ``residual + sun`` holds exactly the map's
  energy (per channel, by construction; tests/relight/test_sun.py checks it to 0.1 %).
* ``clamp=V``: every pixel's RGB is scaled so that its luminance is at most V (hue kept, cmgen ``--clamp``'s
  purpose); the removed fraction of the map's luminous energy is recorded.
* ``keep``: the map as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
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
#: Width of the background ring outside the region (degrees).
RING_DEG = 2.0
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
    region = (lum >= REL_THRESHOLD * peak) & (angle <= SEARCH_DEG)
    reach = float(angle[region].max())
    ring = (angle > reach) & (angle <= reach + RING_DEG) & (lum < REL_THRESHOLD * peak)
    if not np.any(ring):
        raise InputError("no background ring around the sun region (the map is too small)")
    bg = np.sum(env[ring] * d_omega[ring, None], axis=0) / np.sum(d_omega[ring])
    removed = (env[region] - bg) * d_omega[region, None]
    e_sun = removed.sum(axis=0)
    weight = lum[region] * d_omega[region]
    centroid = (dirs[region] * weight[:, None]).sum(axis=0)
    direction = centroid / np.linalg.norm(centroid)
    solid = float(d_omega[region].sum())
    residual = env.copy()
    residual[region] = bg
    total = np.sum(env * d_omega[..., None], axis=(0, 1))
    report = {
        "mode": "extract", "direction": [float(x) for x in direction], "irradiance_rgb": [float(x) for x in e_sun],
        "illuminance": float(e_sun @ LUMINANCE_WEIGHTS), "solid_angle_sr": solid,
        "angular_radius_deg": math.degrees(math.acos(1.0 - solid / (2.0 * math.pi))), "pixels": int(region.sum()),
        "energy_fraction": float((e_sun @ LUMINANCE_WEIGHTS) / (total @ LUMINANCE_WEIGHTS)),
        "background_rgb": [float(x) for x in bg], "threshold": REL_THRESHOLD * peak,
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
