"""Prefiltered cube-map chains for engines: one mip level per roughness, synthesised at cube texel centres.

An engine's specular image-based lighting reads a cube map whose mip ``lod`` holds the environment convolved with
its split-sum GGX lobe (:class:`relight.brdf.splitsum.GGXSplitSum`) at the roughness the engine maps that lod to:

* ``three`` (r187) and ``filament``: ``lod = maxLod * r (2 - r)``, so ``r = 1 - sqrt(1 - lod / maxLod)``;
* ``gltf`` (glTF-IBL-Sampler, KHR_lights_environment draft): ``lod = maxLod * r``.

``maxLod`` is the chain's last level (levels halve the face size down to 1 x 1 by default). Each level is
computed exactly where it is cheap and exact:

* ``r = 0`` (level 0): the mirror lobe, the map itself bilinearly sampled at the texel centres;
* a lobe the map's pixels resolve in frequency space (the order its energy tolerance needs, seed 000 §5.1, is
  below the map's H rings): one lighting projection (the largest order of all such levels, shared), the exact SH
  convolution ``B_lm = Lambda_l rho_l L_lm`` and SH synthesis directly at the texel directions (no lat-long to
  cube resampling); its predicted error is the App. B bound of that level's orders;
* a lobe sharper than a quarter of the orders the map resolves (GGX at small roughness: a peak narrower than a
  pixel *and* heavy ~ 1/theta^4 tails, so neither path alone works): split by a raised-cosine window into a
  near part, summed directly over the pixels within a few pixel widths (sparse, exact pixel quadrature), and a
  smooth far part, which the SH path resolves at a moderate order. The two parts sum to the lobe exactly.

:func:`brute_force` is the plain dense sum over every pixel that tests compare all three against.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from relight import indexing, sh
from relight.brdf.base import RadialLobe
from relight.brdf.coefficients import radial_transfer, spectrum_for_tolerance
from relight.brdf.splitsum import MIN_ROUGHNESS, GGXSplitSum
from relight.conventions import dirs_to_angles, latlong_dirs, pixel_solid_angles, require_rgb_latlong, sample_latlong
from relight.envmap import cube_face_dirs
from relight.errors import InputError
from relight.prefilter import choose_orders, project_lighting

FloatArray = NDArray[np.float64]
Mapping = Literal["quadratic", "linear"]
Method = Literal["sample", "sh", "split"]

#: Engine -> how its mip lod maps to perceptual roughness (module docstring).
TARGET_MAPPING: dict[str, Mapping] = {"three": "quadratic", "filament": "quadratic", "gltf": "linear"}
#: Default energy tolerance per level: the minimum-of-errors rule (seed 000 §5.1) predicts sqrt(2.5e-5) = 0.5 %
#: relative RMS, half of the 1 % the engines' chains are held to (tests/relight/test_cube_chain.py).
DEFAULT_EPSILON = 2.5e-5
#: Split levels: the near part's window ends at this many pixel heights (doubled until the far part is resolved).
NEAR_PIXELS = 8
#: A lobe whose order exceeds (H - 1) / SPLIT_FRACTION is split: measured on city.exr (sun 3.4e4 x the mean),
#: GGX r = 0.134 at F = 209 of 511 gave 1.0 % against the brute force where 0.5 % was predicted (the peak's
#: truncation beside the sun); split, the same level measures below 1e-4.
SPLIT_FRACTION = 4
#: Largest face size a chain accepts (6 x 4096^2 x RGB float32 is 1.2 GB).
MAX_FACE_SIZE = 4096
#: Neighbour pairs per block of the angular path's sparse sum (bounds its memory to ~ 24 bytes x this).
_PAIRS_PER_BLOCK = 4_000_000


def level_roughness(levels: int, mapping: Mapping) -> FloatArray:
    """Perceptual roughness of each mip level 0..levels-1 under an engine's lod mapping (module docstring)."""
    if levels < 1:
        raise InputError(f"a chain needs at least one level, got {levels}")
    if levels == 1:
        return np.zeros(1)
    x = np.arange(levels) / (levels - 1)  # lod / maxLod
    if mapping == "linear":
        return np.asarray(x, dtype=np.float64)
    if mapping == "quadratic":
        return np.asarray(1.0 - np.sqrt(1.0 - x), dtype=np.float64)
    raise InputError(f"unknown roughness mapping {mapping!r}; use 'quadratic' or 'linear'")


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

    def summary(self) -> list[dict[str, float | int | str | None]]:
        return [{"level": lv.level, "size": lv.size, "roughness": lv.roughness, "method": lv.method,
                 "order": lv.order, "near_angle": lv.near_angle, "predicted_rms": lv.predicted_rms,
                 "bound_rms": lv.bound_rms, "seconds": lv.seconds} for lv in self.levels]


class _WindowedLobe(RadialLobe):
    """``u(t) w(theta)`` or ``u(t) (1 - w(theta))`` with a raised-cosine window ``w`` falling from 1 at theta0 to
    0 at theta1: the near and far parts of a lobe, which sum to it exactly."""

    kind = "windowed"

    def __init__(self, lobe: RadialLobe, theta0: float, theta1: float, *, near: bool) -> None:
        self.lobe, self.theta0, self.theta1, self.near = lobe, theta0, theta1, near
        self.center = lobe.center
        self.channels = lobe.channels

    def window(self, t: FloatArray) -> FloatArray:
        theta = np.arccos(np.clip(t, -1.0, 1.0))
        x = np.clip((theta - self.theta0) / (self.theta1 - self.theta0), 0.0, 1.0)
        w = 0.5 * (1.0 + np.cos(np.pi * x))
        return np.asarray(w if self.near else 1.0 - w, dtype=np.float64)

    def u(self, t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        return np.asarray(self.lobe.u(t) * self.window(t)[..., None], dtype=np.float64)

    def params(self) -> dict[str, object]:
        return {"lobe": self.lobe.spec(), "theta0": self.theta0, "theta1": self.theta1, "near": self.near}


def angular_convolution(pixels: NDArray[np.floating], lobe: RadialLobe, dirs: FloatArray,
                        theta_max: float) -> FloatArray:
    """``B(d) = sum_k L_k dOmega_k u(d . w_k)`` over the pixels within ``theta_max`` of d (where u must vanish
    beyond), for directions (N, 3).

    Neighbours come from a k-d tree on the pixel directions (chord ``2 sin(theta/2)``, one pixel of margin),
    processed in blocks of directions so that the sparse pair list stays bounded.
    """
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    theta_star = min(theta_max + math.pi / h, math.pi)
    chord = 2.0 * math.sin(0.5 * theta_star)
    pix_dirs = latlong_dirs(h, w).reshape(-1, 3)
    weighted = (env * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    tree = cKDTree(pix_dirs)
    per_dir = max(1.0, (1.0 - math.cos(theta_star)) / 2.0 * h * w)
    block = max(1, int(_PAIRS_PER_BLOCK / per_dir))
    out = np.empty((dirs.shape[0], 3))
    for start in range(0, dirs.shape[0], block):
        d = dirs[start:start + block]
        pairs = cKDTree(d).sparse_distance_matrix(tree, chord, output_type="coo_matrix")
        kern = np.asarray(lobe.u(1.0 - 0.5 * np.square(pairs.data)), dtype=np.float64)[:, 0]
        for c in range(3):
            out[start:start + block, c] = np.bincount(pairs.row, kern * weighted[pairs.col, c], minlength=d.shape[0])
    return out


def brute_force(pixels: NDArray[np.floating], lobe: RadialLobe, dirs: FloatArray, *, chunk: int = 64) -> FloatArray:
    """The dense reference: every pixel of the map for every direction (tests only; O(N H W))."""
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    pix = latlong_dirs(h, w).reshape(-1, 3)
    weighted = (env * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    out = np.empty((dirs.shape[0], 3))
    for s in range(0, dirs.shape[0], chunk):
        kern = np.asarray(lobe.u(dirs[s:s + chunk] @ pix.T), dtype=np.float64)[..., 0]
        out[s:s + chunk] = kern @ weighted
    return out


def prefilter_chain(pixels: NDArray[np.floating], *, target: str = "three", size: int = 256,
                    levels: int | None = None, epsilon: float = DEFAULT_EPSILON) -> CubeChain:
    """The engine's prefiltered GGX chain of a lat-long map (H, W, 3): face ``size`` at level 0, halving."""
    if target not in TARGET_MAPPING:
        raise InputError(f"unknown target {target!r}; use one of {', '.join(TARGET_MAPPING)}")
    if not (isinstance(size, int) and 1 <= size <= MAX_FACE_SIZE and size & (size - 1) == 0):
        raise InputError(f"size must be a power of two in [1, {MAX_FACE_SIZE}], got {size!r}")
    full = int(math.log2(size)) + 1
    n_levels = full if levels is None else levels
    if not 1 <= n_levels <= full:
        raise InputError(f"levels must lie in [1, {full}] for size {size}, got {levels}")
    if not 0.0 < epsilon < 1.0:
        raise InputError(f"epsilon must lie in (0, 1), got {epsilon}")
    pixels = require_rgb_latlong(pixels)
    h = pixels.shape[0]
    f_cap = h - 1
    mapping = TARGET_MAPPING[target]
    rough = level_roughness(n_levels, mapping)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()

    # Per level: the lobe, or its near (angular) and far (SH) parts when the map cannot resolve it in SH.
    plans: list[tuple[float, RadialLobe | None, RadialLobe | None, float, int]] = []
    for r in rough:
        if r < MIN_ROUGHNESS:
            plans.append((float(r), None, None, 0.0, 0))
            continue
        full_lobe = GGXSplitSum(float(r))
        _, f_rho = spectrum_for_tolerance(full_lobe, epsilon, lmax_cap=f_cap + 1)
        if f_rho <= f_cap // SPLIT_FRACTION:
            plans.append((float(r), None, full_lobe, 0.0, f_rho))
            continue
        theta1 = NEAR_PIXELS * math.pi / h
        while True:
            far = _WindowedLobe(full_lobe, 0.5 * theta1, theta1, near=False)
            _, f_far = spectrum_for_tolerance(far, epsilon, lmax_cap=f_cap + 1)
            if f_far <= f_cap or theta1 >= math.pi / 2:
                break
            theta1 *= 2.0
        near = _WindowedLobe(full_lobe, 0.5 * theta1, theta1, near=True)
        plans.append((float(r), near, far, theta1, min(f_far, f_cap)))
    timings["orders"] = time.perf_counter() - t0

    f_light = max((f for _, _, lobe, _, f in plans if lobe is not None), default=0)
    t1 = time.perf_counter()
    lighting = project_lighting(pixels, f_light) if f_light > 0 else None
    timings["lighting_projection"] = time.perf_counter() - t1

    out: list[ChainLevel] = []
    for i, (r, near_lobe, sh_lobe, theta1, f_rho) in enumerate(plans):
        t = time.perf_counter()
        s = size >> i
        dirs = cube_face_dirs(s).reshape(-1, 3)
        faces = np.zeros((dirs.shape[0], 3))
        order: int | None = None
        rms = bound = 0.0
        method: Method = "sample"
        if near_lobe is None and sh_lobe is None:
            faces = sample_latlong(np.asarray(pixels, dtype=np.float64)[None], dirs)[:, 0]
        if sh_lobe is not None and lighting is not None:
            spectrum = radial_transfer(sh_lobe, f_rho)
            choice = choose_orders(spectrum, lighting, epsilon, None, f_rho, f_cap, spectrum.transfer)
            order = choice.F_B
            l_idx, _ = indexing.healpy_lm(order)
            b_lm = sh.truncate(lighting.alm, lighting.lmax, order) * spectrum.transfer[: order + 1, 0][l_idx][None, :]
            theta, phi = dirs_to_angles(dirs)
            faces = faces + sh.evaluate(b_lm, order, theta, phi)
            # Both relative to the SH part's output, which is at most the whole output: conservative for the level
            rms = math.sqrt(max(choice.eps_min_of_errors, 0.0))
            bound = math.sqrt(max(choice.eps_appendix_b, 0.0))
            method = "sh"
        if near_lobe is not None:
            faces = faces + angular_convolution(pixels, near_lobe, dirs, theta1)
            method = "split"
        out.append(ChainLevel(level=i, size=s, roughness=r, method=method, order=order, predicted_rms=rms,
                              bound_rms=bound, seconds=time.perf_counter() - t, near_angle=theta1,
                              faces=np.asarray(faces, dtype=np.float32).reshape(6, s, s, 3)))
    timings["levels"] = sum(lv.seconds for lv in out)
    timings["total"] = time.perf_counter() - t0
    return CubeChain(target=target, mapping=mapping, epsilon=epsilon, lighting_order=f_light, levels=out,
                     seconds=timings)
