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

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix

from relight import indexing, sh
from relight.brdf.base import RadialLobe
from relight.brdf.coefficients import radial_transfer, spectrum_for_tolerance
from relight.brdf.splitsum import MIN_ROUGHNESS, GGXSplitSum
from relight.conventions import (
    column_phis,
    dirs_to_angles,
    latlong_dirs,
    pixel_solid_angles,
    require_rgb_latlong,
    sample_latlong,
)
from relight.envmap import cube_face_dirs
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
#: The far part's tolerance is the level's epsilon divided by the far part's share of the lobe's energy
#: (``int u_far^2 / int u^2``): its truncation error, relative to the whole level, is then epsilon for white
#: lighting, as for an unsplit lobe. Capped so that the far part keeps 95 % of its own energy: with a cap of
#: 0.5, city.exr at 64 x 128 (GGX r = 0.134, far order 23) measured 1.4 % where 0.47 % was predicted; at 0.05 every
#: split level of tests/relight/test_cube_chain.py measured at most 0.42 %.
FAR_EPSILON_CAP = 0.05
#: A lobe whose order exceeds (H - 1) / SPLIT_FRACTION is split: measured on city.exr (sun 3.4e4 x the mean),
#: GGX r = 0.134 at F = 209 of 511 gave 1.0 % against the brute force where 0.5 % was predicted (the peak's
#: truncation beside the sun); split, the same level measures below 1e-4.
SPLIT_FRACTION = 4
#: Largest face size a chain accepts (6 x 4096^2 x RGB float32 is 1.2 GB).
MAX_FACE_SIZE = 4096
#: (direction, pixel) pairs per block of the angular path's sparse sum (bounds its memory to ~ 100 bytes x this).
_PAIRS_PER_BLOCK = 2_000_000
#: Nodes of the tabulated near lobe (uniform in the chord up to the window's end; module docstring of
#: :func:`angular_convolution`).
_KERNEL_TABLE = 16384


def level_roughness(levels: int, mapping: Mapping, size: int | None = None) -> FloatArray:
    """Perceptual roughness of each mip level 0..levels-1 under an engine's lod mapping (module docstring);
    ``size`` (level 0's face size) is needed by ``log2`` only."""
    if levels < 1:
        raise InputError(f"a chain needs at least one level, got {levels}")
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

    def summary(self) -> list[dict[str, float | int | str | None]]:
        return [{"level": lv.level, "size": lv.size, "roughness": lv.roughness, "method": lv.method,
                 "order": lv.order, "near_angle": lv.near_angle, "predicted_rms": lv.predicted_rms,
                 "bound_rms": lv.bound_rms, "seconds": lv.seconds} for lv in self.levels]


@dataclass(frozen=True)
class _LevelPlan:
    """How one level is computed: its SH lobe (the whole lobe or the far part) at ``order`` and ``epsilon``, the
    near part summed over pixels up to ``theta1``, and the SH part's share of the lobe's energy."""

    roughness: float
    near_lobe: RadialLobe | None
    sh_lobe: RadialLobe | None
    theta1: float
    order: int
    epsilon: float
    share: float


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


def _cap_rows(theta: FloatArray, phi: FloatArray, h: int, w: int,
              theta_star: float) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The lat-long pixels whose centres can lie within ``theta_star`` of each direction, as row runs.

    For a direction at (theta_d, phi_d), ring i (polar angle theta_i) meets the cap where
    ``cos(dphi) >= (cos theta* - cos theta_i cos theta_d) / (sin theta_i sin theta_d)`` (spherical law of
    cosines), i.e. over the columns within ``dphi`` of phi_d; one column of margin on each side (pixels beyond
    the cap cost a zero kernel value, a pixel left out would be an error). Returns, per (direction, ring) run,
    the direction, the ring, the first column (may be negative: wraps) and the number of columns (<= W).
    """
    dth = np.pi / h
    i_lo = np.clip(np.ceil((theta - theta_star) / dth - 0.5), 0, h - 1).astype(np.int64)
    i_hi = np.clip(np.floor((theta + theta_star) / dth - 0.5), 0, h - 1).astype(np.int64)
    n_rows = np.maximum(i_hi - i_lo + 1, 0)
    d_of = np.repeat(np.arange(theta.size, dtype=np.int64), n_rows)
    first = np.cumsum(n_rows) - n_rows
    ring = i_lo[d_of] + np.arange(d_of.size, dtype=np.int64) - first[d_of]
    th_r = (ring + 0.5) * dth
    td = theta[d_of]
    den = np.sin(th_r) * np.sin(td)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_half = (math.cos(theta_star) - np.cos(th_r) * np.cos(td)) / den
    # a direction on the pole (den = 0) or a cap over the pole (cos_half < -1) takes whole rings
    whole = (den <= 1e-300) | (cos_half <= -1.0)
    half = np.arccos(np.clip(np.where(whole, -1.0, cos_half), -1.0, 1.0))
    x = (phi[d_of] + np.pi) / (2.0 * np.pi) * w - 0.5  # continuous column of the direction
    c_lo = np.floor(x - half * w / (2.0 * np.pi)).astype(np.int64) - 1
    c_hi = np.ceil(x + half * w / (2.0 * np.pi)).astype(np.int64) + 1
    count = np.minimum(c_hi - c_lo + 1, w)
    c_lo = np.where(whole | (count >= w), 0, c_lo)
    count = np.where(whole, w, count)
    return d_of, ring, c_lo, count


def angular_convolution(pixels: NDArray[np.floating], lobe: RadialLobe, dirs: FloatArray, theta_max: float, *,
                        backend: Literal["jit", "numpy"] = "jit") -> FloatArray:
    """``B(d) = sum_k L_k dOmega_k u(d . w_k)`` over the pixels within ``theta_max`` of d (where u must vanish
    beyond), for directions (N, 3): the same pixel quadrature as :func:`brute_force`, restricted to the cap.

    The pixels of the cap come ring by ring (:func:`_cap_rows`); the lobe is tabulated against the chord
    ``|d - w| = sqrt(2 - 2 d.w)`` (``_KERNEL_TABLE`` nodes, linear interpolation; the narrowest lobe split here
    spans hundreds of nodes, so the table's error is ~1e-7 of the level, tests/relight/test_cube_chain.py).
    ``backend="jit"`` sums one direction at a time in compiled code (numba); ``"numpy"`` is the same sum
    vectorised (ring runs expanded into a CSR matrix per block of directions), the plain reference it is tested
    against.
    """
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    theta_star = min(theta_max, math.pi)
    weighted = np.ascontiguousarray(env * pixel_solid_angles(h, w)[:, None, None])
    chord_max = 2.0 * math.sin(0.5 * theta_star)
    grid = np.linspace(0.0, chord_max, _KERNEL_TABLE)
    table = np.asarray(lobe.u(1.0 - 0.5 * grid * grid), dtype=np.float64)[:, 0]
    table[-1] = 0.0  # the lobe vanishes at the window's end; chords beyond it add nothing
    scale = (_KERNEL_TABLE - 1) / chord_max
    theta, phi = dirs_to_angles(dirs)
    out = np.empty((dirs.shape[0], 3))
    if backend == "jit":
        cols = column_phis(w)
        _near_sum_jit(np.ascontiguousarray(theta), np.ascontiguousarray(phi), weighted, np.cos(cols), np.sin(cols),
                      table, scale, theta_star, out)
        return out
    if backend != "numpy":
        raise InputError(f"unknown backend {backend!r}; use 'jit' or 'numpy'")
    pix_dirs = latlong_dirs(h, w).reshape(-1, 3)
    flat = weighted.reshape(-1, 3)
    slope = np.diff(table)
    d_of, ring, c_lo, count = _cap_rows(theta, phi, h, w, theta_star)
    per_dir = np.bincount(d_of, weights=count, minlength=dirs.shape[0]).astype(np.int64)
    run_end = np.cumsum(np.bincount(d_of, minlength=dirs.shape[0]))  # the runs of directions < k end here
    pair_end = np.cumsum(per_dir)
    start = 0
    while start < dirs.shape[0]:
        base = pair_end[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(pair_end, base + _PAIRS_PER_BLOCK, side="right")))
        r0 = run_end[start - 1] if start else 0
        r1 = run_end[stop - 1]
        cnt = count[r0:r1]
        offs = np.repeat(np.cumsum(cnt) - cnt, cnt)
        col = np.repeat(c_lo[r0:r1], cnt) + np.arange(offs.size, dtype=np.int64) - offs
        pix = np.repeat(ring[r0:r1] * w, cnt) + np.mod(col, w)
        dd = np.repeat(dirs[d_of[r0:r1]], cnt, axis=0)
        t = np.einsum("ij,ij->i", dd, pix_dirs[pix])
        x = np.minimum(np.sqrt(np.maximum(2.0 - 2.0 * t, 0.0)) * scale, _KERNEL_TABLE - 1.0)
        node = np.minimum(x.astype(np.int64), _KERNEL_TABLE - 2)
        kern = table[node] + (x - node) * slope[node]
        indptr = np.concatenate([[0], np.cumsum(per_dir[start:stop])])
        out[start:stop] = csr_matrix((kern, pix, indptr), shape=(stop - start, h * w)) @ flat
        start = stop
    return out


@numba.njit(cache=True, nogil=True)
def _near_sum_jit(theta: FloatArray, phi: FloatArray, weighted: FloatArray, cos_col: FloatArray,
                  sin_col: FloatArray, table: FloatArray, scale: float, theta_star: float, out: FloatArray) -> None:
    """:func:`angular_convolution`'s sum, one direction at a time: the ring runs of :func:`_cap_rows` (the same
    margins) with the same tabulated lobe, ``t = cos a cos b + sin a sin b cos(dphi)`` from per-column tables."""
    h, w = weighted.shape[0], weighted.shape[1]
    dth = math.pi / h
    dph = 2.0 * math.pi / w
    cos_star = math.cos(theta_star)
    last = table.shape[0] - 1
    for n in range(theta.shape[0]):
        ctd, std = math.cos(theta[n]), math.sin(theta[n])
        cpd, spd = math.cos(phi[n]), math.sin(phi[n])
        x_d = (phi[n] + math.pi) / dph - 0.5
        i_lo = max(0, int(math.ceil((theta[n] - theta_star) / dth - 0.5)))
        i_hi = min(h - 1, int(math.floor((theta[n] + theta_star) / dth - 0.5)))
        acc0 = acc1 = acc2 = 0.0
        for i in range(i_lo, i_hi + 1):
            th_r = (i + 0.5) * dth
            a = ctd * math.cos(th_r)
            b = std * math.sin(th_r)
            c_lo, count = 0, w
            if b > 1e-300:
                cos_half = (cos_star - a) / b
                if cos_half > -1.0:
                    half = math.acos(min(cos_half, 1.0)) / dph
                    c_lo = int(math.floor(x_d - half)) - 1
                    count = min(int(math.ceil(x_d + half)) + 1 - c_lo + 1, w)
                    if count >= w:
                        c_lo = 0
            for k in range(count):
                j = (c_lo + k) % w
                t = a + b * (cpd * cos_col[j] + spd * sin_col[j])
                x = math.sqrt(max(2.0 - 2.0 * t, 0.0)) * scale
                if x >= last:
                    continue
                node = int(x)
                kv = table[node] + (x - node) * (table[node + 1] - table[node])
                acc0 += kv * weighted[i, j, 0]
                acc1 += kv * weighted[i, j, 1]
                acc2 += kv * weighted[i, j, 2]
        out[n, 0] = acc0
        out[n, 1] = acc1
        out[n, 2] = acc2


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
    rough = level_roughness(n_levels, mapping, size)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()

    # Per level: the lobe, or its near (angular) and far (SH) parts when the map cannot resolve it in SH.
    plans: list[_LevelPlan] = []
    for r in rough:
        if r < MIN_ROUGHNESS:
            plans.append(_LevelPlan(float(r), None, None, 0.0, 0, epsilon, 1.0))
            continue
        full_lobe = GGXSplitSum(float(r), max_roughness=MAX_ROUGHNESS)
        full_spec, f_rho = spectrum_for_tolerance(full_lobe, epsilon, lmax_cap=f_cap + 1)
        if f_rho <= f_cap // SPLIT_FRACTION:
            plans.append(_LevelPlan(float(r), None, full_lobe, 0.0, f_rho, epsilon, 1.0))
            continue
        e_full = float(np.max(full_spec.total_energy))
        theta1 = NEAR_PIXELS * math.pi / h
        while True:
            far = _WindowedLobe(full_lobe, 0.5 * theta1, theta1, near=False)
            share = min(1.0, float(np.max(radial_transfer(far, 64).total_energy)) / e_full)
            eps_far = min(epsilon / share, FAR_EPSILON_CAP)
            _, f_far = spectrum_for_tolerance(far, eps_far, lmax_cap=f_cap + 1)
            if f_far <= f_cap // FAR_FRACTION or theta1 >= math.pi / 2:
                break
            theta1 *= 2.0
        near = _WindowedLobe(full_lobe, 0.5 * theta1, theta1, near=True)
        plans.append(_LevelPlan(float(r), near, far, theta1, min(f_far, f_cap), eps_far, share))
    timings["orders"] = time.perf_counter() - t0

    f_light = max((p.order for p in plans if p.sh_lobe is not None), default=0)
    t1 = time.perf_counter()
    lighting = project_lighting(pixels, f_light) if f_light > 0 else None
    timings["lighting_projection"] = time.perf_counter() - t1

    out: list[ChainLevel] = []
    for i, p in enumerate(plans):
        t = time.perf_counter()
        s = size >> i
        dirs = cube_face_dirs(s).reshape(-1, 3)
        faces = np.zeros((dirs.shape[0], 3))
        order: int | None = None
        rms = bound = 0.0
        method: Method = "sample"
        if p.near_lobe is None and p.sh_lobe is None:
            faces = sample_latlong(np.asarray(pixels, dtype=np.float64)[None], dirs)[:, 0]
        if p.sh_lobe is not None and lighting is not None:
            spectrum = radial_transfer(p.sh_lobe, p.order)
            choice = choose_orders(spectrum, lighting, p.epsilon, None, p.order, f_cap, spectrum.transfer)
            order = choice.F_B
            l_idx, _ = indexing.healpy_lm(order)
            b_lm = sh.truncate(lighting.alm, lighting.lmax, order) * spectrum.transfer[: order + 1, 0][l_idx][None, :]
            theta, phi = dirs_to_angles(dirs)
            faces = faces + sh.evaluate(b_lm, order, theta, phi)
            # The prediction of the SH part scaled by its share of the lobe's energy (exact for white lighting);
            # App. B relative to the SH part's output, which is at most the whole output: conservative.
            rms = math.sqrt(max(choice.eps_min_of_errors, 0.0) * p.share)
            bound = math.sqrt(max(choice.eps_appendix_b, 0.0))
            method = "sh"
        if p.near_lobe is not None:
            faces = faces + angular_convolution(pixels, p.near_lobe, dirs, p.theta1)
            method = "split"
        out.append(ChainLevel(level=i, size=s, roughness=p.roughness, method=method, order=order,
                              predicted_rms=rms, bound_rms=bound, seconds=time.perf_counter() - t,
                              near_angle=p.theta1, faces=np.asarray(faces, dtype=np.float32).reshape(6, s, s, 3)))
    timings["levels"] = sum(lv.seconds for lv in out)
    timings["total"] = time.perf_counter() - t0
    return CubeChain(target=target, mapping=mapping, epsilon=epsilon, lighting_order=f_light, levels=out,
                     seconds=timings)
