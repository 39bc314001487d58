"""``/tradeoffs`` (accuracy against time as a job) and ``/plan``'s calibrated cost model, against the live server."""

from __future__ import annotations

import time
from typing import Any

import httpx
import pytest

from relight.client.sdk import RelightClient
from relight.contract.models import TradeoffPublic

from ..support import assert_healthy, assert_problem, wait_done

pytestmark = pytest.mark.timeout(240)
UNKNOWN = "f" * 64
REQUIRED = {"method", "orders", "predicted_error", "measured_error", "predicted_seconds", "measured_seconds",
            "pareto", "pareto_overall"}


def test_tradeoff_job_returns_points_and_is_shared(client: RelightClient, http: httpx.Client,
                                                   sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    body = {"envmap": env.id, "brdf": "phong:s=16", "rows": 16, "size": 8, "epsilons": [0.1, 0.01],
            "truncations": [0.1]}
    r = http.post("/tradeoffs", json=body)
    assert r.status_code == 202, r.text
    first = TradeoffPublic.model_validate(r.json())
    assert r.headers["location"] == f"/tradeoffs/{first.id}" and first.points is None
    done = wait_done(http, f"/tradeoffs/{first.id}")
    assert done["state"] == "succeeded", done
    points = done["points"]
    assert [p["method"] for p in points] == ["frequency", "frequency", "angular"]
    assert all(REQUIRED <= set(p) for p in points)
    assert done["meta"]["input"]["height"] == 16 and done["meta"]["output"]["height"] == 8
    # the same request written differently (order of epsilons, the BRDF as an object) is the same sweep: 200, done
    again = http.post("/tradeoffs", json={**body, "epsilons": [0.01, 0.1], "brdf": {"kind": "phong", "s": 16}})
    assert again.status_code == 200 and again.json()["id"] == first.id and again.json()["points"] == points
    assert_healthy(http)


def test_tradeoff_measures_against_mitsuba_when_the_material_has_a_twin(client: RelightClient, http: httpx.Client,
                                                                         sample_exr: bytes) -> None:
    """A material with a Mitsuba 3 twin (Lambert) gets each point's error against a Mitsuba render, with the
    render's noise floor and the reference's own agreement (``relight.tradeoff``: the reference must agree with
    Mitsuba to a few noise floors, else the comparison is wrong); one without (Phong) says why not."""
    env = client.upload_envmap(sample_exr)
    body = {"envmap": env.id, "brdf": "lambert:albedo=0.8", "rows": 16, "size": 16, "epsilons": [0.3, 0.01],
            "truncations": [0.1]}
    done = wait_done(http, f"/tradeoffs/{http.post('/tradeoffs', json=body).json()['id']}")
    assert done["state"] == "succeeded", done
    ms = done["meta"]["mitsuba"]
    assert ms["computed"] is True, ms
    assert 0 < ms["noise"] < 0.02 and ms["reference_error"] < 3 * ms["noise"] + 5e-3, ms
    errors = [p["mitsuba_error"] for p in done["points"]]
    assert all(isinstance(e, float) and e >= 0 for e in errors), errors
    phong = wait_done(http, f"/tradeoffs/{http.post('/tradeoffs', json={**body, 'brdf': 'phong:s=16'}).json()['id']}")
    assert phong["meta"]["mitsuba"]["computed"] is False and "twin" in phong["meta"]["mitsuba"]["reason"]
    assert all(p["mitsuba_error"] is None for p in phong["points"])


@pytest.mark.parametrize(("patch", "status", "fragment"), [
    ({"epsilons": [1.5]}, 422, "epsilons"),
    ({"truncations": [0.0]}, 422, "truncations"),
    ({"rows": 100000}, 422, "rows"),
    ({"view": [0, 0, 0]}, 422, "non-zero"),
    ({"view": [1, 2]}, 422, "view"),
    ({"brdf": "nonsense:x=1"}, 422, "nonsense"),
    ({"colour": "red"}, 422, "colour"),
    ({"envmap": UNKNOWN}, 404, UNKNOWN),
])
def test_invalid_tradeoff_requests(client: RelightClient, http: httpx.Client, sample_exr: bytes,
                                   patch: dict[str, Any], status: int, fragment: str) -> None:
    env = client.upload_envmap(sample_exr)
    assert_problem(http.post("/tradeoffs", json={"envmap": env.id, "brdf": "phong:s=8", **patch}), status, fragment)


def test_unknown_tradeoff_is_404(http: httpx.Client) -> None:
    assert_problem(http.get(f"/tradeoffs/{UNKNOWN}"), 404, UNKNOWN)


def test_plan_uses_the_calibrated_cost_model(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    """/plan answers at once (the built-in constants while no calibration exists) and starts one calibration in a
    worker; later answers use it. Either way the prediction is the cost model's compute time plus the I/O terms."""
    env = client.upload_envmap(sample_exr)
    body = {"envmap": env.id, "brdf": "phong:s=32", "epsilon": 0.01}
    deadline = time.monotonic() + 150.0
    while True:
        r = http.post("/plan", json=body)
        assert r.status_code == 200, r.text
        cm = r.json()["cost_model"]
        assert r.json()["predicted_seconds"] == pytest.approx(cm["compute_seconds"] + cm["io_seconds"])
        assert set(cm["stages"]) >= {"lighting_projection", "synthesis", "brdf_coefficients"}
        if cm["calibrated"]:
            break
        assert time.monotonic() < deadline, "the cost model was never calibrated"
        time.sleep(1.0)
    general = http.post("/plan", json={**body, "brdf": "microfacet:sigma=0.4", "epsilon": 0.05}).json()
    assert general["cost_model"]["calibrated"] and general["cost_model"]["stages"]["synthesis"] > 0
