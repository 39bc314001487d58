"""Seed 002's predictions for a planner (relight.sg_predict) against what the full fit and the chain produce."""

from __future__ import annotations

import math

import numpy as np
import pytest

from relight.brdf.models import TorranceSparrow
from relight.errors import InputError
from relight.gaussian_chain import build_chain
from relight.sg_predict import chain_cost, object_cost, predict_fit_error, sphere_error
from relight.sgfit import FitSettings, fit_gaussian_lobes


def test_coarse_fit_predicts_the_full_fit() -> None:
    """The coarse fit (960 instead of 3840 nodes, 80 instead of 200 iterations) against the full fit at the same 6
    elevations. Measured: within 4 % of each other (relative) on Torrance-Sparrow alpha 0.2; held to 15 %, the
    planner's use (choosing a representation) needs the error's size, not its third digit."""
    brdf = TorranceSparrow(0.2, fresnel="none")
    pred = predict_fit_error(brdf)
    full = fit_gaussian_lobes(brdf, FitSettings(max_lobes=5, elevations=6, max_inserted=0))
    assert full.errors is not None
    np.testing.assert_allclose(pred.theta_o, full.elevations, rtol=1e-12)
    np.testing.assert_allclose(pred.errors, full.errors, rtol=0.15)
    assert pred.sphere_error == pytest.approx(sphere_error(full.elevations, full.errors), rel=0.15)
    assert pred.as_dict()["coarse_seconds"] > 0


def test_sphere_error_weights() -> None:
    t = np.linspace(0.0, math.radians(87.0), 30)
    assert sphere_error(t, np.full(30, 0.03)) == pytest.approx(0.03, rel=1e-12)  # a constant error is itself
    # an error only at grazing views counts by the disc's area there: the closed form of the weight's integral
    e = np.where(t > math.radians(60.0), 0.1, 0.0)
    w = np.cos(t) * np.sin(t)
    assert sphere_error(t, e) == pytest.approx(0.1 * math.sqrt(np.trapezoid(w * (e > 0), t) / np.trapezoid(w, t)))


def test_chain_cost_matches_the_built_chain() -> None:
    rng = np.random.default_rng(3)
    env = np.exp(rng.normal(size=(32, 64, 3))).astype(np.float32)
    ch = build_chain(env, epsilon=1e-3)
    cost = chain_cost(32, 64, epsilon=1e-3)
    assert cost["levels"] == len(ch.levels)
    np.testing.assert_allclose(cost["sigmas"], ch.sigmas, rtol=1e-12)
    # the predicted order is the lobe's (an upper bound: the lighting may need less); rows follow the order
    for lv, f, s in zip(ch.levels, cost["orders"], cost["rows"], strict=True):
        assert lv.orders["F_B"] <= f and lv.orders["size"] <= s
    assert cost["seconds"] > 0 and cost["bytes"] >= sum(6 * lv.map.shape[0] * lv.map.shape[1] for lv in ch.levels)
    with pytest.raises(InputError, match="H x 2H"):
        chain_cost(32, 63)


def test_object_cost() -> None:
    c = object_cost(3, 15, visibility_order=3)
    assert c["material_bytes"] == 720 and c["visibility_floats_per_vertex"] == 16
    assert c["chain_lookups_per_pixel"] == 3
    with pytest.raises(InputError, match="lobes"):
        object_cost(0, 15)
