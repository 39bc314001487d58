"""The mid-elevation rule of issue 14 (interpolated lobes within 1.5x their neighbours) on several materials, with
the bisection pass of relight.sgfit_refine, and the fit's fan-out over elevations (relight.sgfit.cold_elevation)."""

from __future__ import annotations

import math
import tempfile
from concurrent.futures import ProcessPoolExecutor
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.measured import MERLBRDF, tabulate_merl, write_merl
from relight.brdf.spec import parse_brdf
from relight.brdf.vmf import vmf
from relight.sg_slice import slice_grid, transfer_slice
from relight.sgfit import ColdElevation, FitSettings, cold_elevation, fit_gaussian_lobes
from relight.sgfit_refine import MID_RATIO

MERL_PREFIX = "merl-file:"


@cache
def brdf_of(spec: str) -> Any:
    """The model of ``spec``, or with ``merl-file:`` the MERL .binary file written from it (relight.brdf.measured:
    the model tabulated at MERL's sample angles and read back through MERLBRDF's interpolation)."""
    if not spec.startswith(MERL_PREFIX):
        return parse_brdf(spec)
    path = Path(tempfile.mkdtemp(prefix="sgfit-merl-")) / "model.binary"
    write_merl(path, tabulate_merl(parse_brdf(spec.removeprefix(MERL_PREFIX))))
    return MERLBRDF(path)


@cache
def fit(spec: str, max_lobes: int, max_inserted: int | None = None) -> GaussianLobes:
    st = FitSettings(max_lobes=max_lobes)
    if max_inserted is not None:
        st.max_inserted = max_inserted
    return fit_gaussian_lobes(brdf_of(spec), st)


def ratios(m: GaussianLobes) -> np.ndarray:
    e = m.errors
    assert e is not None
    return np.asarray(m.fit["mid_errors"]) / np.maximum(e[:-1], e[1:])


def interpolated_error(m: GaussianLobes, spec: str, theta: float) -> float:
    """Relative L2 error of the material's interpolated lobes at theta against the BRDF's slice over the whole
    sphere (the fit's metric: lobe mass below the horizon counts as error), from GaussianLobes.params_at (what
    the renderers interpolate) and relight.brdf.vmf, not the fit's own basis code."""
    grid = slice_grid(160, 24)
    t, valid = transfer_slice(brdf_of(spec), grid, theta)
    t = np.repeat(t, 3, axis=1) if t.shape[1] == 1 else t
    wi = grid.world(theta)
    mu, sigma, w = m.params_at(np.array(theta))
    r = np.array([-math.sin(theta), 0.0, math.cos(theta)])
    e = np.array([math.cos(theta), 0.0, math.sin(theta)])  # r rotated by 90 degrees toward n = +z
    c = np.cos(mu)[:, None] * r + np.sin(mu)[:, None] * e  # (K, 3)
    approx = vmf(wi @ c.T, 1.0 / sigma**2) @ w  # (M, 3)
    wt = grid.weights * valid
    return math.sqrt(float(np.sum(wt[:, None] * (approx - t) ** 2)) / float(np.sum(wt[:, None] * t * t)))


# Before the bisection pass (max_inserted = 0) the rule fails on each of these: measured max ratios 2.81
# (Torrance-Sparrow alpha 0.2, K = 3, at 34 degrees: one wide lobe becomes two), 6.1 (alpha 0.05: sharp lobes whose
# mu moves faster than linearly). With it, measured 1.26 and 1.33. (GGX alpha 0.2, K = 3: 2.62 -> 1.11;
# bench/fit.py --materials prints all of them.)
CASES = [("torrance-sparrow:alpha=0.2,fresnel=none", 3), ("torrance-sparrow:alpha=0.05,fresnel=none", 3)]


@pytest.mark.parametrize(("spec", "max_lobes"), CASES)
def test_mid_elevations_within_1_5x_their_neighbours(spec: str, max_lobes: int) -> None:
    plain = fit(spec, max_lobes, 0)
    assert ratios(plain).max() > MID_RATIO  # the hard case is real
    check_rule(fit(spec, max_lobes), spec)


def check_rule(m: GaussianLobes, spec: str) -> None:
    r = ratios(m)
    print(spec, "elevations", m.elevations.size, "max ratio", r.max().round(3),
          "envelope", np.round(m.fit["envelope_ratios"], 2).tolist())
    assert np.all(r <= MID_RATIO), r.round(2)
    assert m.fit["elevations_fitted"] == 15 and m.elevations.size == 15 + m.fit["elevations_inserted"] <= 15 + 24
    # the reported mid errors are what a renderer gets: GaussianLobes.transfer at the mid-elevations (tolerance:
    # float rounding only; the grids are the same)
    mids = np.asarray(m.fit["mid_elevations"])
    for j in np.argsort(-r)[:3]:
        assert interpolated_error(m, spec, float(mids[j])) == pytest.approx(m.fit["mid_errors"][j], rel=1e-9)
    e = m.errors
    assert e is not None
    assert np.all(np.isfinite(e)) and np.all(np.diff(m.elevations) > 0)


# Sharp lobes with extra lobes where K = 3 exceeds 5 %, the case the rule failed before lobes kept their slots
# (relight.sg_order.FADE_TOLERANCE): GGX alpha 0.1 with up to 5 lobes measured 19.7x without the bisection pass and
# 5.3x with it (live lobes hopped slots between 0 and 12 degrees; the dead lobes left behind were pinned toward the
# other side). Now, measured max ratios (the bisection pass included): GGX 0.96 (no elevation inserted: the plain
# fit already holds), Beckmann alpha 0.1 1.23 with up to 5 lobes and 1.35 with K = 3, and a MERL .binary file
# written from GGX 0.1 0.96 (its fit is the model's: tests/relight/test_sgfit.py).
SHARP = [("ggx:alpha=0.1", 5), ("torrance-sparrow:alpha=0.1,fresnel=none", 5),
         ("torrance-sparrow:alpha=0.1,fresnel=none", 3), (MERL_PREFIX + "ggx:alpha=0.1", 5)]


@pytest.mark.parametrize(("spec", "max_lobes"), SHARP)
def test_sharp_lobes_with_extra_lobes_hold_the_rule(spec: str, max_lobes: int) -> None:
    check_rule(fit(spec, max_lobes), spec)


@pytest.mark.parametrize(("spec", "steady"), [("ggx:alpha=0.1", 3), ("ggx:alpha=0.3", 0)])
def test_lobes_keep_their_slots_without_bisection(spec: str, steady: int) -> None:
    """The lobe order alone (no inserted elevation) holds the rule with up to 5 lobes: each lobe keeps its slot
    while it lives. Before: GGX alpha 0.1 19.7x at 0-6 degrees (a lobe hopping slots at a 1e-6 gain), GGX alpha 0.3
    4.64x; measured now 0.96 and 1.00."""
    m = fit(spec, 5, 0)
    assert np.all(ratios(m) <= MID_RATIO), ratios(m).round(2)
    live = m.weight.sum(axis=2) > 0.0
    # GGX 0.1 keeps the same three lobes from 0 to 19 degrees: no slot fades out while another fades in (the hop
    # of before). GGX 0.3 does change its lobes there (two become three, measured): only the rule is checked.
    hops = (live[:-1] & ~live[1:]).sum(axis=1) * (~live[:-1] & live[1:]).sum(axis=1)
    assert np.all(hops[:steady] == 0), live[: steady + 1].astype(int)


def test_envelope_is_reported_against_the_original_neighbours() -> None:
    """An inserted elevation could pass the rule by fitting badly itself; the envelope measures everything inside
    each original interval against its original ends, so it is never below the plain ratio there and it is what
    the report states. Torrance-Sparrow alpha 0.2, K = 3: measured at most 2.06 (the basin switch at 34 degrees,
    bridged by two inserted elevations, one of them worse than the original ends; the rule itself, between
    neighbouring rows, holds at 1.26); 2.81 before."""
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
