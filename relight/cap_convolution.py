"""Convolution of a lat-long map with a radial lobe that vanishes beyond a cap, summed over the cap's pixels.

``B(d) = sum_k L_k dOmega_k u(d . w_k)`` over the pixels within ``theta_max`` of each direction (the pixel-centre
quadrature of the whole sphere, restricted to the cap): the near part of a lobe that the map cannot resolve in
spherical harmonics (``relight.cube_chain``'s split levels). :class:`WindowedLobe` cuts a lobe into such a near
part and the smooth far part with a raised-cosine window (the two sum to the lobe exactly); :func:`brute_force`
is the dense sum over every pixel that the cap sum is tested against.
"""

from __future__ import annotations

import math
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix

from relight.brdf.base import RadialLobe
from relight.conventions import column_phis, dirs_to_angles, latlong_dirs, pixel_solid_angles, require_rgb_latlong
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: (direction, pixel) pairs per block of the angular path's sparse sum (bounds its memory to ~ 100 bytes x this).
_PAIRS_PER_BLOCK = 2_000_000
#: Nodes of the tabulated near lobe (uniform in the chord up to the window's end; module docstring of
#: :func:`angular_convolution`).
_KERNEL_TABLE = 16384


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
