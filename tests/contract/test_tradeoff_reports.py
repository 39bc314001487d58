"""The API's sweep answer wraps the core's typed reports: ``TradeoffPublic.points`` are
``relight.tradeoff.TradeoffPoint`` and ``TradeoffPublic.meta`` is ``relight.tradeoff.TradeoffMeta`` (one definition
each). A real sweep goes through the JSON the service stores and comes back as the same core objects; the stored
JSON keeps the keys it had as a dict, and a result stored before the Mitsuba 3 comparison (result version 1) still
validates, saying why nothing was measured."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import numpy as np

from relight import costmodel, tradeoff
from relight.brdf.radial import Phong
from relight.contract.models import TradeoffPublic
from relight.tradeoff.report import NOT_RECORDED, MitsubaComparison, TradeoffMeta, TradeoffPoint

#: The keys of the stored ``meta`` when it was a dict (result version 2): the stored format is a contract.
META_KEYS = {"relight_version", "brdf", "representation", "input", "output", "view", "metric", "reference",
             "calibration", "time_ratio_range", "mitsuba"}


def public(result: dict[str, object]) -> TradeoffPublic:
    return TradeoffPublic(id="0" * 64, state="succeeded", envmap="1" * 64, brdf="2" * 64, brdf_spec={}, params={},
                          points=result["points"], meta=result["meta"], created_at=datetime.now(UTC))


def test_the_api_models_are_the_core_reports() -> None:
    fields = TradeoffPublic.model_fields
    assert fields["points"].annotation == list[TradeoffPoint] | None
    assert fields["meta"].annotation == TradeoffMeta | None


def test_a_sweep_round_trips_through_the_stored_json() -> None:
    px = 0.5 + np.random.default_rng(5).random((16, 32, 3))
    res = tradeoff.sweep(px, Phong(8.0), epsilons=(0.1,), truncations=(0.1,), size=8,
                         calibration=costmodel.default_calibration(), mitsuba=False)
    stored = json.loads(json.dumps(res.as_dict()))  # what the worker stores
    assert set(stored["meta"]) == META_KEYS
    assert stored["meta"]["mitsuba"] == {"computed": False, "reason": res.meta.mitsuba.reason}
    assert stored["meta"]["input"] == {"height": 16, "width": 32}  # unset optional keys are left out
    pub = public(stored)
    assert pub.meta == res.meta and pub.points == res.points
    # and back out as JSON: what the API sends parses into the same reports again
    again = TradeoffPublic.model_validate_json(pub.model_dump_json())
    assert again.meta == res.meta and again.points == res.points


def test_a_result_stored_before_the_mitsuba_comparison_still_validates() -> None:
    px = 0.5 + np.random.default_rng(6).random((16, 32, 3))
    res = tradeoff.sweep(px, Phong(8.0), epsilons=(0.1,), truncations=(), size=8,
                         calibration=costmodel.default_calibration(), mitsuba=False)
    old = json.loads(json.dumps(res.as_dict()))
    del old["meta"]["mitsuba"]
    for p in old["points"]:
        del p["mitsuba_error"], p["image_error"]
    pub = public(old)
    assert pub.meta is not None and pub.meta.mitsuba == MitsubaComparison(computed=False, reason=NOT_RECORDED)
    assert pub.points is not None and pub.points[0].mitsuba_error is None
