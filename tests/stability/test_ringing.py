"""Ringing: the Gibbs overshoot and the negative lobes of a truncated lobe, measured and bounded, and what optional
windowing (Hann, Lanczos sigma factors) buys and costs (``relight.tradeoff.window_tradeoff``).

Bounds, from ``B(C) = int L(w) u_F(C . w) dw`` with ``int u_F dw = 1`` (Lambda_0 rho_0 = 1 for a normalised lobe)
and ``L >= 0``: ``B >= min(u_F, 0) int L`` (the report's ``lower_bound_rgb``) and ``B <= max L int max(u_F, 0) dw``
(the overshoot bound). ``u_F`` is evaluated here independently with scipy's Legendre polynomials.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.special import eval_legendre

from relight.brdf.coefficients import phong_transfer, window_factors
from relight.brdf.radial import Phong
from relight.conventions import latlong_dirs
from relight.envmap import read_envmap, resample_latlong
from relight.prefilter import prefilter_radial
from relight.tradeoff import window_tradeoff

from ._hyp import stable

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"


@cache
def env(name: str = "courtyard", rows: int = 32) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


def positive_mass(s: float, order: int, window: str = "none") -> float:
    """``int max(u_F, 0) dOmega`` of the (windowed) order-F Phong lobe, on 20001 points in cos(theta)."""
    transfer = phong_transfer(s, order) * window_factors(order, window)
    t = np.linspace(-1.0, 1.0, 20001)
    u = sum((2 * l + 1) / (4 * math.pi) * transfer[l] * eval_legendre(l, t) for l in range(order + 1))
    return float(2.0 * math.pi * np.trapezoid(np.maximum(u, 0.0), t))


def half_sky(rows: int = 64) -> np.ndarray:
    """1 above the horizon, 0 below: a step, the classical Gibbs set-up."""
    px = np.zeros((rows, 2 * rows, 3))
    px[: rows // 2] = 1.0
    return px


@stable(8)
@given(s=st.sampled_from([64.0, 256.0, 1024.0]), order=st.integers(6, 30), window=st.sampled_from(["none", "hann"]))
def test_gibbs_overshoot_and_undershoot_are_bounded(s: float, order: int, window: str) -> None:
    """On a step (half sky), the order-F output overshoots 1 and undershoots 0 near the horizon; both stay within
    the bounds (1e-9 slack for rounding)."""
    res = prefilter_radial(half_sky(), Phong(s), order=order, size=64, window=window)
    y = res.map[..., 1]
    over = positive_mass(s, order, window)
    assert y.max() <= over + 1e-9, (y.max(), over)
    lower = res.report.ringing.lower_bound_rgb[1]
    assert y.min() >= lower - 1e-9
    assert lower <= 0.0 and over >= 1.0 - 1e-9


def test_gibbs_overshoot_is_real_and_windowing_tames_it() -> None:
    """A sharp lobe cut at a low order: measurable overshoot (above 1 by > 1 %) and undershoot (below 0) on the
    step; the Hann window reduces both (seed 000 does not window; the window trades accuracy for ringing)."""
    plain = prefilter_radial(half_sky(), Phong(1024.0), order=12, size=64).map[..., 1]
    hann = prefilter_radial(half_sky(), Phong(1024.0), order=12, size=64, window="hann").map[..., 1]
    assert plain.max() > 1.01 and plain.min() < -0.01
    assert hann.max() < plain.max() and hann.min() > plain.min()


@pytest.mark.parametrize(("s", "order"), [(64.0, 12), (512.0, 20), (2048.0, 31)])
def test_windowing_shrinks_the_negative_lobe_and_reports_its_cost(s: float, order: int) -> None:
    """``window_tradeoff`` on a map with a sun: Hann and Lanczos make the kernel's negative lobe and the negative
    output texels smaller; the RMS error of each choice against the angular reference is reported (finite, and
    different from the unwindowed one: windowing is not free)."""
    px = env().copy()
    px[6, 20] = 1e4 * px.mean()
    rows = {r["window"]: r for r in window_tradeoff(px, Phong(s), order=order, size=16)}
    none = rows["none"]
    assert none["kernel_min"] < 0.0 and none["negative_fraction"] > 0.0
    for w in ("hann", "lanczos"):
        r = rows[w]
        assert abs(r["kernel_min_relative"]) < abs(none["kernel_min_relative"]), (w, r, none)
        assert r["negative_fraction"] <= none["negative_fraction"]
        assert r["min_output_relative"] >= none["min_output_relative"]
        assert math.isfinite(r["relative_rms"]) and r["relative_rms"] != none["relative_rms"]
        assert min(r["lower_bound_rgb"]) >= min(none["lower_bound_rgb"])


def test_negative_lobe_of_a_delta_light_reaches_the_reported_bound() -> None:
    """A single lit pixel reflects ``q L u_F``: its most negative output lies between the report's bound and half of
    it (the 64-row output samples u_F's negative lobe finely enough), i.e. the bound is tight, not just valid."""
    px = np.zeros((64, 128, 3))
    px[20, 30] = 1.0
    res = prefilter_radial(px, Phong(512.0), order=16, size=64)
    lower = res.report.ringing.lower_bound_rgb[0]
    got = res.map[..., 0].min()
    assert lower < 0.0 and lower - 1e-15 <= got <= 0.5 * lower
    # the most negative texel sits on the first negative ring of u_F around the light
    i, j = np.unravel_index(np.argmin(res.map[..., 0]), res.map.shape[:2])
    angle = math.acos(float(np.clip(latlong_dirs(64, 128)[i, j] @ latlong_dirs(64, 128)[20, 30], -1, 1)))
    assert 0.5 * math.pi / 16 < angle < 3.0 * math.pi / 16
