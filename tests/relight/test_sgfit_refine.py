"""The mid-elevation rule of issue 14 (interpolated lobes within 1.5x their neighbours) on several materials, with
the bisection pass of relight.sgfit_refine, and the fit's fan-out over elevations (relight.sgfit.cold_elevation)."""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from functools import cache
from typing import Any

import numpy as np
import pytest

from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.spec import parse_brdf
from relight.brdf.vmf import vmf
from relight.sg_slice import slice_grid, transfer_slice
from relight.sgfit import ColdElevation, FitSettings, cold_elevation, fit_gaussian_lobes
from relight.sgfit_refine import MID_RATIO


@cache
def fit(spec: str, max_lobes: int, max_inserted: int | None = None) -> GaussianLobes:
    st = FitSettings(max_lobes=max_lobes)
    if max_inserted is not None:
        st.max_inserted = max_inserted
    return fit_gaussian_lobes(parse_brdf(spec), st)


def ratios(m: GaussianLobes) -> np.ndarray:
    e = m.errors
    assert e is not None
    return np.asarray(m.fit["mid_errors"]) / np.maximum(e[:-1], e[1:])


def interpolated_error(m: GaussianLobes, spec: str, theta: float) -> float:
    """Relative L2 error of the material's interpolated lobes at theta against the BRDF's slice over the whole
    sphere (the fit's metric: lobe mass below the horizon counts as error), from GaussianLobes.params_at (what
    the renderers interpolate) and relight.brdf.vmf, not the fit's own basis code."""
    grid = slice_grid(160, 24)
    t, valid = transfer_slice(parse_brdf(spec), grid, theta)
    t = np.repeat(t, 3, axis=1) if t.shape[1] == 1 else t
    wi = grid.world(theta)
    mu, sigma, w = m.params_at(np.array(theta))
    r = np.array([-math.sin(theta), 0.0, math.cos(theta)])
    e = np.array([math.cos(theta), 0.0, math.sin(theta)])  # r rotated by 90 degrees toward n = +z
    c = np.cos(mu)[:, None] * r + np.sin(mu)[:, None] * e  # (K, 3)
    approx = vmf(wi @ c.T, 1.0 / sigma**2) @ w  # (M, 3)
    wt = grid.weights * valid
    return math.sqrt(float(np.sum(wt[:, None] * (approx - t) ** 2)) / float(np.sum(wt[:, None] * t * t)))


# Before the bisection pass (max_inserted = 0) the rule failed on each of these: measured max ratios 2.81
# (Torrance-Sparrow alpha 0.2, K = 3, at 34 degrees), 6.1 (alpha 0.05: sharp lobes whose mu moves faster than
# linearly) and 4.64 (GGX alpha 0.3 with up to 5 lobes).
# (GGX alpha 0.2, K = 3: 2.62 -> 1.11; bench/fit.py --materials prints all of them.)
CASES = [("torrance-sparrow:alpha=0.2,fresnel=none", 3), ("torrance-sparrow:alpha=0.05,fresnel=none", 3),
         ("ggx:alpha=0.3", 5)]


@pytest.mark.parametrize(("spec", "max_lobes"), CASES)
def test_mid_elevations_within_1_5x_their_neighbours(spec: str, max_lobes: int) -> None:
    plain = fit(spec, max_lobes, 0)
    assert ratios(plain).max() > MID_RATIO  # the hard case is real
    m = fit(spec, max_lobes)
    r = ratios(m)
    print(spec, max_lobes, "elevations", m.elevations.size, "max ratio", r.max().round(3),
          "envelope", np.round(m.fit["envelope_ratios"], 2).tolist())
    assert np.all(r <= MID_RATIO), r.round(2)
    assert m.fit["elevations_fitted"] == 15 and m.elevations.size == 15 + m.fit["elevations_inserted"] <= 15 + 24
    # the reported mid errors are what a renderer gets: GaussianLobes.transfer at the mid-elevations (tolerance:
    # float rounding only; the grids are the same)
    mids = np.asarray(m.fit["mid_elevations"])
    for j in np.argsort(-r)[:3]:
        assert interpolated_error(m, spec, float(mids[j])) == pytest.approx(m.fit["mid_errors"][j], rel=1e-9)
    # the per-elevation targets of the issue still hold on the fitted grid (inserted elevations only add rows)
    e = m.errors
    assert e is not None
    assert np.all(np.isfinite(e)) and np.all(np.diff(m.elevations) > 0)


def test_envelope_is_reported_against_the_original_neighbours() -> None:
    """An inserted elevation could pass the rule by fitting badly itself; the envelope measures everything inside
    each original interval against its original ends, so it is never below the plain ratio there and it is what
    the report states. Torrance-Sparrow alpha 0.2, K = 3: measured at most 1.61 (the basin switch at 34 degrees,
    bridged by an inserted elevation at 35 degrees with 2.4 % against 1.49 and 1.45 % at its ends); 2.81 before."""
    m = fit("torrance-sparrow:alpha=0.2,fresnel=none", 3)
    env = np.asarray(m.fit["envelope_ratios"])
    assert env.size == 14 and np.all(np.isfinite(env))
    plain = ratios(fit("torrance-sparrow:alpha=0.2,fresnel=none", 3, 0))
    untouched = plain <= 1.35  # intervals the pass left alone: the envelope is their plain ratio
    np.testing.assert_allclose(env[untouched], plain[untouched], rtol=1e-9)
    assert env.max() < plain.max()


def _cold(args: tuple[str, Any, float, bool]) -> ColdElevation:
    spec, st, th, first = args
    return cold_elevation(parse_brdf(spec), st, th, first)


def test_fanned_out_cold_part_equals_the_serial_fit() -> None:
    """The per-elevation part runs in other processes (as Dask runs it in the worker): the fit is identical."""
    spec = "ggx:alpha=0.3"
    st = FitSettings(elevations=6, theta_max=math.radians(70.0))
    serial = fit_gaussian_lobes(parse_brdf(spec), st)
    with ProcessPoolExecutor(2) as pool:
        def fan(items: list[tuple[float, bool]]) -> list[ColdElevation]:
            return list(pool.map(_cold, [(spec, st, th, first) for th, first in items]))
        fanned = fit_gaussian_lobes(parse_brdf(spec), st, cold_map=fan)
    for name in ("elevations", "mu", "sigma", "weight", "errors"):
        np.testing.assert_array_equal(getattr(fanned, name), getattr(serial, name), err_msg=name)
