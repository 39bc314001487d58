"""Prefiltered cube-map chains for engines: one mip level per roughness, synthesised at cube texel centres.

An engine's specular image-based lighting reads a cube map whose mip ``lod`` holds the environment convolved with
its split-sum GGX lobe (:class:`relight.brdf.splitsum.GGXSplitSum`) at the roughness the engine maps that lod to:

* ``three`` (r187) and ``filament``: ``lod = maxLod * r (2 - r)``, so ``r = 1 - sqrt(1 - lod / maxLod)``;
* ``gltf`` (glTF-IBL-Sampler, KHR_lights_environment draft): ``lod = maxLod * r``;
* ``babylon``: ``lod = 0.8 log2(size alpha)`` with alpha = r^2 and ``size`` the face size of level 0
  (``getLodFromAlphaG`` in its PBR shaders scaled by the texture's ``lodGenerationScale`` = 0.8, which its own
  ``HDRFiltering`` prefilter sets, writing level lod >= 1 with ``alphaG = 2^(lod / 0.8) / size``); level 0 is the
  mirror. Its last levels have alpha > 1 (the shader never asks for lod > 0.8 log2(size), but trilinear filtering
  blends them in), and the lobe is then a GGX wider than the clamped cosine, as Babylon filters it.

``maxLod`` is the chain's last level (levels halve the face size down to 1 x 1 by default). Each level is
computed exactly where it is cheap and exact:

* ``r = 0`` (level 0): the mirror lobe, the cube copy of the map three's PMREMGenerator makes (r187
  ``PMREMEquirectangularToCubemap``, which its level 0 is): per texel the mean of four bilinear samples a quarter
  texel from its centre along both face axes;
* a lobe the map's pixels resolve in frequency space (the order its energy tolerance needs, seed 000 §5.1, is
  below the map's H rings): one lighting projection (the largest order of all such levels, shared), the exact SH
  convolution ``B_lm = Lambda_l rho_l L_lm`` and SH synthesis directly at the texel directions (no lat-long to
  cube resampling); its predicted error is the App. B bound of that level's orders;
* a lobe sharper than a quarter of the orders the map resolves (GGX at small roughness: a peak narrower than a
  pixel *and* heavy ~ 1/theta^4 tails, so neither path alone works): split by a raised-cosine window into a
  near part, integrated directly over the map's bilinear interpolant within a few pixel widths
  (:func:`relight.cap_convolution.angular_convolution`: a midpoint rule refined where the lobe varies inside a
  pixel, rescaled to the near part's exact mass, so that a lobe narrower than a pixel is a unit-mass average of
  the map next to the texel, never outside the map's range), and a smooth far part, which the SH path resolves
  at a moderate order. The two parts sum to the lobe exactly.

:func:`relight.cap_convolution.brute_force` (the same integral on a finer grid over the whole sphere, not
normalised) is the reference tests compare all three against.

``brdf`` (``--brdf SPEC``) replaces the split-sum lobe by another family's lobe at view = normal
(:mod:`relight.brdf.normal_view`): each level is then a mirror weight times the sampled map plus one lobe per lobe
of the spec, each planned as above on its own, and an RGB lobe one channel at a time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from relight import indexing, sh, validate
from relight.brdf.base import RadialLobe
from relight.brdf.coefficients import radial_transfer, spectrum_for_tolerance
from relight.brdf.normal_view import ChainBrdf, ChannelLobe
from relight.brdf.splitsum import MIN_ROUGHNESS, GGXSplitSum
from relight.cap_convolution import WindowedLobe, angular_convolution, cell_means, taps_rgb
from relight.conventions import (
    dirs_to_angles,
    require_rgb_latlong,
)
from relight.envmap import cube_face_dirs
from relight.envmap.cubemap import _FACE_AXES
from relight.errors import InputError
from relight.prefilter import choose_orders, project_lighting

FloatArray = NDArray[np.float64]
Mapping = Literal["quadratic", "linear", "log2"]
Method = Literal["sample", "sh", "split"]

#: Engine -> how its mip lod maps to perceptual roughness (module docstring).
TARGET_MAPPING: dict[str, Mapping] = {"three": "quadratic", "filament": "quadratic", "gltf": "linear",
                                      "babylon": "log2"}
#: Babylon's ``lodGenerationScale`` for prefiltered maps (``HDRFiltering._lodGenerationScale``, offset 0).
BABYLON_LOD_SCALE = 0.8
#: Widest lobe a chain asks for: Babylon's last level of a 4096^2 (MAX_FACE_SIZE) chain, alpha = 4096^(1/4) = 8.
MAX_ROUGHNESS = math.sqrt(8.0)
#: Default energy tolerance per level: the minimum-of-errors rule (seed 000 §5.1) predicts sqrt(2.5e-5) = 0.5 %
#: relative RMS, half of the 1 % the engines' chains are held to (tests/relight/test_cube_chain.py).
DEFAULT_EPSILON = 2.5e-5
#: Split levels: the near part's window ends at this many pixel heights (doubled until the far part's order is
#: at most (H - 1) / FAR_FRACTION). Its pixel pairs cost ~ (NEAR_PIXELS pi / H)^2 H W / 4 per texel.
NEAR_PIXELS = 4
FAR_FRACTION = 2
#: The far part is held to the level's epsilon on its own energy, as the whole lobe would be unsplit. (It was held
#: to epsilon / share, its share of the lobe's energy, capped at 0.05: exact for white lighting, but next to a sun
#: the far part's truncation rings relative to the texels it lands on, not to the whole level. City.exr at 1024 x
#: 512, GGX r = 0.134 at 128^2 texels, 300 texels against the brute force: 1.3 %, 4.2 % and 11 % at epsilon
#: 2.5e-5, 1e-3 and 3e-3 that way, 0.035 %, 0.21 % and 2.9 % now, in about the same time, because the wider
#: windows the higher far orders need are summed on the grid: relight.cap_convolution.grid_pays.)
#: A lobe whose order exceeds (H - 1) / SPLIT_FRACTION is split: measured on city.exr (sun 3.4e4 x the mean),
#: GGX r = 0.134 at F = 209 of 511 gave 1.0 % against the brute force where 0.5 % was predicted (the peak's
#: truncation beside the sun); split, the same level measures below 1e-4.
SPLIT_FRACTION = 4
#: Largest face size a chain accepts (6 x 4096^2 x RGB float32 is 1.2 GB).
MAX_FACE_SIZE = 4096


def mirror_level(pixels: NDArray[np.floating], size: int) -> FloatArray:
    """Level 0 (r = 0) as three r187's PMREM makes it (module docstring): (6 * size^2, 3), OpenGL face order: per
    texel the mean of the map's bilinear interpolant (:func:`relight.conventions.sample_latlong`) at the four
    directions a quarter texel off its centre along both face axes."""
    env = np.ascontiguousarray(require_rgb_latlong(pixels), dtype=np.float64)
    out = np.empty((6 * size * size, 3))
    _mirror_jit(env, size, _FACE_AXES, out)
    return out


@numba.njit(cache=True, nogil=True)
def _mirror_jit(env: FloatArray, size: int, axes: FloatArray, out: FloatArray) -> None:
    """:func:`mirror_level` texel by texel (the NumPy form, 4 x 6 size^2 directions through ``sample_latlong``,
    took 0.4 s at 256^2; tests/relight/test_cube_chain.py holds the two equal)."""
    h, w = env.shape[0], env.shape[1]
    quarter = 0.5 / size
    for f in range(6):
        for r in range(size):
            b_c = (r + 0.5) / size * 2.0 - 1.0
            for c in range(size):
                a_c = (c + 0.5) / size * 2.0 - 1.0
                acc0 = acc1 = acc2 = 0.0
                for db in (-quarter, quarter):
                    for da in (-quarter, quarter):
                        a, b = a_c + da, b_c + db
                        x = a * axes[f, 0, 0] + b * axes[f, 1, 0] + axes[f, 2, 0]
                        y = a * axes[f, 0, 1] + b * axes[f, 1, 1] + axes[f, 2, 1]
                        z = a * axes[f, 0, 2] + b * axes[f, 1, 2] + axes[f, 2, 2]
                        theta = math.atan2(math.hypot(x, z), y)
                        phi = math.atan2(z, x)
                        py = min(max(theta / math.pi * h - 0.5, 0.0), h - 1.0)
                        px = (phi / (2.0 * math.pi) + 0.5) * w - 0.5
                        y0 = min(int(py), max(h - 2, 0))
                        fy = py - y0
                        y1 = min(y0 + 1, h - 1)
                        x0f = math.floor(px)
                        fx = px - x0f
                        x0 = int(x0f) % w
                        x1 = (x0 + 1) % w
                        w00, w01 = (1.0 - fx) * (1.0 - fy), fx * (1.0 - fy)
                        w10, w11 = (1.0 - fx) * fy, fx * fy
                        t0, t1, t2 = taps_rgb(env, y0, y1, x0, x1, w00, w01, w10, w11)
                        acc0 += t0
                        acc1 += t1
                        acc2 += t2
                n = (f * size + r) * size + c
                out[n, 0], out[n, 1], out[n, 2] = 0.25 * acc0, 0.25 * acc1, 0.25 * acc2


def level_roughness(levels: int, mapping: Mapping, size: int | None = None) -> FloatArray:
    """Perceptual roughness of each mip level 0..levels-1 under an engine's lod mapping (module docstring);
    ``size`` (level 0's face size) is needed by ``log2`` only."""
    validate.at_least("levels", levels, 1)
    if mapping == "log2":
        if size is None or size < 1:
            raise InputError(f"the log2 (Babylon) mapping needs the face size of level 0, got {size!r}")
        lod = np.arange(levels, dtype=np.float64)
        alpha = np.exp2(lod / BABYLON_LOD_SCALE) / size
        return np.asarray(np.where(lod == 0, 0.0, np.sqrt(alpha)), dtype=np.float64)
    if levels == 1:
        return np.zeros(1)
    x = np.arange(levels) / (levels - 1)  # lod / maxLod
    if mapping == "linear":
        return np.asarray(x, dtype=np.float64)
    if mapping == "quadratic":
        return np.asarray(1.0 - np.sqrt(1.0 - x), dtype=np.float64)
    raise InputError(f"unknown roughness mapping {mapping!r}; use 'quadratic', 'linear' or 'log2'")


@dataclass(frozen=True)
class ChainLevel:
    """One mip level: faces (6, size, size, 3) in OpenGL order (docs/conventions.md) and how they were made."""

    level: int
    size: int
    roughness: float
    method: Method
    order: int | None  # F_B of the SH part
    predicted_rms: float  # seed 000 §5.1 minimum-of-errors prediction of the SH part, 0 when sampled
    bound_rms: float  # App. B's conservative bound of the SH part (relative to the whole level), 0 when sampled
    seconds: float
    near_angle: float  # split levels: the angle (radians) up to which the lobe is summed over pixels
    faces: NDArray[np.float32] = field(repr=False)


@dataclass(frozen=True)
class CubeChain:
    target: str
    mapping: Mapping
    epsilon: float
    lighting_order: int
    levels: list[ChainLevel]
    seconds: dict[str, float]
    brdf: str | None = None  # the --brdf spec, None for the engine's split-sum GGX lobe

    def summary(self) -> list[dict[str, float | int | str | None]]:
        return [{"level": lv.level, "size": lv.size, "roughness": lv.roughness, "method": lv.method,
                 "order": lv.order, "near_angle": lv.near_angle, "predicted_rms": lv.predicted_rms,
                 "bound_rms": lv.bound_rms, "seconds": lv.seconds} for lv in self.levels]


@dataclass(frozen=True)
class _LevelPlan:
    """How one level (or one colour channel of it) is computed: its SH lobe (the whole lobe or the far part) at
    ``order`` and ``epsilon``, the near part summed over pixels up to ``theta1``, and the SH part's share of the
    lobe's energy; ``channel`` is the output channel of an RGB kernel's pass (None: all three, a grey kernel)."""

    near_lobe: RadialLobe | None
    sh_lobe: RadialLobe | None
    theta1: float
    order: int
    epsilon: float
    share: float
    channel: int | None = None


def _plan(lobe: RadialLobe, epsilon: float, h: int, channel: int | None) -> _LevelPlan:
    """The whole lobe in SH when the map resolves it, else its near (angular) and far (SH) parts."""
    f_cap = h - 1
    full_spec, f_rho = spectrum_for_tolerance(lobe, epsilon, lmax_cap=f_cap + 1)
    if f_rho <= f_cap // SPLIT_FRACTION:
        return _LevelPlan(None, lobe, 0.0, f_rho, epsilon, 1.0, channel)
    e_full = float(np.max(full_spec.total_energy))
    theta1 = NEAR_PIXELS * math.pi / h
    while True:
        far = WindowedLobe(lobe, 0.5 * theta1, theta1, near=False)
        share = min(1.0, float(np.max(radial_transfer(far, 64).total_energy)) / e_full)
        _, f_far = spectrum_for_tolerance(far, epsilon, lmax_cap=f_cap + 1)
        if f_far <= f_cap // FAR_FRACTION or theta1 >= math.pi / 2:
            break
        theta1 *= 2.0
    near = WindowedLobe(lobe, 0.5 * theta1, theta1, near=True)
    return _LevelPlan(near, far, theta1, min(f_far, f_cap), epsilon, share, channel)


def _kernels(rough: FloatArray, brdf: str | None) -> list[tuple[FloatArray, list[RadialLobe]]]:
    """Per level: the RGB weight of the map itself (the mirror) and the continuous lobes."""
    if brdf is None:  # the engine's split-sum GGX lobe
        return [(np.ones(3), []) if r < MIN_ROUGHNESS else (np.zeros(3), [GGXSplitSum(float(r),
                max_roughness=MAX_ROUGHNESS)]) for r in rough]
    family = ChainBrdf(brdf, max_roughness=MAX_ROUGHNESS)
    return [(k.mirror, k.lobes) for k in (family.kernel(float(r)) for r in rough)]


def prefilter_chain(pixels: NDArray[np.floating], *, target: str = "three", size: int = 256,
                    levels: int | None = None, epsilon: float = DEFAULT_EPSILON,
                    brdf: str | None = None) -> CubeChain:
    """The engine's prefiltered GGX chain of a lat-long map (H, W, 3): face ``size`` at level 0, halving;
    ``brdf`` (a spec string) another lobe family per level (``relight.brdf.normal_view``)."""
    if target not in TARGET_MAPPING:
        raise InputError(f"unknown target {target!r}; use one of {', '.join(TARGET_MAPPING)}")
    if not (isinstance(size, int) and 1 <= size <= MAX_FACE_SIZE and size & (size - 1) == 0):
        raise InputError(f"size must be a power of two in [1, {MAX_FACE_SIZE}], got {size!r}")
    full = int(math.log2(size)) + 1
    n_levels = full if levels is None else levels
    if not 1 <= n_levels <= full:
        raise InputError(f"levels must lie in [1, {full}] for size {size}, got {levels}")
    validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    pixels = require_rgb_latlong(pixels)
    h = pixels.shape[0]
    f_cap = h - 1
    mapping = TARGET_MAPPING[target]
    rough = level_roughness(n_levels, mapping, size)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()

    # Per level: the mirror weight, and per lobe the lobe (or its near and far parts), one pass per channel of an
    # RGB lobe.
    kernels = _kernels(rough, brdf)
    plans: list[list[_LevelPlan]] = []
    for _, lobes in kernels:
        plans.append([])
        for lobe in lobes:
            if lobe.channels == 1:
                plans[-1].append(_plan(lobe, epsilon, h, None))
            else:
                plans[-1].extend(_plan(ChannelLobe(lobe, c), epsilon, h, c) for c in range(lobe.channels))
    timings["orders"] = time.perf_counter() - t0

    f_light = max((p.order for ps in plans for p in ps if p.sh_lobe is not None), default=0)
    t1 = time.perf_counter()
    # the pixel sums of the interpolant's cell means: the SH parts integrate the same function as the near parts
    lighting = project_lighting(cell_means(pixels), f_light) if f_light > 0 else None
    timings["lighting_projection"] = time.perf_counter() - t1

    out: list[ChainLevel] = []
    for i, (r, (mirror, _), passes) in enumerate(zip(rough, kernels, plans, strict=True)):
        t = time.perf_counter()
        s = size >> i
        dirs = cube_face_dirs(s).reshape(-1, 3)
        faces = np.zeros((dirs.shape[0], 3))
        order: int | None = None
        rms = bound = theta1 = 0.0
        method: Method = "sample"
        if np.any(mirror != 0.0):
            sampled = mirror_level(pixels, s)
            faces = sampled if np.all(mirror == 1.0) else faces + mirror[None, :] * sampled
        for p in passes:
            part = np.zeros_like(faces)
            if p.sh_lobe is not None and lighting is not None:
                spectrum = radial_transfer(p.sh_lobe, p.order)
                choice = choose_orders(spectrum, lighting, p.epsilon, None, p.order, f_cap, spectrum.transfer)
                order = max(order or 0, choice.F_B)
                l_idx, _ = indexing.healpy_lm(choice.F_B)
                b_lm = (sh.truncate(lighting.alm, lighting.lmax, choice.F_B)
                        * spectrum.transfer[: choice.F_B + 1, 0][l_idx][None, :])
                theta, phi = dirs_to_angles(dirs)
                part = part + sh.evaluate(b_lm, choice.F_B, theta, phi)
                # The prediction of the SH part scaled by its share of the lobe's energy (exact for white
                # lighting); App. B relative to the SH part's output, which is at most the whole output.
                rms = max(rms, math.sqrt(max(choice.eps_min_of_errors, 0.0) * p.share))
                bound = max(bound, math.sqrt(max(choice.eps_appendix_b, 0.0)))
                method = "sh" if method == "sample" else method
            if p.near_lobe is not None:
                part = part + angular_convolution(pixels, p.near_lobe, dirs, p.theta1)
                method, theta1 = "split", max(theta1, p.theta1)
            if p.channel is None:
                faces = faces + part
            else:
                faces[:, p.channel] += part[:, p.channel]
        out.append(ChainLevel(level=i, size=s, roughness=float(r), method=method, order=order,
                              predicted_rms=rms, bound_rms=bound, seconds=time.perf_counter() - t,
                              near_angle=theta1, faces=np.asarray(faces, dtype=np.float32).reshape(6, s, s, 3)))
    timings["levels"] = sum(lv.seconds for lv in out)
    timings["total"] = time.perf_counter() - t0
    return CubeChain(target=target, mapping=mapping, epsilon=epsilon, lighting_order=f_light, levels=out,
                     seconds=timings, brdf=brdf)
