"""Mitsuba 3 twins of relight's models: an independent renderer for measuring relight's error on a sphere image.

Mitsuba 3 (``pip install mitsuba``) is optional: it is imported inside the functions that need it, and
:func:`unavailable_reason` says why it cannot be used here (not installed, no variant that runs) instead of failing.
``relight.tradeoff.sweep`` uses it (through ``relight.mitsuba_compare``) to record each point's error against
Mitsuba as well as against the angular reference; ``tests/relight/test_mitsuba_oracle.py`` checks relight's SHRM
against it block by block.

**Twins** (:func:`twin`). A relight model has a Mitsuba twin when Mitsuba's ``BSDF.eval`` (which returns
``f_r cos(theta_light)``) equals relight's ``f_r cos(theta_light)`` in every pair of directions, checked to 1e-4
by the tests (``tests/relight/test_tradeoff_mitsuba.py``, ``tests/relight/test_mitsuba_oracle.py``):

* ``TorranceSparrow(alpha, "beckmann", fresnel="none")`` = ``roughconductor``, ``distribution="beckmann"``,
  ``material="none"`` (F = 1; D and Walter et al. 2007's rational Smith G1 as in ``docs/facts.md``);
* ``TorranceSparrow(alpha, "ggx", fresnel="none")`` (and ``GGX(alpha)``) = ``roughconductor``,
  ``distribution="ggx"``, ``material="none"`` (exact Smith G1 for GGX in both);
* ``Lambert(albedo)`` = ``diffuse`` with ``reflectance = albedo`` (``f_r = albedo / pi`` in both).
* ``AnisotropicTorranceSparrow(alpha_u, alpha_v, d, fresnel="none")`` (seed 003, ``relight.brdf.anisotropic``) =
  ``roughconductor`` with ``alpha_u`` along the shading frame's s (relight's tangent t), ``alpha_v`` along t
  (relight's bitangent b), ``material="none"`` (``tests/relight/test_anisotropic_brdf.py``).

Everything else has none: Phong has no Mitsuba 3 plugin, Schlick's and the conductor Fresnel terms are not
Mitsuba's (its ``roughconductor`` uses the exact conductor Fresnel of named materials with spectral IORs), and
seed 000's eq. 11 microfacet, Kajiya–Kay, tabulated and measured lobes have no plugin either.

**Conventions** (``docs/facts.md`` "Independent ground truth: Mitsuba 3", measured with Mitsuba 3.9.1 by
evaluating the ``envmap`` emitter on a bitmap whose texels encode their own indices):

* ``envmap`` bitmap of ``Hm x Wm`` texels: texel ``(y, x)`` is the radiance in the direction
  ``d = (sin(phi) sin(theta), cos(theta), -cos(phi) sin(theta))`` with ``theta = pi y / (Hm - 1)`` (rows are *not*
  texel-centred: the first and last rows sit on the poles) and ``phi = 2 pi (x + 1/2) / Wm`` (columns *are*
  texel-centred and wrap), so u = 0 is -Z, u = 1/4 is +X and u = 1/2 is +Z. Between texels the radiance is
  bilinear in (phi, theta). Negative texels are used as they are (relight clamps them on reading; so must callers).
  relight's lat-long maps (``docs/conventions.md``) are texel-centred in both directions.
* ``BSDF.eval`` returns ``f_r cos(theta_o)`` with ``wo`` toward the light, ``si.wi`` toward the viewer.
* Camera (:func:`sphere_scene`): ``orthographic`` at ``look_at(origin=3 V, target=0, up)`` with the ``up`` of
  ``relight.shrm.sphere_geometry`` (+Y, or +Z when V = +-Y). Mitsuba's image right is ``-normalize(up x dir)`` with
  ``dir = -V``, i.e. ``normalize(up x V)``, and its image up is ``V x right``: exactly relight's image right and up
  (+X and +Y for V = +Z), so pixel (i, j) of both images shows the normal
  ``x right + y up + sqrt(1 - x^2 - y^2) V`` with ``x = 2 (j + 1/2) / n - 1``, ``y = 1 - 2 (i + 1/2) / n``. The
  unit sphere fills the frame. The ``hdrfilm`` box filter makes each pixel the mean radiance over the pixel's area
  (every sample lands in exactly one pixel), so relight's side is supersampled and averaged per pixel.
* ``path`` with ``max_depth=2`` is direct lighting only (the scene has nothing else); ``hide_emitters`` gives the
  background 0, as ``relight.shrm.render_sphere``'s default.
* The ``moment`` integrator adds per-pixel first and second moments of the samples in CIE XYZ; CIE Y of linear
  Rec. 709 RGB is Rec. 709 luminance, so ``(m2 - m1^2) / spp`` is the Monte Carlo variance of each pixel's
  luminance estimate, from the render itself.

The conversion of a relight lat-long map to a Mitsuba bitmap (:func:`mitsuba_bitmap`) is exact, not a resampling:
Mitsuba's radiance equals relight's pixel value everywhere except in thin bilinear seams along the pixel edges.

How relight's maps are compared with the Mitsuba sphere (block means, the noise floor, :class:`TwinSettings`) is
``relight.mitsuba_compare``.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import luminance
from relight.errors import InputError, RelightError

FloatArray = NDArray[np.float64]

#: Preferred variants: the LLVM one is 3-5x faster but needs Debian's ``libllvm19`` (docs/facts.md).
VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
#: Largest Mitsuba bitmap width :func:`texels_per_pixel` aims for (a 4096 x 2049 RGB float32 bitmap is 100 MB).
MAX_BITMAP_WIDTH = 4096


def _mitsuba() -> Any:
    """The ``mitsuba`` module (typed ``Any``: its attributes depend on the variant set at run time)."""
    import mitsuba

    return mitsuba


@functools.cache
def choose_variant() -> str:
    """The first Mitsuba variant of :data:`VARIANTS` that loads and evaluates a scene here (set, then cached).

    Raises ``ImportError`` when Mitsuba is not installed and ``RelightError`` when no variant runs.
    """
    mi = _mitsuba()
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
    raise RelightError("no usable Mitsuba 3 variant: " + "; ".join(errors))


def unavailable_reason() -> str | None:
    """None when Mitsuba 3 runs here, else one line saying why not (not installed, or no variant runs)."""
    try:
        choose_variant()
    except ImportError:
        return "Mitsuba 3 is not installed (pip install mitsuba)"
    except RelightError as exc:
        return str(exc)
    return None


def mitsuba_module() -> Any:
    """``mitsuba`` with :func:`choose_variant`'s variant set; ``RelightError`` if it cannot run here."""
    reason = unavailable_reason()
    if reason is not None:
        raise RelightError(reason)
    mi = _mitsuba()
    variant = choose_variant()
    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


# ------------------------------------------------------------------------------------------------- twins
def twin(brdf: Any) -> dict[str, Any] | None:
    """The Mitsuba 3 BSDF dictionary (``mitsuba.load_dict``) equal to ``brdf``, or None (module docstring).

    The dictionary holds only JSON values, so it can be recorded as it is.
    """
    from relight.brdf.anisotropic import AnisotropicTorranceSparrow
    from relight.brdf.models import TorranceSparrow
    from relight.brdf.radial import Lambert

    if isinstance(brdf, AnisotropicTorranceSparrow) and brdf.fresnel == "none":
        return {"type": "roughconductor", "distribution": brdf.distribution, "alpha_u": float(brdf.alpha_u),
                "alpha_v": float(brdf.alpha_v), "material": "none"}
    if isinstance(brdf, TorranceSparrow) and brdf.fresnel == "none":
        return {"type": "roughconductor", "distribution": brdf.distribution, "alpha": float(brdf.alpha),
                "material": "none"}
    if isinstance(brdf, Lambert):
        albedo = [float(a) for a in brdf.albedo]
        rgb = albedo * 3 if len(albedo) == 1 else albedo
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}
    return None


def bsdf_eval(bsdf: dict[str, Any], wi: FloatArray, wo: FloatArray) -> FloatArray:
    """Mitsuba's ``BSDF.eval`` of ``bsdf`` (a :func:`twin` dictionary): ``f_r cos(theta_o)``, RGB (n, 3).

    ``wi`` (toward the viewer) and ``wo`` (toward the light) are (n, 3) in the local frame, normal +Z.
    """
    mi = mitsuba_module()
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    obj = mi.load_dict(bsdf)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi.T)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    return _rows(obj.eval(mi.BSDFContext(), si, mi.Vector3f(*wo.T)), wi.shape[0])


def _rows(value: Any, n: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    return arr.T if arr.shape == (3, n) else arr.reshape(n, 3)


# ------------------------------------------------------------------------------------------ environment map
def texel_dirs(hm: int, wm: int) -> FloatArray:
    """World direction of every texel of a Mitsuba ``envmap`` bitmap of ``hm x wm`` texels, (hm, wm, 3)."""
    theta = np.pi * np.arange(hm) / (hm - 1)
    phi = 2.0 * np.pi * (np.arange(wm) + 0.5) / wm
    st = np.sin(theta)[:, None]
    return np.stack(
        np.broadcast_arrays(np.sin(phi)[None, :] * st, np.cos(theta)[:, None], -np.cos(phi)[None, :] * st), axis=-1
    )


def check_bitmap_shape(shape: tuple[int, ...]) -> str | None:
    """None when an (H, W, C) lat-long map can be shown exactly by :func:`mitsuba_bitmap`, else why not."""
    if len(shape) != 3 or shape[0] < 2 or shape[1] != 2 * shape[0] or shape[1] % 4:
        return (f"the Mitsuba twin needs an (H, 2H, C) lat-long map with H even (W divisible by 4, so that relight's "
                f"+X falls on a Mitsuba texel edge), got shape {tuple(shape)}")
    return None


def texels_per_pixel(width: int, most: int = 8) -> int:
    """Mitsuba texels per relight pixel edge for a map ``width`` pixels wide: ``most``, fewer for wide maps (the
    bitmap at most :data:`MAX_BITMAP_WIDTH` wide), never below 2 (with 1 every texel row would sit on an edge)."""
    return int(max(2, min(most, MAX_BITMAP_WIDTH // max(width, 1))))


def mitsuba_bitmap(pixels: NDArray[np.floating], up: int) -> NDArray[np.float32]:
    """Mitsuba ``envmap`` texels ``(up H + 1, 2 up H, 3)`` showing relight's lat-long map (H, 2H, 3) exactly.

    The map is read as piecewise constant (each pixel's value over its solid angle, which is what
    ``relight.envmap.resample_latlong`` area-averages to). Columns: relight column j spans ``phi_r`` in
    ``[-pi + 2 pi j / W, -pi + 2 pi (j + 1) / W]`` and ``phi_r = phi_m - pi/2`` (relight's +X is Mitsuba's u = 1/4),
    so Mitsuba column x (centre ``phi_m = 2 pi (x + 1/2) / (up W)``) lies inside relight column
    ``floor((x + 1/2) / up + W / 4) mod W``: each relight column gets exactly ``up`` texel columns and the bilinear
    seam is symmetric about the pixel edge (this needs W divisible by 4; InputError otherwise). Rows: with
    ``Hm - 1 = up H`` texel row ``y = up i + r`` sits at ``theta = pi (i + r / up) / H``: inside relight row i for
    ``0 < r < up``, exactly on the edge between rows i - 1 and i for r = 0 (given their mean), and on the poles for
    y = 0 and y = Hm - 1 (given the mean of the first or last row: every texel there is the same direction). So
    Mitsuba's radiance equals the pixel value in every direction farther than 1/up of a pixel from a pixel edge
    (checked in ``tests/relight/test_mitsuba_oracle.py``); the seams are box filters of the edges, of width 1/up pixel
    across columns and 2/up across rows.
    """
    p = np.asarray(pixels, dtype=np.float64)
    reason = check_bitmap_shape(p.shape)
    if reason is not None:
        raise InputError(reason)
    validate.at_least("Mitsuba texels per pixel edge", up, 2)
    h, w = p.shape[0], p.shape[1]
    hm, wm = up * h + 1, up * w
    cols = np.floor((np.arange(wm) + 0.5) / up + w / 4).astype(np.intp) % w
    i, r = np.divmod(np.arange(hm), up)
    inner = p[np.minimum(i, h - 1)]
    edge = 0.5 * (p[np.clip(i - 1, 0, h - 1)] + p[np.minimum(i, h - 1)])
    rows = np.where((r > 0)[:, None, None], inner, edge)
    rows[0] = p[0].mean(axis=0)
    rows[-1] = p[h - 1].mean(axis=0)
    return np.ascontiguousarray(rows[:, cols], dtype=np.float32)


def emitter_radiance(bitmap: NDArray[np.float32], dirs: FloatArray) -> FloatArray:
    """Mitsuba's ``envmap`` radiance (RGB) arriving from world directions ``dirs`` (n, 3)."""
    mi = mitsuba_module()
    em = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(bitmap)})
    d = np.asarray(dirs, dtype=np.float64)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(-d[:, 0], -d[:, 1], -d[:, 2])  # wi points from the emitter toward the scene
    return _rows(em.eval(si), d.shape[0])


# ----------------------------------------------------------------------------------------------- rendering
def camera_up(view: FloatArray) -> FloatArray:
    """The camera's up vector: +Y, or +Z when V = +-Y (``relight.shrm.sphere_geometry``'s rule)."""
    return np.array([0.0, 1.0, 0.0]) if abs(float(view[1])) < 1.0 - 1e-9 else np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class SphereRender:
    """A Mitsuba image of the unit sphere: RGB, luminance and the Monte Carlo variance of each pixel's luminance."""

    rgb: FloatArray
    luminance: FloatArray
    variance: FloatArray
    spp: int
    seconds: float
    variant: str


def sphere_scene(bitmap: NDArray[np.float32], bsdf: dict[str, Any], view: FloatArray, size: int,
                 spp: int, crop: tuple[int, int, int, int] | None = None) -> dict[str, Any]:
    """The scene dictionary (module docstring): unit sphere with ``bsdf``, envmap, orthographic camera along V.

    ``crop = (x, y, width, height)`` renders only that window of the ``size x size`` image (same pixels)."""
    mi = mitsuba_module()
    v = np.asarray(view, dtype=np.float64)
    film: dict[str, Any] = {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                            "pixel_format": "rgb"}
    if crop is not None:
        film.update(crop_offset_x=crop[0], crop_offset_y=crop[1], crop_width=crop[2], crop_height=crop[3])
    return {
        "type": "scene",
        "integrator": {"type": "moment", "nested": {"type": "path", "max_depth": 2, "hide_emitters": True}},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=(3.0 * v).tolist(), target=[0, 0, 0],
                                                       up=camera_up(v).tolist()),
            "film": film,
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "emitter": {"type": "envmap", "bitmap": mi.Bitmap(bitmap)},
        "sphere": {"type": "sphere", "bsdf": bsdf},
    }


def render_sphere_mitsuba(bitmap: NDArray[np.float32], bsdf: dict[str, Any], size: int, spp: int, *,
                          view: NDArray[np.floating] | tuple[float, float, float] = (0.0, 0.0, 1.0),
                          seed: int = 0, crop: tuple[int, int, int, int] | None = None) -> SphereRender:
    """Render the unit sphere seen along V (module docstring) and return the image with its per-pixel variance.

    With ``crop = (x, y, width, height)`` only that window is rendered; the other pixels are NaN."""
    from relight.shrm import unit_view

    mi = mitsuba_module()
    v = unit_view(view)
    x0, y0, cw, ch = crop if crop is not None else (0, 0, size, size)
    if not (0 <= x0 and 0 <= y0 and 1 <= cw and 1 <= ch and x0 + cw <= size and y0 + ch <= size):
        raise InputError(f"crop window {crop} does not fit a {size} x {size} image")
    t0 = time.perf_counter()
    scene = mi.load_dict(sphere_scene(bitmap, bsdf, v, size, spp, crop))
    img = np.array(mi.render(scene, spp=spp, seed=mi.UInt32(seed)), dtype=np.float64)
    seconds = time.perf_counter() - t0
    # channels: R, G, B, then the moment integrator's nested.{X,Y,Z} and m2_nested.{X,Y,Z}
    if img.shape != (ch, cw, 9):
        raise RelightError(f"unexpected Mitsuba film layout {img.shape}")
    full = np.full((size, size, 9), np.nan)
    full[y0 : y0 + ch, x0 : x0 + cw] = img
    y, m2 = full[..., 4], full[..., 7]
    var = np.maximum(m2 - y * y, 0.0) / spp
    return SphereRender(rgb=full[..., :3], luminance=luminance(full[..., :3]), variance=var, spp=spp,
                        seconds=seconds, variant=str(mi.variant()))
