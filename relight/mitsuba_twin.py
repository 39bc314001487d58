"""Mitsuba 3 twins of relight's models: an independent renderer for measuring relight's error on a sphere image.

Mitsuba 3 (``pip install mitsuba``) is optional: it is imported inside the functions that need it, and
:func:`unavailable_reason` says why it cannot be used here (not installed, no variant that runs) instead of failing.
``relight.tradeoff.sweep`` uses it to record each point's error against Mitsuba as well as against the angular
reference; ``tests/relight/test_mitsuba_oracle.py`` checks relight's SHRM against it block by block.

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
    if up < 2:
        raise InputError(f"need at least 2 Mitsuba texels per pixel edge, got {up}")
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
    if size < 1 or supersample < 1:
        raise InputError(f"size and supersample must be >= 1, got {size} and {supersample}")
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
        if self.spp < 1 or self.supersample < 1 or self.texels < 2:
            raise InputError(f"need spp >= 1, supersample >= 1 and texels >= 2, got {self.spp}, {self.supersample}, "
                             f"{self.texels}")
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

