"""Convolution of a lat-long map with a radial lobe that vanishes beyond a cap, and its dense reference.

The map is the function the engines sample: the bilinear interpolant of its pixel centres
(:func:`relight.conventions.bilinear_latlong`: columns wrap, rows clamp at the poles). The convolution is

    B(d) = int_S2 u(d . w) L(w) dw

over the cap ``theta <= theta_max`` where ``u`` is non-zero (the near part of a lobe that the map cannot resolve in
spherical harmonics: ``relight.cube_chain``'s split levels). :class:`WindowedLobe` cuts a lobe into such a near
part and the smooth far part with a raised-cosine window (the two sum to the lobe exactly).

:func:`angular_convolution` integrates cell by cell (a cell: one pixel's lat-long rectangle) with a midpoint rule
refined where the lobe varies within the cell (near its peak, and over a window's ramp: a raised cosine falling
over 4 pixels curves on a 1.3-pixel scale, and one-sample cells there put a sun in the ramp 10 % off), then
rescales the sum so that its weights integrate to the lobe's exact mass (:func:`cap_mass`): the sum is scaled to
it, except for a lobe narrower than the finest sub-cells, where a sum short of it gives the rest to the
interpolant at ``d`` (the part of the peak the sub-cells miss).
The weights stay positive and sum to the lobe's mass, so the result never leaves ``[min L, max L]`` times that
mass, and a lobe narrower than a sub-cell tends to ``L(d)``, the bilinear value at the texel's direction.
(Summing ``L_k dOmega_k u(d . w_k)`` at the pixel centres alone is not normalised for such a lobe: a pixel
centre next to ``d`` takes the peak's weight times a whole pixel's solid angle; on an octant map with values in
[0.05, 1] a level reached 3.5.)

For many directions and a lobe several pixels wide (:func:`grid_pays`) the same sum is evaluated on a lat-long
grid at half-pixel spacing and interpolated (:func:`_near_grid`): the sum commutes with rotations about the poles,
so one stencil of pixel weights per grid row and half-pixel offset gives the whole row, as circular correlations
along ``phi`` done with FFTs. A 1024 x 512 map's split GGX level (r = 0.134, 128^2 faces, window 16 px) took 26 s
summed per texel, 2.5 s on the grid. The interpolation (Catmull-Rom, clamped to the four nearest nodes' range,
so the range property above holds) adds ~ 0.05 % relative RMS.

:func:`brute_force` is the independent reference tests use: the same integral over the whole sphere, each pixel's
cell cut ``m`` x ``m`` and each fine cell integrated by a 2 x 2 Gauss-Legendre rule under ``sin theta`` (the
interpolant at the nodes by :func:`relight.conventions.sample_latlong`), ``m`` chosen from the lobe's half width and
no normalisation.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import NDArray

from relight.brdf.base import RadialLobe
from relight.conventions import (
    angles_to_dirs,
    column_phis,
    dirs_to_angles,
    require_rgb_latlong,
    sample_latlong,
)

FloatArray = NDArray[np.float64]

#: Nodes of the tabulated near lobe, uniform in sqrt(chord / chord_max) (a node every chord_max / N^2 at the
#: peak: a lobe a millionth of the cap wide still spans hundreds of nodes).
_KERNEL_TABLE = 16384
#: The near sum's midpoint rule takes this many samples across the scale on which the lobe varies inside a cell
#: (its half width at the peak, the distance from the peak further out, a window's curvature radius over its
#: ramp); at most NEAR_MAX_SUB per cell side. Measured against brute_force (Phong s = 64's near part, window
#: pi/4..pi/2, sun_sky(32), 96 texels): 2 -> 0.70 %, 4 -> 0.14 %, 8 -> 0.043 %, 16 -> 0.006 % relative RMS
#: (second order; tests/relight/test_cap_convolution.py holds the convergence).
NEAR_SUB_PER_SCALE = 4.0
NEAR_MAX_SUB = 8
#: The reference's fine grid: this many Gauss nodes across the lobe's half width (2 per fine cell side), and at
#: least 2 fine cells per pixel side.
REF_SUB_PER_HALF_WIDTH = 3.0
#: Elements of the reference's (directions x fine cells) kernel block (bounds its memory to ~ 50 bytes x this).
_REF_BLOCK = 4_000_000
#: The grid path (:func:`_near_grid`, :func:`grid_pays`): GRID_K nodes per pixel side; lobes at least
#: GRID_MIN_HALF_WIDTH pixel heights wide (half width at half maximum) with a window ramp at least GRID_MIN_RAMP
#: wide, when the directions outnumber GRID_MIN_RATIO times the grid's stencils; GRID_BLOCK grid rows per FFT
#: batch, fewer where its arrays (stencils, their FFTs, the map rows they take: ~ 72 B per stencil element) would
#: pass GRID_BLOCK_BYTES. Measured against the direct sum (sun_sky(32), GGX near parts, window
#: 4..8 px): r = 0.4 (half width 2.1 px, ramp 4 px) 0.05 % relative RMS; r = 0.45 with a 2-px ramp 0.15 %, the
#: Catmull-Rom interpolation missing the ramp's curvature (its radius 0.64 px against the 0.5-px spacing).
GRID_K = 2
GRID_MIN_HALF_WIDTH = 2.0
GRID_MIN_RAMP = 3.0
GRID_MIN_RATIO = 4
GRID_BLOCK = 32
GRID_BLOCK_BYTES = 256 << 20


class WindowedLobe(RadialLobe):
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


def half_width(lobe: RadialLobe, theta_max: float = math.pi) -> float:
    """The angle at which the lobe's first channel falls to half its value at the centre (bisection; the lobes
    here fall monotonically), ``theta_max`` if it never does."""

    def u(theta: float) -> float:
        return float(lobe.u(np.array([math.cos(theta)]))[0, 0])

    peak = u(0.0)
    if not peak > 0.0 or u(theta_max) >= 0.5 * peak:
        return theta_max
    lo, hi = 0.0, theta_max
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if u(mid) >= 0.5 * peak else (lo, mid)
    return hi


def cap_mass(lobe: RadialLobe, theta_max: float) -> float:
    """``2 pi int_0^theta_max u(cos theta) sin theta dtheta`` (first channel): Gauss-Legendre on panels graded
    geometrically from a hundredth of the half width, so that the peak of the narrowest lobe is resolved."""
    hw = half_width(lobe, theta_max)
    edges = np.unique(np.concatenate([[0.0], np.geomspace(min(hw, theta_max) * 1e-2, theta_max, 96),
                                      np.linspace(0.0, theta_max, 65)]))
    x, wq = np.polynomial.legendre.leggauss(16)
    a, b = edges[:-1, None], edges[1:, None]
    theta = (0.5 * (b - a) * x + 0.5 * (a + b)).ravel()
    weight = (0.5 * (b - a) * wq).ravel()
    u = np.asarray(lobe.u(np.cos(theta)), dtype=np.float64)[:, 0]
    return float(2.0 * np.pi * np.sum(u * np.sin(theta) * weight))


def _mean_rows(h: int) -> tuple[FloatArray, FloatArray]:
    """:func:`cell_means`' weights of the row above and the row below each row (H,) (the row's own: the rest)."""
    dth = math.pi / h
    x, wq = np.polynomial.legendre.leggauss(8)
    frac = 0.25 * (x + 1.0)  # (theta - theta_i) / dth over (0, 1/2)
    theta_i = (np.arange(h) + 0.5) * dth
    sa_down = np.sin(theta_i[:, None] + frac * dth) @ wq
    sa_up = np.sin(theta_i[:, None] - frac * dth) @ wq
    c_down = (np.sin(theta_i[:, None] + frac * dth) * frac) @ wq / (sa_down + sa_up)
    c_up = (np.sin(theta_i[:, None] - frac * dth) * frac) @ wq / (sa_down + sa_up)
    c_up[0] = 0.0
    c_down[-1] = 0.0
    return c_up, c_down


def cell_means(pixels: NDArray[np.floating]) -> FloatArray:
    """The mean of the bilinear interpolant over each pixel's cell, weighted by solid angle: the separable
    ``(1/8, 3/4, 1/8)`` in ``phi`` (exact) and, in ``theta``, the weights of the two neighbouring rows over the
    cell's halves under ``sin theta`` (Gauss-Legendre; rows clamp at the poles, so the first and last rows take no
    weight from beyond)."""
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    c_up, c_down = _mean_rows(env.shape[0])
    up = np.concatenate([env[:1], env[:-1]])
    down = np.concatenate([env[1:], env[-1:]])
    rows = (1.0 - c_up - c_down)[:, None, None] * env + c_up[:, None, None] * up + c_down[:, None, None] * down
    return np.ascontiguousarray(0.75 * rows + 0.125 * (np.roll(rows, 1, axis=1) + np.roll(rows, -1, axis=1)))


def angular_convolution(pixels: NDArray[np.floating], lobe: RadialLobe, dirs: FloatArray,
                        theta_max: float, *, sub_per_scale: float | None = None,
                        method: Literal["auto", "direct", "grid"] = "auto") -> FloatArray:
    """``B(d) = int u(d . w) L(w) dw`` of the map's bilinear interpolant over the cap ``theta <= theta_max``
    (where ``u`` must vanish beyond), for directions (N, 3) -> (N, 3) (module docstring).

    Cells come ring by ring (the rows and column runs a cap widened by a pixel can touch); a cell is one midpoint
    sample (its pixel, its solid angle) where the lobe is smooth on the pixel's scale, else ``m_theta x m_phi``
    sub-cells (even counts, so that no sub-cell straddles the interpolant's kinks at the pixel centres) with their
    exact solid angles and the interpolant at their centres; a single sample takes the interpolant's mean over
    the cell (:func:`cell_means`), so both kinds of cell integrate the same function. The lobe is tabulated
    against the chord (one-sample cells) and ``sqrt(chord)`` (sub-cells; ``_KERNEL_TABLE`` nodes, linear
    interpolation). The weights are made to sum to :func:`cap_mass` (module docstring). The scale on which the
    lobe varies is its half width at the peak, the distance from the peak further out and, over a
    :class:`WindowedLobe`'s ramp, the window's curvature radius ``(theta1 - theta0) / pi``; ``sub_per_scale``
    (default ``NEAR_SUB_PER_SCALE``) samples span it, so refining it refines every cell the lobe varies in.

    ``method``: ``"direct"`` sums per direction; ``"grid"`` evaluates the same sum on the grid of
    :func:`_near_grid` and interpolates (:func:`_grid_sample`); ``"auto"`` takes the grid for a lobe at least
    ``GRID_MIN_HALF_WIDTH`` pixels wide when there are more directions than ``GRID_MIN_RATIO`` times its nodes.
    """
    env = np.ascontiguousarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    theta_star = min(theta_max, math.pi)
    chord_max = 2.0 * math.sin(0.5 * theta_star)
    s = np.linspace(0.0, 1.0, _KERNEL_TABLE)
    tables = []
    for chord in (chord_max * s, chord_max * s * s):
        table = np.asarray(lobe.u(1.0 - 0.5 * chord * chord), dtype=np.float64)[:, 0]
        table[-1] = 0.0  # the lobe vanishes at the window's end; chords beyond it add nothing
        tables.append(table)
    below = np.flatnonzero(tables[1] < 0.5 * tables[1][0])
    hw_angle = 2.0 * math.asin(0.5 * chord[below[0]]) if below.size and tables[1][0] > 0 else theta_star
    cols = column_phis(w)
    # a window's raised cosine varies on the scale (theta1 - theta0) / pi (its curvature radius) over its ramp
    ramp_lo, ramp_scale = theta_star + 1.0, math.pi
    if isinstance(lobe, WindowedLobe):
        ramp_lo, ramp_scale = lobe.theta0, (lobe.theta1 - lobe.theta0) / math.pi
    sub = NEAR_SUB_PER_SCALE if sub_per_scale is None else sub_per_scale
    args = (np.cos(cols), np.sin(cols), tables[0], tables[1], chord_max, theta_star, hw_angle,
            cap_mass(lobe, theta_star), ramp_lo, ramp_scale, sub, NEAR_MAX_SUB)
    if method == "auto":
        ramp = lobe.theta1 - lobe.theta0 if isinstance(lobe, WindowedLobe) else math.inf
        method = "grid" if grid_pays(hw_angle, ramp, h, dirs.shape[0]) else "direct"
    theta, phi = dirs_to_angles(dirs)
    if method == "grid":
        return _grid_sample(_near_grid(env, args), theta, phi)
    if method != "direct":
        raise ValueError(f"method must be auto, direct or grid, not {method!r}")
    out = np.empty((dirs.shape[0], 3))
    _near_sum_jit(np.ascontiguousarray(theta), np.ascontiguousarray(phi), env, cell_means(env), *args, out)
    return out


def grid_pays(half_width: float, ramp: float, h: int, n: int) -> bool:
    """Whether :func:`angular_convolution` takes the grid for ``n`` directions on an ``h``-row map: a lobe whose
    half width spans ``GRID_MIN_HALF_WIDTH`` pixel heights and whose window ramp (``theta1 - theta0``, the near
    part's other sharp feature) ``GRID_MIN_RAMP`` (where interpolation on the half-pixel grid stays within
    ~ 0.1 % relative RMS of the direct sum), and more directions than ``GRID_MIN_RATIO`` times the grid's
    stencils (below that the direct sum costs less)."""
    pixel = math.pi / h
    resolved = half_width >= GRID_MIN_HALF_WIDTH * pixel and ramp >= GRID_MIN_RAMP * pixel
    return resolved and n > GRID_MIN_RATIO * (GRID_K * h + 1) * GRID_K


def _near_grid(env: FloatArray, args: tuple[Any, ...]) -> FloatArray:
    """:func:`angular_convolution`'s sum on the grid ``theta = o pi / (K H)``, ``o = 0 ... K H`` (both poles and
    every pixel centre's row), ``phi = -pi + (1/2 + c / K) 2 pi / W``, ``c = 0 ... K W - 1`` (every pixel centre's
    column): (K H + 1, K W, 3), ``K = GRID_K``.

    The sum is rotation-invariant about the poles: at ``phi`` shifted by whole pixels its weights shift with it.
    So one stencil per grid row and sub-pixel offset (:func:`_near_stencils_jit`: the normalised weights of the
    map's pixels, exactly those the direct sum applies) gives a whole row of the grid, each stencil row a circular
    correlation along ``phi`` with one row of the map, done with real FFTs (the map's rows transformed once)."""
    h, w = env.shape[:2]
    k = GRID_K
    dth, dph = math.pi / h, 2.0 * math.pi / w
    theta_star = float(args[5])
    c_up, c_down = _mean_rows(h)
    env_hat = np.fft.rfft(env, axis=1)  # (H, W/2 + 1, 3)
    grid = np.empty((k * h + 1, k * w, 3))
    offsets = -math.pi + (0.5 + np.arange(k) / k) * dph
    rows_max = 2 * math.ceil(theta_star / dth) + 4  # map rows a stencil can touch (the cap, +- one pixel)
    block = max(1, min(GRID_BLOCK, GRID_BLOCK_BYTES // (k * rows_max * w * 72)))
    for o0 in range(0, k * h + 1, block):
        th = np.minimum(np.arange(o0, min(o0 + block, k * h + 1)) * (dth / k), math.pi)
        theta = np.repeat(th, k)
        phi = np.tile(offsets, th.size)
        i_lo = np.maximum(0, np.ceil((theta - theta_star) / dth - 0.5).astype(np.int64))
        i_hi = np.minimum(h - 1, np.floor((theta + theta_star) / dth - 0.5).astype(np.int64))
        row0 = np.maximum(i_lo - 1, 0)
        rows = int(np.max(np.minimum(i_hi + 1, h - 1) - row0)) + 1
        st = np.zeros((theta.size, rows, w))
        stencils: Any = _near_stencils_jit  # numba's Dispatcher stub takes no starred tuple
        stencils(theta, phi, row0, env, *args, c_up, c_down, st)
        idx = np.minimum(row0[:, None] + np.arange(rows)[None, :], h - 1)
        b_hat = np.einsum("nrm,nrmc->nmc", np.conj(np.fft.rfft(st, axis=2)), env_hat[idx])
        rows_out = np.fft.irfft(b_hat, n=w, axis=1)  # (n, W, 3): column j of offset s is grid column j K + s
        grid[o0:o0 + th.size] = rows_out.reshape(th.size, k, w, 3).transpose(0, 2, 1, 3).reshape(th.size, k * w, 3)
    return grid


def _grid_sample(grid: FloatArray, theta: FloatArray, phi: FloatArray) -> FloatArray:
    """Catmull-Rom interpolation of :func:`_near_grid`'s grid at ``(theta, phi)`` (N,) -> (N, 3), each value
    clamped to the range of its four nearest nodes (so that it never leaves the range the nodes keep). Rows
    beyond a pole continue on the far side (row ``-o`` is row ``o`` half a turn away)."""
    out = np.empty((theta.shape[0], 3))
    _grid_sample_jit(grid, np.ascontiguousarray(theta), np.ascontiguousarray(phi), GRID_K, out)
    return out


@numba.njit(cache=True, nogil=True)
def _grid_sample_jit(grid: FloatArray, theta: FloatArray, phi: FloatArray, k: int, out: FloatArray) -> None:
    g_h, g_w = grid.shape[0], grid.shape[1]
    kh = g_h - 1
    step_t = math.pi / kh
    step_p = 2.0 * math.pi / g_w
    phi0 = -math.pi + 0.5 * k * step_p  # grid column 0: the first pixel centre
    wy = np.empty(4)
    wx = np.empty(4)
    for n in range(theta.shape[0]):
        y = min(max(theta[n] / step_t, 0.0), float(kh))
        x = (phi[n] - phi0) / step_p
        oy = min(int(y), kh - 1)
        ty = y - oy
        oxf = math.floor(x)
        tx = x - oxf
        ox = int(oxf)
        for t, wt in ((ty, wy), (tx, wx)):
            t2, t3 = t * t, t * t * t
            wt[0] = 0.5 * (-t3 + 2.0 * t2 - t)
            wt[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0)
            wt[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t)
            wt[3] = 0.5 * (t3 - t2)
        for c in range(3):
            acc = 0.0
            lo, hi = np.inf, -np.inf
            for a in range(4):
                r = oy - 1 + a
                shift = 0
                if r < 0:
                    r, shift = -r, g_w // 2
                elif r > kh:
                    r, shift = 2 * kh - r, g_w // 2
                row = 0.0
                for b in range(4):
                    v = grid[r, (ox - 1 + b + shift) % g_w, c]
                    row += wx[b] * v
                    if (a == 1 or a == 2) and (b == 1 or b == 2):
                        lo, hi = min(lo, v), max(hi, v)
                acc += wy[a] * row
            out[n, c] = min(max(acc, lo), hi)


@numba.njit(cache=True, nogil=True)
def _sub_offsets(dph: float, max_sub: int) -> tuple[FloatArray, FloatArray]:
    """cos and sin of the sub-columns' azimuths relative to their pixel's centre, per sub-division count."""
    off_c = np.ones((max_sub + 1, max_sub))
    off_s = np.zeros((max_sub + 1, max_sub))
    for m in range(1, max_sub + 1):
        for q in range(m):
            off_c[m, q] = math.cos(((q + 0.5) / m - 0.5) * dph)
            off_s[m, q] = math.sin(((q + 0.5) / m - 0.5) * dph)
    return off_c, off_s


@numba.njit(cache=True, nogil=True, inline="always")
def taps_rgb(env: FloatArray, y0: int, y1: int, x0: int, x1: int, w00: float, w01: float, w10: float,
             w11: float) -> tuple[float, float, float]:
    """The four texels (y0 | y1, x0 | x1) of an RGB map weighted by w00, w01, w10, w11, per channel (a bilinear
    tap; the chain's level 0 and the near sum share it)."""
    return (w00 * env[y0, x0, 0] + w01 * env[y0, x1, 0] + w10 * env[y1, x0, 0] + w11 * env[y1, x1, 0],
            w00 * env[y0, x0, 1] + w01 * env[y0, x1, 1] + w10 * env[y1, x0, 1] + w11 * env[y1, x1, 1],
            w00 * env[y0, x0, 2] + w01 * env[y0, x1, 2] + w10 * env[y1, x0, 2] + w11 * env[y1, x1, 2])


@numba.njit(cache=True, nogil=True)
def _near_one(th: float, ph: float, env: FloatArray, means: FloatArray, cos_col: FloatArray, sin_col: FloatArray,
              table: FloatArray, fine: FloatArray, chord_max: float, theta_star: float, hw_angle: float,
              ramp_lo: float, ramp_scale: float, sub_per_scale: float, max_sub: int, off_c: FloatArray,
              off_s: FloatArray, acc: FloatArray, splat: bool, st: FloatArray, row0: int, c_up: FloatArray,
              c_down: FloatArray) -> float:
    """One direction ``(th, ph)`` of :func:`angular_convolution`'s sum, unnormalised; returns the sum of its
    weights. ``splat`` False: the weighted values go to ``acc`` (3,). True: the weights go to the stencil ``st``
    (rows ``row0 ...`` of the map, all columns) as weights of the map's pixels, a one-sample cell's mean spread
    over the nine pixels :func:`cell_means` takes it from (``c_up``, ``c_down``: its row weights)."""
    h, w = env.shape[0], env.shape[1]
    dth = math.pi / h
    dph = 2.0 * math.pi / w
    last = table.shape[0] - 1
    inv_chord = 1.0 / chord_max
    cos_star = math.cos(theta_star)
    ctd, std = math.cos(th), math.sin(th)
    cpd, spd = math.cos(ph), math.sin(ph)
    x_d = (ph + math.pi) / dph - 0.5
    i_lo = max(0, int(math.ceil((th - theta_star) / dth - 0.5)))
    i_hi = min(h - 1, int(math.floor((th + theta_star) / dth - 0.5)))
    acc0 = acc1 = acc2 = 0.0
    wsum = 0.0
    for i in range(i_lo, i_hi + 1):
        t_top, t_bot = i * dth, (i + 1) * dth
        th_r = t_top + 0.5 * dth
        a = ctd * math.cos(th_r)
        b = std * math.sin(th_r)
        sin_max = 1.0 if t_top <= 0.5 * math.pi <= t_bot else max(math.sin(t_top), math.sin(t_bot))
        half_diag = 0.5 * math.sqrt(dth * dth + (sin_max * dph) ** 2)
        cell_sa = dph * (math.cos(t_top) - math.cos(t_bot))
        # a cell is one sample when the lobe's scale there, max(half width, distance), spans sub_per_scale
        # times its longer side: always if the half width does, else beyond the distance rho_one
        side = sub_per_scale * max(dth, sin_max * dph)
        cos_one = 2.0 if hw_angle >= side else math.cos(min(side + half_diag, math.pi))
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
            t_c = a + b * (cpd * cos_col[j] + spd * sin_col[j])
            dist = math.acos(min(1.0, max(-1.0, t_c)))
            in_ramp = dist + half_diag > ramp_lo and ramp_scale < side
            if t_c <= cos_one and not in_ramp:  # one midpoint sample: the pixel at its centre
                x = math.sqrt(max(2.0 - 2.0 * t_c, 0.0)) * inv_chord * last
                if x >= last:
                    continue
                node = int(x)
                kv = (table[node] + (x - node) * (table[node + 1] - table[node])) * cell_sa
                wsum += kv
                if splat:
                    for dr in range(-1, 2):
                        rw = c_up[i] if dr < 0 else (c_down[i] if dr > 0 else 1.0 - c_up[i] - c_down[i])
                        if rw == 0.0:
                            continue
                        r = min(max(i + dr, 0), h - 1) - row0
                        st[r, (j - 1) % w] += 0.125 * kv * rw
                        st[r, j] += 0.75 * kv * rw
                        st[r, (j + 1) % w] += 0.125 * kv * rw
                else:
                    acc0 += kv * means[i, j, 0]
                    acc1 += kv * means[i, j, 1]
                    acc2 += kv * means[i, j, 2]
                continue
            scale = max(hw_angle, dist - half_diag)
            if in_ramp:
                scale = min(scale, ramp_scale)
            # even counts (>= 2 on both sides): the sub-cells meet at the pixel's centre lines, where the
            # interpolant has its kinks, and take their share of the neighbours' values as the means do
            m_t = math.ceil(sub_per_scale * dth / scale)
            m_p = math.ceil(sub_per_scale * sin_max * dph / scale)
            m_t = min(max_sub, max(2, m_t + (m_t & 1)))
            m_p = min(max_sub, max(2, m_p + (m_p & 1)))
            cdj = cpd * cos_col[j] + spd * sin_col[j]  # cos and sin of the pixel's azimuth from d's
            sdj = cpd * sin_col[j] - spd * cos_col[j]
            for p in range(m_t):
                fy = (p + 0.5) / m_t - 0.5
                ths = th_r + fy * dth
                sa = (dph / m_p) * (math.cos(ths - 0.5 * dth / m_t) - math.cos(ths + 0.5 * dth / m_t))
                ca = ctd * math.cos(ths)
                cb = std * math.sin(ths)
                y = min(max(i + fy, 0.0), h - 1.0)
                y0 = min(int(y), max(h - 2, 0))
                gy = y - y0
                y1 = min(y0 + 1, h - 1)
                for q in range(m_p):
                    fx = (q + 0.5) / m_p - 0.5
                    t = ca + cb * (cdj * off_c[m_p, q] - sdj * off_s[m_p, q])
                    x = math.sqrt(math.sqrt(max(2.0 - 2.0 * t, 0.0)) * inv_chord) * last
                    if x >= last:
                        continue
                    node = int(x)
                    kv = (fine[node] + (x - node) * (fine[node + 1] - fine[node])) * sa
                    xf = j + fx
                    x0f = math.floor(xf)
                    gx = xf - x0f
                    x0 = int(x0f) % w
                    x1 = (x0 + 1) % w
                    wsum += kv
                    gx1, gy1 = 1.0 - gx, 1.0 - gy
                    w00, w01, w10, w11 = kv * gx1 * gy1, kv * gx * gy1, kv * gx1 * gy, kv * gx * gy
                    if splat:
                        st[y0 - row0, x0] += w00
                        st[y0 - row0, x1] += w01
                        st[y1 - row0, x0] += w10
                        st[y1 - row0, x1] += w11
                    else:
                        t0, t1, t2 = taps_rgb(env, y0, y1, x0, x1, w00, w01, w10, w11)
                        acc0 += t0
                        acc1 += t1
                        acc2 += t2
    acc[0], acc[1], acc[2] = acc0, acc1, acc2
    return wsum


@numba.njit(cache=True, nogil=True)
def _at_d(th: float, ph: float, h: int, w: int) -> tuple[int, int, int, int, float, float]:
    """The interpolant's pixels and weights at ``(th, ph)``: rows ``r0, r1``, columns ``c0, c1``, ``gy``, ``gx``."""
    dth = math.pi / h
    dph = 2.0 * math.pi / w
    yd = min(max(th / dth - 0.5, 0.0), h - 1.0)
    r0 = min(int(yd), max(h - 2, 0))
    r1 = min(r0 + 1, h - 1)
    x_d = (ph + math.pi) / dph - 0.5
    c0f = math.floor(x_d)
    c0 = int(c0f) % w
    return r0, r1, c0, (c0 + 1) % w, yd - r0, x_d - c0f


@numba.njit(cache=True, nogil=True)
def _near_sum_jit(theta: FloatArray, phi: FloatArray, env: FloatArray, means: FloatArray, cos_col: FloatArray,
                  sin_col: FloatArray, table: FloatArray, fine: FloatArray, chord_max: float, theta_star: float,
                  hw_angle: float, mass: float, ramp_lo: float, ramp_scale: float, sub_per_scale: float, max_sub: int,
                  out: FloatArray) -> None:
    """:func:`angular_convolution`'s sum, one direction at a time (``method="direct"``)."""
    h, w = env.shape[0], env.shape[1]
    dth = math.pi / h
    dph = 2.0 * math.pi / w
    # a lobe the finest sub-cells resolve is scaled to its mass; a narrower one gives the missing mass to L(d)
    resolved = hw_angle * max_sub >= sub_per_scale * max(dth, dph)
    off_c, off_s = _sub_offsets(dph, max_sub)
    acc = np.zeros(3)
    dummy = np.zeros((1, 1))
    empty = np.zeros(1)
    for n in range(theta.shape[0]):
        wsum = _near_one(theta[n], phi[n], env, means, cos_col, sin_col, table, fine, chord_max, theta_star,
                         hw_angle, ramp_lo, ramp_scale, sub_per_scale, max_sub, off_c, off_s, acc, False, dummy, 0,
                         empty, empty)
        # unit mass (module docstring): scaled to the lobe's mass, or, for a lobe the sub-cells do not resolve,
        # the mass they miss given to the interpolant at d. Every weight stays positive.
        r0, r1, c0, c1, gy, gx = _at_d(theta[n], phi[n], h, w)
        rest = 0.0 if resolved else max(mass - wsum, 0.0)
        norm = mass / wsum if wsum > 0.0 and (resolved or wsum > mass) else 1.0
        for c in range(3):
            ld = ((env[r0, c0, c] * (1.0 - gx) + env[r0, c1, c] * gx) * (1.0 - gy)
                  + (env[r1, c0, c] * (1.0 - gx) + env[r1, c1, c] * gx) * gy)
            out[n, c] = acc[c] * norm + rest * ld


@numba.njit(cache=True, nogil=True)
def _near_stencils_jit(theta: FloatArray, phi: FloatArray, row0: NDArray[np.int64], env: FloatArray,
                       cos_col: FloatArray, sin_col: FloatArray, table: FloatArray, fine: FloatArray,
                       chord_max: float, theta_star: float, hw_angle: float, mass: float, ramp_lo: float,
                       ramp_scale: float, sub_per_scale: float, max_sub: int, c_up: FloatArray, c_down: FloatArray,
                       st: FloatArray) -> None:
    """The normalised weights of the map's pixels (rows ``row0[n] ...``, all columns) that :func:`_near_sum_jit`
    applies for direction ``n``: ``st`` (N, R, W), zero on entry."""
    h, w = env.shape[0], env.shape[1]
    dth = math.pi / h
    dph = 2.0 * math.pi / w
    resolved = hw_angle * max_sub >= sub_per_scale * max(dth, dph)
    off_c, off_s = _sub_offsets(dph, max_sub)
    acc = np.zeros(3)
    for n in range(theta.shape[0]):
        wsum = _near_one(theta[n], phi[n], env, env, cos_col, sin_col, table, fine, chord_max, theta_star, hw_angle,
                         ramp_lo, ramp_scale, sub_per_scale, max_sub, off_c, off_s, acc, True, st[n], row0[n], c_up,
                         c_down)
        rest = 0.0 if resolved else max(mass - wsum, 0.0)
        norm = mass / wsum if wsum > 0.0 and (resolved or wsum > mass) else 1.0
        st[n] *= norm
        if rest > 0.0:
            r0, r1, c0, c1, gy, gx = _at_d(theta[n], phi[n], h, w)
            st[n, r0 - row0[n], c0] += rest * (1.0 - gx) * (1.0 - gy)
            st[n, r0 - row0[n], c1] += rest * gx * (1.0 - gy)
            st[n, r1 - row0[n], c0] += rest * (1.0 - gx) * gy
            st[n, r1 - row0[n], c1] += rest * gx * gy


def brute_force(pixels: NDArray[np.floating], lobe: RadialLobe, dirs: FloatArray, *,
                oversample: int | None = None) -> FloatArray:
    """The dense reference (tests and benchmarks; O(N H W m^2)): ``sum_s u(d . w_s) L(w_s) w_s`` over the map's
    cells cut ``m`` x ``m`` (module docstring), each fine cell integrated by the 2 x 2 Gauss-Legendre product rule
    in ``(theta, phi)`` with the weight ``sin theta`` (``w_s``), the interpolant at the nodes. ``m`` (even, so that
    no fine cell straddles the interpolant's kinks at the pixel centres: it is bilinear in each) defaults to
    ``REF_SUB_PER_HALF_WIDTH`` nodes across the lobe's half width, at least 2 fine cells per pixel side. (The
    midpoint rule at the fine cells' centres is second order only: beside a sun its cross term ``u' L' h^3 / 12``
    per cell left the reference 0.7 % off at m = 2 for Phong s = 64 on a 32-row map; this rule is 4th order in
    ``h / m``: 0.0065 % there.)"""
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    if oversample is None:
        need = REF_SUB_PER_HALF_WIDTH * (math.pi / h) / half_width(lobe)  # nodes per pixel side, 2 per fine cell
        oversample = max(2, 2 * math.ceil(0.25 * need))
    m = int(oversample)
    x, wq = np.polynomial.legendre.leggauss(2)
    theta = ((np.arange(h * m)[:, None] + 0.5 * (x + 1.0)) * (math.pi / (h * m))).ravel()
    w_theta = np.tile(wq, h * m) * (0.5 * math.pi / (h * m)) * np.sin(theta)
    phi = ((np.arange(w * m)[:, None] + 0.5 * (x + 1.0)) * (2.0 * math.pi / (w * m))).ravel() - math.pi
    w_phi = np.tile(wq, w * m) * (math.pi / (w * m))
    fine = angles_to_dirs(theta[:, None], phi[None, :]).reshape(-1, 3)
    values = sample_latlong(env[None], fine)[:, 0, :] * (w_theta[:, None] * w_phi[None, :]).reshape(-1, 1)
    out = np.empty((dirs.shape[0], 3))
    chunk = max(1, _REF_BLOCK // fine.shape[0])
    for s in range(0, dirs.shape[0], chunk):
        kern = np.asarray(lobe.u(dirs[s:s + chunk] @ fine.T), dtype=np.float64)[..., 0]
        out[s:s + chunk] = kern @ values
    return out
