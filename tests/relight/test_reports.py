"""The typed reports' JSON is a contract (the CLI's ``--report`` file, ``plan.json``, stored job results and the
API): these tests pin its key sets, check that the typed fields hold what the JSON says, and that the API's
``Orders`` and ``PredictedError`` models take the core's reports field for field."""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

from relight import costmodel, planning
from relight.brdf.radial import Phong
from relight.prefilter import prefilter_radial, project_lighting
from relight.reports import OrderReport, Orders, PredictedError, PrefilterReport

RNG = np.random.default_rng(7)
PX = RNG.random((32, 64, 3)) + 0.1
CAL = costmodel.default_calibration()

ORDER_KEYS = {"F_L", "F_rho", "F_B", "P_B"}
ERROR_KEYS = {"epsilon_lighting", "epsilon_brdf", "epsilon_min_of_errors", "rms_min_of_errors", "epsilon_appendix_b",
              "rms_appendix_b"}
PREFILTER_KEYS = {"representation", "center", "brdf", "epsilon", "order_requested", "window", "orders", "predicted",
                  "ringing", "input", "output", "timings", "total_seconds", "backend", "relight_version"}
JOB_KEYS = {"representation", "reason", "orders", "predicted_error", "size", "components", "output",
            "predicted_seconds", "cost_model"}
PLAN_KEYS = {"format", "relight_version", "scene", "environment", "epsilon", "time_budget_s", "mode", "lighting",
             "computations", "objects", "brdf_seconds", "predicted_seconds", "predicted_stages", "predicted_error",
             "cost_model", "jobs", "lighting_mode", "frame"}
BUDGET_KEYS = {"budget_met", "budget_ladder", "budget_note"}
COMPUTATION_KEYS = {"id", "lobe", "kind", "center", "representation", "structure", "reason", "F_rho", "P_rho", "F_L",
                    "F_B", "P_B", "n_maps", "n_coefficients", "size", "epsilon_rho", "epsilon_rho_below",
                    "predicted", "shared_by", "order_search_probes"}
OBJECT_KEYS = {"name", "shape", "size", "distance", "material", "view", "view_dependent", "viewer", "shrm",
               "view_spread_deg", "p_delta", "near_below_distance", "output_rows", "computations", "predicted_error",
               "effects", "representations", "per_frame_ms", "shadows_requested", "interreflections",
               "material_edited"}  # planner v2 (issue 16): what each lobe is drawn with, and the object's inputs
VIEW_KEYS = {"by_view", "grazing_limit"}  # left out of the JSON while None (relight.reports.OMIT_NONE)
SUMMARY_KEYS = {"rms_min_of_errors", "rms_appendix_b", "epsilon_min_of_errors", "epsilon_appendix_b"}


def test_prefilter_report_keys_and_typed_fields() -> None:
    res = prefilter_radial(PX, Phong(32.0), epsilon=0.01, size=16)
    rep = res.report
    assert isinstance(rep, PrefilterReport)
    d = rep.to_json()
    json.dumps(d, allow_nan=False)
    assert set(d) == PREFILTER_KEYS
    assert set(d["orders"]) == ORDER_KEYS | ERROR_KEYS and set(d["predicted"]) == ERROR_KEYS | {"by_view"}
    assert [b["ndotv"] for b in d["predicted"]["by_view"]] == [[0.0, 0.3], [0.3, 0.7], [0.7, 1.0]]
    assert set(d["ringing"]) == {"kernel_min", "lower_bound_rgb", "min_output_rgb"}
    assert set(d["output"]) == {"height", "width", "layout", "cube_size"} and set(d["input"]) == {"height", "width"}
    assert d["orders"]["F_B"] == rep.orders.F_B and d["output"]["height"] == rep.output.height == 16
    # rms = sqrt(epsilon) for an orthogonal truncation (relight.orders.rms_from_energy)
    assert rep.orders.epsilon_min_of_errors is not None
    assert rep.orders.rms_min_of_errors == pytest.approx(math.sqrt(rep.orders.epsilon_min_of_errors))
    assert dataclasses.replace(rep.predicted, by_view=None) == rep.orders.predicted() and rep.orders.orders() == Orders(
        F_L=rep.orders.F_L, F_rho=rep.orders.F_rho, F_B=rep.orders.F_B, P_B=0)


def test_order_report_is_orders_then_errors() -> None:
    names = [f.name for f in dataclasses.fields(OrderReport)]
    assert names[:4] == ["F_L", "F_rho", "F_B", "P_B"] and set(names[4:]) == ERROR_KEYS | VIEW_KEYS


def _info() -> dict[str, Any]:
    lig = project_lighting(PX, 31)
    return {"height": 32, "width": 64, "sh_power_spectrum": lig.band_energy().tolist(),
            "total_energy": lig.total_energy}


@pytest.mark.parametrize(("spec", "params", "extra"), [
    ({"kind": "phong", "s": 32.0}, {"epsilon": 0.01}, set()),
    ({"kind": "phong", "s": 32.0}, {"order": 12}, set()),
    ({"kind": "microfacet", "sigma": 0.3}, {"epsilon": 0.05}, {"component_plans"}),
])
def test_job_plan_keys(spec: dict[str, Any], params: dict[str, Any], extra: set[str]) -> None:
    p = planning.plan_job(_info(), spec, {"epsilon": None, "order": None, "p_order": None, "size": None, **params},
                          calibration=CAL)
    d = p.to_json()
    json.dumps(d, allow_nan=False)
    assert set(d) == JOB_KEYS | extra
    assert set(d["orders"]) == ORDER_KEYS and set(d["predicted_error"]) - VIEW_KEYS == ERROR_KEYS
    assert [b["ndotv"] for b in d["predicted_error"]["by_view"]] == [[0.0, 0.3], [0.3, 0.7], [0.7, 1.0]]
    assert all({"rms", "rms_appendix_b"} <= set(b) for b in d["predicted_error"]["by_view"])
    assert set(d["output"]) == {"height", "width", "layers", "bin_bytes", "exr_bytes_estimate"}
    assert set(d["cost_model"]) == {"calibrated", "key", "created", "compute_seconds", "io_seconds", "stages"}
    # the seconds are the cost model's computation plus the I/O terms, nothing else
    assert p.predicted_seconds == pytest.approx(p.cost_model.compute_seconds + p.cost_model.io_seconds)
    assert p.cost_model.compute_seconds == pytest.approx(sum(p.cost_model.stages.values()))


def test_api_models_take_the_core_reports_field_for_field() -> None:
    from relight.contract.models import Orders as ApiOrders
    from relight.contract.models import PredictedError as ApiPredictedError

    assert set(ApiOrders.model_fields) == {f.name for f in dataclasses.fields(Orders)}
    assert set(ApiPredictedError.model_fields) == {f.name for f in dataclasses.fields(PredictedError)}
    p = planning.plan_job(_info(), {"kind": "phong", "s": 8.0}, {"epsilon": 0.01}, calibration=CAL)
    assert ApiOrders(**p.orders.to_json()).F_B == p.orders.F_B
    assert ApiPredictedError(**p.predicted_error.to_json()).rms_appendix_b == p.predicted_error.rms_appendix_b
    wrapped = ApiPredictedError.from_core(p.predicted_error)
    assert wrapped.by_view is not None and p.predicted_error.by_view is not None
    assert [b.rms for b in wrapped.by_view] == [b.rms for b in p.predicted_error.by_view]
    with pytest.raises(TypeError):
        ApiOrders.from_core(p.predicted_error)


def test_scene_plan_keys_in_both_modes() -> None:
    objs = [{"name": "a", "size": 1, "distance": 3, "material": "phong:s=32"},
            {"name": "b", "size": 1, "distance": 30, "material": "lambert+microfacet:sigma=0.3"}]
    for mode, extra in (({"epsilon": 0.05}, set()), ({"time_budget_s": 0.5}, BUDGET_KEYS)):
        sc = planning.scene_from_dict({"environment": "x", "size": 16, "objects": objs, **mode})
        d = planning.plan_scene(sc, PX, calibration=CAL).report.to_json()
        assert json.loads(planning.plan_json(planning.plan_scene(sc, PX, calibration=CAL))).keys() == d.keys()
        assert set(d) == PLAN_KEYS | extra
        assert set(d["lighting"]) == {"F_proj", "projected_once", "input", "seconds", "shared_by", "reason"}
        assert {"budget_ms", "predicted_ms", "met", "per_object_ms", "downgrades", "note"} <= set(d["frame"])
        assert set(d["frame"]["per_object_ms"]) == {"a", "b"} and d["lighting_mode"] == "static"
        assert {c["id"] for c in d["computations"]} <= {j["params"].get("computation") for j in d["jobs"]}
        # SHRM lobes add the view-band order search's verdict (relight.shrm.order_search)
        assert all(set(c) - {"order_search"} == COMPUTATION_KEYS for c in d["computations"])
        assert all(set(o) == OBJECT_KEYS for o in d["objects"]) and set(d["predicted_error"]) == SUMMARY_KEYS
        assert all(set(e) == {"effect", "simulated", "reason"} for o in d["objects"] for e in o["effects"])
        assert set(d["cost_model"]) == {"calibrated", "key", "note"}
        if extra:
            assert all(set(s) == {"epsilon", "predicted_seconds", "fits", "predicted_rms"}
                       for s in d["budget_ladder"])


POINT_KEYS = {"method", "representation", "setting", "orders", "predicted_error", "predicted_error_bound",
              "measured_error", "predicted_seconds", "measured_seconds", "predicted_stages", "measured_stages",
              "mitsuba_error", "image_error", "pareto", "pareto_overall"}


def test_tradeoff_point_keys() -> None:
    from relight.tradeoff import sweep

    res = sweep(PX[::2, ::2], Phong(8.0), epsilons=(0.1,), truncations=(0.1,), size=8, calibration=CAL,
                mitsuba=False)
    d = res.as_dict()
    json.dumps(d, allow_nan=False)
    assert [set(p) for p in d["points"]] == [POINT_KEYS, POINT_KEYS]
    assert set(d["points"][0]["orders"]) == {"F_B", "P_B", "F_rho", "F_L", "F_proj"}
    assert set(d["points"][1]["orders"]) == {"truncation", "theta_star_deg", "W", "W_visited"}
