"""Mitsuba 3 side of relight's external-oracle test (``tests/test_mitsuba_oracle.py``).

Mitsuba conventions used here (``shared/FACTS.md`` "Independent ground truth: Mitsuba 3", and measured with
Mitsuba 3.9.1 by evaluating the ``envmap`` emitter on a bitmap whose texels encode their own indices):

* ``envmap`` bitmap of ``Hm x Wm`` texels: texel ``(y, x)`` is the radiance in the direction
  ``d = (sin(phi) sin(theta), cos(theta), -cos(phi) sin(theta))`` with ``theta = pi y / (Hm - 1)`` (rows are *not*
  texel-centred: the first and last rows sit on the poles) and ``phi = 2 pi (x + 1/2) / Wm`` (columns *are*
  texel-centred and wrap), so u = 0 is -Z, u = 1/4 is +X and u = 1/2 is +Z. Between texels the radiance is
  bilinear in (phi, theta). Negative texels are used as they are (relight clamps them on reading; so do we).
* ``roughconductor`` with ``distribution="beckmann"``, ``material="none"`` is relight's
  ``TorranceSparrow(alpha, "beckmann", fresnel="none")``; ``BSDF.eval`` returns ``f_r cos(theta_light)``.
* ``orthographic`` sensor at ``look_at(origin=(0, 0, 3), target=0, up=+Y)`` images the unit sphere filling the
  frame, image right = +X, image up = +Y: ``relight.shrm.sphere_geometry`` for V = +Z. The ``hdrfilm`` box
  filter makes each pixel the mean radiance over the pixel's area (every sample lands in exactly one pixel).
* ``path`` with ``max_depth=2`` is direct lighting only (the scene has nothing else); ``hide_emitters`` gives the
  background 0, as ``relight.shrm.render_sphere``'s default.
* The ``moment`` integrator adds per-pixel first and second moments of the samples in CIE XYZ; CIE Y of linear
  Rec. 709 RGB is exactly Rec. 709 luminance, so ``(m2 - m1^2) / spp`` is the Monte Carlo variance of each
  pixel's luminance estimate, from the render itself.

The conversion of a relight lat-long map (``docs/conventions.md``) to a Mitsuba bitmap is exact, not a
resampling: Mitsuba's radiance equals relight's pixel value everywhere except in thin bilinear seams along the
pixel edges (see :func:`mitsuba_bitmap`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Preferred variants: the LLVM one is 3-5x faster but needs Debian's ``libllvm19`` (FACTS.md).
VARIANTS = ("llvm_ad_rgb", "scalar_rgb")


def choose_variant() -> str:
    """Set and return the first Mitsuba variant of :data:`VARIANTS` that loads and evaluates a scene here."""
    import mitsuba as mi

    errors = []
    for variant in VARIANTS:
        try:
            mi.set_variant(variant)
            em = mi.load_dict({"type": "constant", "radiance": {"type": "rgb", "value": 1.0}})
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(0.0, 0.0, 1.0)
            value = np.array(em.eval(si)).ravel()
            if not np.allclose(value, 1.0):
                raise RuntimeError(f"constant emitter evaluated to {value}")
            return variant
        except Exception as exc:  # noqa: BLE001 - a variant that cannot run here: try the next one
            errors.append(f"{variant}: {exc}")
    raise RuntimeError("no usable Mitsuba variant: " + "; ".join(errors))


# ------------------------------------------------------------------------------------------ environment map
def texel_dirs(hm: int, wm: int) -> FloatArray:
    """World direction of every texel of a Mitsuba ``envmap`` bitmap of ``hm x wm`` texels, (hm, wm, 3)."""
    theta = np.pi * np.arange(hm) / (hm - 1)
    phi = 2.0 * np.pi * (np.arange(wm) + 0.5) / wm
    st = np.sin(theta)[:, None]
    return np.stack(
        np.broadcast_arrays(np.sin(phi)[None, :] * st, np.cos(theta)[:, None], -np.cos(phi)[None, :] * st), axis=-1
    )


def mitsuba_bitmap(pixels: NDArray[np.floating], up: int) -> NDArray[np.float32]:
    """Mitsuba ``envmap`` texels ``(up H + 1, 2 up H, 3)`` showing relight's lat-long map (H, 2H, 3) exactly.

    The map is read as piecewise constant (each pixel's value over its solid angle, which is what
    ``relight.envmap.resample_latlong`` area-averages to). Columns: relight column j spans ``phi_r`` in
    ``[-pi + 2 pi j / W, -pi + 2 pi (j + 1) / W]`` and ``phi_r = phi_m - pi/2`` (relight's +X is Mitsuba's u = 1/4),
    so Mitsuba column x (centre ``phi_m = 2 pi (x + 1/2) / (up W)``) lies inside relight column
    ``floor((x + 1/2) / up + W / 4) mod W``: each relight column gets exactly ``up`` texel columns and the bilinear
    seam is symmetric about the pixel edge. Rows: with ``Hm - 1 = up H`` texel row ``y = up i + r`` sits at
    ``theta = pi (i + r / up) / H``: inside relight row i for ``0 < r < up``, exactly on the edge between rows
    i - 1 and i for r = 0 (given their mean), and on the poles for y = 0 and y = Hm - 1 (given the mean of the
    first or last row: every texel there is the same direction). So Mitsuba's radiance equals the pixel value in
    every direction farther than 1/up of a pixel from a pixel edge (checked in the test); the seams are
    box-filters of the edges, of width 1/up pixel across columns and 2/up across rows.
    """
    p = np.asarray(pixels, dtype=np.float64)
    h, w = p.shape[0], p.shape[1]
    if p.ndim != 3 or w != 2 * h or w % 4:
        raise ValueError(f"need an (H, 2H, C) lat-long map with H even, got {p.shape}")
    hm, wm = up * h + 1, up * w
    cols = np.floor((np.arange(wm) + 0.5) / up + w / 4).astype(np.intp) % w
    rows = np.empty((hm, w) + p.shape[2:])
    for y in range(hm):
        i, r = divmod(y, up)
        if r:
            rows[y] = p[i]
        elif i == 0:
            rows[y] = p[0].mean(axis=0)
        elif i == h:
            rows[y] = p[h - 1].mean(axis=0)
        else:
            rows[y] = 0.5 * (p[i - 1] + p[i])
    return np.ascontiguousarray(rows[:, cols], dtype=np.float32)


def nearest_upsample(pixels: NDArray[np.floating], k: int) -> FloatArray:
    """The same piecewise-constant map on a k times finer lat-long grid (each pixel split into k x k)."""
    p = np.asarray(pixels, dtype=np.float64)
    return np.repeat(np.repeat(p, k, axis=0), k, axis=1)


def emitter_radiance(bitmap: NDArray[np.float32], dirs: FloatArray) -> FloatArray:
    """Mitsuba's ``envmap`` radiance (RGB) arriving from world directions ``dirs`` (n, 3)."""
    import mitsuba as mi

    em = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(bitmap)})
    d = np.asarray(dirs, dtype=np.float64)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(-d[:, 0], -d[:, 1], -d[:, 2])  # wi points from the emitter toward the scene
    return _rows(em.eval(si), d.shape[0])


def bsdf_eval(alpha: float, wi: FloatArray, wo: FloatArray) -> FloatArray:
    """Mitsuba ``roughconductor`` (Beckmann, ``material="none"``) ``eval``: ``f_r cos(theta_o)``, (n,) (grey).

    ``wi`` (toward the viewer) and ``wo`` (toward the light) are (n, 3) in the local frame, normal +Z.
    """
    import mitsuba as mi

    bsdf = mi.load_dict({"type": "roughconductor", "distribution": "beckmann", "alpha": alpha, "material": "none"})
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*np.asarray(wi, dtype=np.float64).T)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    value = _rows(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*np.asarray(wo, dtype=np.float64).T)), len(wi))
    return np.asarray(value[:, 1], dtype=np.float64)


def _rows(value: Any, n: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    return arr.T if arr.shape == (3, n) else arr.reshape(n, 3)


# ----------------------------------------------------------------------------------------------- rendering
@dataclass(frozen=True)
class SphereRender:
    """A Mitsuba image of the unit sphere: RGB, luminance and the Monte Carlo variance of each pixel's luminance."""

    rgb: FloatArray
    luminance: FloatArray
    variance: FloatArray
    spp: int
    seconds: float


def sphere_scene(bitmap: NDArray[np.float32], alpha: float, size: int, spp: int) -> dict[str, Any]:
    """The scene dictionary (module docstring): unit sphere, ``roughconductor``, envmap, orthographic camera."""
    import mitsuba as mi

    return {
        "type": "scene",
        "integrator": {"type": "moment", "nested": {"type": "path", "max_depth": 2, "hide_emitters": True}},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "emitter": {"type": "envmap", "bitmap": mi.Bitmap(bitmap)},
        "sphere": {"type": "sphere", "bsdf": {"type": "roughconductor", "distribution": "beckmann", "alpha": alpha,
                                             "material": "none"}},
    }


def render_sphere_mitsuba(bitmap: NDArray[np.float32], alpha: float, size: int, spp: int,
                          seed: int = 0) -> SphereRender:
    """Render the sphere (module docstring) and return the image with its per-pixel Monte Carlo variance."""
    import time

    import mitsuba as mi

    t0 = time.perf_counter()
    scene = mi.load_dict(sphere_scene(bitmap, alpha, size, spp))
    img = np.array(mi.render(scene, spp=spp, seed=mi.UInt32(seed)), dtype=np.float64)
    seconds = time.perf_counter() - t0
    # channels: R, G, B, then the moment integrator's nested.{X,Y,Z} and m2_nested.{X,Y,Z}
    if img.shape != (size, size, 9):
        raise RuntimeError(f"unexpected film layout {img.shape}")
    lum, m2 = img[..., 4], img[..., 7]
    var = np.maximum(m2 - lum * lum, 0.0) / spp
    return SphereRender(rgb=img[..., :3], luminance=lum, variance=var, spp=spp, seconds=seconds)


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


def theta_v_deg(radius: float) -> float:
    """Angle between N and V (degrees) at image radius ``radius`` of the orthographic sphere image."""
    return math.degrees(math.asin(min(radius, 1.0)))
