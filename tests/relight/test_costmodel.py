"""The cost model (seed 000 Table 3): its feature counts against what the code really does, the least-squares fit,
the cache keyed by machine and version, and the calibrated prediction against a measured run.

Counts are checked by instrumenting the code under test (ducc0 syntheses, lobe evaluations, radial quadrature
orders), an independent tally of the work; timings only in the calibration test, with a wide tolerance because
the machines are shared and noisy (docs/facts.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import ducc0
import numpy as np
import pytest

import relight
from relight import costmodel
from relight.brdf import lpq
from relight.brdf.models import KajiyaKay, Microfacet
from relight.brdf.radial import Lambert, Phong
from relight.errors import InputError

RNG = np.random.default_rng(42)


def random_env(h: int) -> np.ndarray:
    return np.asarray(RNG.random((h, 2 * h, 3)), dtype=np.float64)


# ------------------------------------------------------------------------------------------------ the fit
def test_fit_recovers_constants_exactly_and_under_noise() -> None:
    truth = {"a": 2e-9, "b": 5e-6, "c": 0.0}
    rows = []
    for n in [10, 50, 200, 1000, 5000]:
        for k in [1, 3, 7]:
            f = {"a": float(n * n * k), "b": float(k), "c": float(n)}
            rows.append((f, sum(truth[x] * f[x] for x in truth)))
    got = costmodel.fit(rows, ["a", "b", "c"])
    for name, value in truth.items():
        assert got[name] == pytest.approx(value, rel=1e-9, abs=1e-20)
    # 5 % multiplicative noise: relative least squares keeps every constant within 15 % (deterministic seed)
    noisy = [(f, t * (1.0 + 0.05 * RNG.standard_normal())) for f, t in rows]
    got = costmodel.fit(noisy, ["a", "b", "c"])
    assert got["a"] == pytest.approx(truth["a"], rel=0.15)
    assert got["b"] == pytest.approx(truth["b"], rel=0.15)
    assert got["c"] >= 0.0  # non-negative least squares
    assert costmodel.fit([], ["a"]) == {"a": 0.0}


def test_predict_sums_stages_and_rejects_unknown_features() -> None:
    cal = costmodel.default_calibration()
    feats = {"proj_call": 3.0, "proj_px": 1e6, "syn_call": 3.0, "call": 1.0}
    pred = cal.predict(feats)
    assert set(pred.stages) == {"lighting_projection", "synthesis", "other"}
    assert pred.seconds == pytest.approx(sum(cal.constants[k] * v for k, v in feats.items()))
    with pytest.raises(ValueError, match="unknown cost-model features"):
        cal.predict({"warp_drive": 1.0})


# ------------------------------------------------------------------------------------------------ feature counts
def _count_syntheses(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    spins: list[int] = []
    real = ducc0.sht.synthesis_2d

    def counting(**kw: Any) -> Any:
        spins.append(int(kw["spin"]))
        return real(**kw)

    monkeypatch.setattr(ducc0.sht, "synthesis_2d", counting)
    return spins


@pytest.mark.parametrize(("brdf", "order", "p_order"), [
    (Microfacet(0.4), 6, 3), (KajiyaKay(8.0), 6, 4), (Phong(16.0), 8, None), (Microfacet(0.4), 2, 4),
])
def test_synthesis_counts_match_the_ducc0_calls(monkeypatch: pytest.MonkeyPatch, brdf: Any, order: int,
                                                p_order: int | None) -> None:
    """Table 3's (P + 1)^2 maps per SHRM, P + 1 without azimuthal dependence, 1 for a radial lobe, as the number
    of spin-0 and spin-weighted ducc0 syntheses create_shrm really makes (3 colours)."""
    from relight.shrm import create_shrm

    spins = _count_syntheses(monkeypatch)
    sm = create_shrm(random_env(16), brdf, order=order, p_order=p_order, size=8)
    comp = sm.components[0]
    n0, nq = costmodel.synthesis_counts(comp.structure, comp.P, comp.F)
    assert (spins.count(0), len(spins) - spins.count(0)) == (n0, nq)
    assert costmodel.n_maps(comp.structure, comp.P) == len(comp.terms)


def test_tabulation_points_match_lpq_grid() -> None:
    lobe = Microfacet(0.3)
    for f, p in [(8, 2), (20, 5)]:
        pts, q = costmodel.tabulation_points(f, p, radial=False, azimuthal=False)
        assert pts == math.prod(lpq.brdf_coefficients(lobe, f, p).grid_shape)
        assert q == p + 1


def test_radial_probes_match_the_order_search(monkeypatch: pytest.MonkeyPatch) -> None:
    """The orders spectrum_for_tolerance evaluates a radial lobe at, as counted by instrumenting radial_transfer."""
    from relight.brdf import coefficients

    seen: list[int] = []
    real = coefficients.radial_transfer

    def counting(lobe: Any, lmax: int) -> Any:
        seen.append(lmax)
        return real(lobe, lmax)

    monkeypatch.setattr(coefficients, "radial_transfer", counting)
    for lobe, eps in [(Phong(64.0), 1e-3), (Phong(2000.0), 1e-2), (Lambert(), 1e-3)]:
        seen.clear()
        _, f_rho = coefficients.spectrum_for_tolerance(lobe, eps)
        assert seen == costmodel.radial_probes(lobe, f_rho, explicit=False), lobe.spec()


def test_angular_pairs_count_what_reference_radial_visits() -> None:
    """Every visited (output, input) pair evaluates the lobe once, in (outputs x inputs) blocks: count them (the 1-D
    calls are truncation_angle's search for theta*)."""
    from relight.reference import reference_radial, truncation_angle

    class Counting(Phong):
        n = 0

        def u(self, t: np.ndarray) -> np.ndarray:
            if np.ndim(t) == 2:
                Counting.n += t.size
            return super().u(t)

    for s_exp, trunc in [(8.0, 0.01), (300.0, 1e-3)]:
        lobe = Counting(s_exp)
        Counting.n = 0
        reference_radial(random_env(16), lobe, 8, epsilon=trunc)
        assert Counting.n == costmodel.angular_pairs(16, 8, truncation_angle(lobe, trunc))


def test_angular_view_counts_match_lobe_evaluations(monkeypatch: pytest.MonkeyPatch) -> None:
    """reference_view's lobe evaluations (counted by wrapping f) against the model's per-block estimate."""
    from relight.reference_view import reference_view

    lobe = Microfacet(0.3)
    seen = [0]
    real = Microfacet.f

    def counting(self: Microfacet, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        seen[0] += math.prod(np.broadcast_shapes(wi.shape, wo.shape, n.shape)[:-1])
        return real(self, wi, wo, n)

    monkeypatch.setattr(Microfacet, "f", counting)
    view = np.array([0.0, 0.5, 0.8660254])
    for trunc in (0.3, 1e-3):
        seen[0] = 0
        reference_view(random_env(24), lobe, view, 12, truncation=trunc)
        pairs, evals, w = costmodel.angular_view_counts(lobe, view, 24, 12, trunc)
        # the estimate replaces each block's test of every pair by the cones' expected pixel counts: 2 % agreement
        assert evals[0] == pytest.approx(seen[0], rel=0.02), (trunc, evals, seen)
        assert seen[0] <= pairs and 0.0 < w < 0.5


def test_view_and_shrm_features_scale_like_table3() -> None:
    """F_B P_B^2 S_B^2: doubling S_B with S ~ 10 F quadruples the per-map pixel work; (P+1)^2 maps."""
    small = costmodel.synthesis_features(32, 3, *costmodel.synthesis_counts("general", 2, 3))
    big = costmodel.synthesis_features(64, 3, *costmodel.synthesis_counts("general", 2, 3))
    assert big["syn_leg"] == pytest.approx(2 * small["syn_leg"])  # S (F+1)^2: linear in S at fixed F
    assert big["syn_px"] / small["syn_px"] == pytest.approx(4 * math.log2(128) / math.log2(64))
    assert costmodel.n_maps("general", 3) == 16 and costmodel.n_maps("azimuthal", 3) == 4
    v = costmodel.view_features([("general", 2, "R"), ("radial", 0, "N")], 16)
    assert v["view_px"] == 9 * 512 and v["lookup_px"] == 512 and v["eq8_px"] == (1 + 9 + 25) * 512


# ------------------------------------------------------------------------------------------------ calibration
def test_cache_round_trip_keyed_by_machine_and_version(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    costmodel.forget()
    calls = [0]

    def fake_calibrate(**_: Any) -> costmodel.Calibration:
        calls[0] += 1
        cal = costmodel.default_calibration()
        cal.calibrated, cal.created = True, f"run {calls[0]}"
        cal.constants["call"] = 1e-3 * calls[0]
        return cal

    monkeypatch.setattr(costmodel.calibration, "calibrate", fake_calibrate)
    a = costmodel.load_calibration(tmp_path)
    path = costmodel.cache_path(tmp_path)
    assert calls[0] == 1 and path.is_file() and a.calibrated
    costmodel.forget()
    b = costmodel.load_calibration(tmp_path)  # from the file, not calibrated again
    assert calls[0] == 1 and b.constants == a.constants and b.created == "run 1"
    # another relight version: another file, a new calibration
    monkeypatch.setattr(relight, "__version__", "999.0")
    costmodel.forget()
    c = costmodel.load_calibration(tmp_path)
    assert calls[0] == 2 and c.created == "run 2" and costmodel.cache_path(tmp_path) != path
    # another machine: another key
    assert costmodel.calibration_key({"cpu": "x"}) != costmodel.calibration_key({"cpu": "y"})
    # a corrupt file is replaced; run=False without a file gives the uncalibrated defaults
    costmodel.forget()
    costmodel.cache_path(tmp_path).write_text("{not json")
    d = costmodel.load_calibration(tmp_path)
    assert calls[0] == 3 and json.loads(costmodel.cache_path(tmp_path).read_text())["created"] == "run 3"
    costmodel.forget()
    assert not costmodel.load_calibration(tmp_path / "empty", run=False).calibrated
    assert d.calibrated
    costmodel.forget()


def test_from_dict_rejects_incomplete_or_negative_constants() -> None:
    good = costmodel.default_calibration().as_dict()
    assert costmodel.Calibration.from_dict(good).constants == good["constants"]
    for bad in ({**good, "constants": {"call": 1.0}}, {**good, "constants": {**good["constants"], "call": -1.0}},
                {k: v for k, v in good.items() if k != "key"}):
        with pytest.raises(InputError):
            costmodel.Calibration.from_dict(bad)


def test_quick_calibration_fits_positive_constants_and_predicts_monotone_costs() -> None:
    """A real (quick) calibration run: every fitted constant is finite and non-negative, and predictions grow with the
    work (higher order, larger output). Tests never assert wall-clock times: how well predicted seconds match
    measured ones is reported by ``bench/tradeoff_plots.py`` and ``relight costmodel``, not asserted here."""
    from relight.prefilter import prefilter_radial

    cal = costmodel.calibrate(quick=True, repeat=1)
    # non-negative least squares: a term the runs cannot separate may fit to 0, never below
    assert cal.constants and all(np.isfinite(v) and v >= 0 for v in cal.constants.values()), cal.constants
    # every stage the runs time costs something; which of its terms carries it may vary with one noisy repeat (the
    # fit can trade proj_px against proj_leg when the machine is loaded), so no single constant is required > 0
    for stage in ("lighting_projection", "synthesis", "brdf_coefficients", "angular", "angular_view"):
        assert any(cal.constants[f] > 0 for f in costmodel.STAGES[stage]), (stage, cal.constants)

    env = random_env(96)
    lobe = Phong(100.0)
    preds = []
    for order, size in [(8, 24), (24, 24), (24, 48)]:
        res = prefilter_radial(env, lobe, order=order, size=size)
        feats = costmodel.prefilter_report_features(lobe, res.report, height=96, width=192)
        preds.append(cal.predict(feats).seconds)
    assert all(np.isfinite(p) and p > 0 for p in preds)
    assert preds[0] < preds[1] < preds[2], preds


def test_angular_view_counts_walk_the_blocks_reference_view_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """One block plan: the pairs reference_view visits (recorded block by block as it runs) equal the pairs the cost
    model counts, also with blocks small enough to split every group's rows (exact: both walk block_plan)."""
    from relight import reference_view as rv

    visited: list[int] = []
    real_blocks = rv.ViewGroup.blocks

    def recording(self: rv.ViewGroup) -> Any:
        for sl in real_blocks(self):
            visited.append(self.outputs.size * (sl.stop - sl.start))
            yield sl

    monkeypatch.setattr(rv.ViewGroup, "blocks", recording)
    view = np.array([0.2, 0.5, 0.8])
    h = 16
    for brdf, chunk in [(Microfacet(0.3), 2_000), (Microfacet(0.1), 500_000)]:
        visited.clear()
        rv.reference_view(random_env(h), brdf, view, 8, truncation=0.01, chunk_elems=chunk)
        walked = sum(visited) * 2 * h
        visited.clear()
        pairs, _, _ = costmodel.angular_view_counts(brdf, view, h, 8, 0.01, chunk_elems=chunk)
        assert walked > 0 and pairs == walked
    assert rv.DENSE_FRACTION == 0.3 and rv.is_dense(31.0, 100) and not rv.is_dense(30.0, 100)
