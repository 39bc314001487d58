"""The API's scene answer wraps the core's typed reports: ``ScenePublic.plan`` is ``relight.planning.ScenePlan``
and ``ScenePublic.result`` is ``relight.planning.SceneResult`` (one definition each). A real plan and run of a
small scene go through the JSON the service stores and come back as the same core objects."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from relight import costmodel, planning
from relight.contract.models import ScenePublic
from relight.planning.report import ObjectFiles, ObjectResult, ScenePlan, SceneResult


def test_the_api_models_are_the_core_reports() -> None:
    fields = ScenePublic.model_fields
    assert fields["plan"].annotation == ScenePlan | None
    assert fields["result"].annotation == SceneResult | None


def test_a_run_round_trips_through_the_stored_json(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    px = (0.5 + rng.random((16, 32, 3))).astype(np.float32)
    scene = planning.scene_from_dict({"environment": "sky", "epsilon": 0.05, "size": 8, "objects": [
        {"name": "chalk", "size": 1, "distance": 5, "material": "lambert:albedo=0.7"},
        {"name": "gloss", "size": 1, "distance": 5, "material": "phong:s=8"}]})
    plan = planning.plan_scene(scene, px, calibration=costmodel.default_calibration())
    run = planning.run_plan(plan, tmp_path, preview_size=8)
    result = run.result
    assert [o.name for o in result.objects] == ["chalk", "gloss"] and run.maps == {}
    gloss = result.objects[1]
    assert isinstance(gloss, ObjectResult) and isinstance(gloss.files, ObjectFiles)
    assert gloss.files.sphere_png == "gloss.sphere.png" and (tmp_path / gloss.files.sphere_png).is_file()
    assert result.objects[0].irradiance_real_sh is not None  # Lambert: 9 coefficients per colour at F = 2
    # result.json is the report's JSON; None fields are left out of it
    stored = json.loads((tmp_path / "result.json").read_text())
    assert stored == result.to_json() and "coefficients_bin" not in stored["objects"][1]["files"]
    pub = ScenePublic(id="0" * 64, state="succeeded", scene={}, plan=plan.report.to_json(), result=stored,
                      created_at=datetime.now(UTC))
    assert pub.result == result and pub.plan == plan.report
    # and back out as JSON: what the API sends parses into the same report again
    assert ScenePublic.model_validate_json(pub.model_dump_json()).result == result


def test_a_shadowed_mesh_object_round_trips(tmp_path: Path) -> None:
    """A Lambertian teapot: the plan's ShadowPlan and the run's shadows and transfer file survive the JSON."""
    px = (0.5 + np.random.default_rng(4).random((16, 32, 3))).astype(np.float32)
    scene = planning.scene_from_dict({"environment": "sky", "epsilon": 0.3, "size": 8, "objects": [
        {"name": "pot", "shape": "teapot", "size": 1, "distance": 5, "material": "lambert:albedo=0.7"}]})
    plan = planning.plan_scene(scene, px, calibration=costmodel.default_calibration())
    assert plan.report.objects[0].shadows is not None
    run = planning.run_plan(plan, tmp_path)
    pot = run.result.objects[0]
    assert pot.files.transfer == "pot.transfer.npz" and pot.shadows is not None
    with np.load(tmp_path / pot.files.transfer) as npz:
        assert npz["transfer"].shape == (529, 16) and npz["positions"].shape == (529, 3)
    stored = json.loads((tmp_path / "result.json").read_text())
    pub = ScenePublic(id="0" * 64, state="succeeded", scene={}, plan=plan.report.to_json(), result=stored,
                      created_at=datetime.now(UTC))
    assert pub.plan == plan.report and pub.result == run.result
    assert ScenePublic.model_validate_json(pub.model_dump_json()).plan == plan.report
