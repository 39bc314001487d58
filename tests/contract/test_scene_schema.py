"""The API's scene model (``relight.contract.models.SceneCreate``) and the core's scene parser
(``relight.planning.scene.scene_from_dict``) are one schema: at every limit they share, both accept or both refuse."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from pydantic import ValidationError

from relight.contract.models import SceneCreate
from relight.errors import InputError
from relight.planning import scene as planner

ENV = "0" * 64  # a digest: the API takes an envmap id, the core any non-empty string


def _scene(n_objects: int = 1, **changes: Any) -> dict[str, Any]:
    objects = [{"name": f"o{k}", "size": 1.0, "distance": 3.0, "material": "lambert"} for k in range(n_objects)]
    return {"name": "s", "environment": ENV, "objects": objects, "epsilon": 0.05, **changes}


def _api_ok(scene: dict[str, Any]) -> bool:
    try:
        SceneCreate.model_validate(scene)
    except ValidationError:
        return False
    return True


def _core_ok(scene: dict[str, Any]) -> bool:
    try:
        planner.scene_from_dict(copy.deepcopy(scene))
    except InputError:
        return False
    return True


def _object(**changes: Any) -> dict[str, Any]:
    scene = _scene()
    scene["objects"][0].update(changes)
    return scene


CASES = {
    # object count (the core allowed 64 and the API 16 before both took MAX_SCENE_OBJECTS)
    "max objects": (_scene(planner.MAX_SCENE_OBJECTS), True),
    "one object too many": (_scene(planner.MAX_SCENE_OBJECTS + 1), False),
    "no objects": (_scene(0), False),
    # output size (the core allowed 2048 and the API 512)
    "smallest size": (_scene(size=planner.MIN_SCENE_SIZE), True),
    "below smallest size": (_scene(size=planner.MIN_SCENE_SIZE - 1), False),
    "largest size": (_scene(size=planner.MAX_SCENE_SIZE), True),
    "above largest size": (_scene(size=planner.MAX_SCENE_SIZE + 1), False),
    # time budget
    "longest budget": ({**_scene(time_budget_s=planner.MAX_TIME_BUDGET_S), "epsilon": None}, True),
    "budget too long": ({**_scene(time_budget_s=planner.MAX_TIME_BUDGET_S * 1.001), "epsilon": None}, False),
    # names: the core's NAME_PATTERN
    "64-character name": (_scene(name="n" * 64), True),
    "65-character name": (_scene(name="n" * 65), False),
    "name starting with a dot": (_scene(name=".hidden"), False),
    "object name with a slash": (_object(name="a/b"), False),
    # shapes: the core's SHAPES
    **{f"shape {s}": (_object(shape=s), True) for s in planner.SHAPES},
    "unknown shape": (_object(shape="cube"), False),
    # tolerance or budget: exactly one
    "both epsilon and budget": (_scene(time_budget_s=1.0), False),
    "neither epsilon nor budget": ({k: v for k, v in _scene().items() if k != "epsilon"}, False),
    "epsilon 1": (_scene(epsilon=1.0), False),
    # unknown keys
    "unknown scene key": (_scene(colour="red"), False),
    "unknown object key": (_object(colour="red"), False),
    # sizes and distances
    "zero object size": (_object(size=0.0), False),
    "largest object": (_object(size=planner.MAX_OBJECT_SIZE, distance=2 * planner.MAX_OBJECT_SIZE), True),
    "object too large": (_object(size=planner.MAX_OBJECT_SIZE * 1.001, distance=4 * planner.MAX_OBJECT_SIZE), False),
    "farthest object": (_object(distance=planner.MAX_OBJECT_DISTANCE), True),
    "object too far": (_object(distance=planner.MAX_OBJECT_DISTANCE * 1.001), False),
    # planner v2's inputs (issue 16 item 4)
    **{f"shadows {m}": (_object(shadows=m), True) for m in planner.SHADOW_MODES},
    "unknown shadows": (_object(shadows="soft"), False),
    **{f"lighting {m}": (_scene(lighting=m), True) for m in planner.LIGHTING_MODES},
    "unknown lighting": (_scene(lighting="strobe"), False),
    "interreflections": (_object(interreflections=True), True),
    "interreflections not a bool": (_object(interreflections="yes"), False),
    "largest frame budget": (_scene(frame_budget_ms=planner.MAX_FRAME_BUDGET_MS), True),
    "frame budget too large": (_scene(frame_budget_ms=planner.MAX_FRAME_BUDGET_MS * 1.001), False),
    "zero frame budget": (_scene(frame_budget_ms=0.0), False),
    "edits of all materials": (_scene(material_edits=True), True),
    "edits by name": (_scene(material_edits=["o0"]), True),
    "edits of an unknown object": (_scene(material_edits=["nobody"]), False),
    "mesh and shape": (_object(mesh="0" * 64, shape="bunny"), False),
    "tangent project": (_object(tangent={"kind": "project", "direction": [1, 0, 0]}), True),
    "tangent project without direction": (_object(tangent={"kind": "project"}), False),
    "tangent of the mesh on the sphere": (_object(tangent={"kind": "mesh"}), False),
    "tangent of the mesh on a sample mesh": (_object(shape="teapot", tangent={"kind": "mesh"}), True),
    "unknown tangent": (_object(tangent={"kind": "combed"}), False),
    "anisotropic material": (_object(material="ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0"), True),
}


@pytest.mark.parametrize("name", list(CASES))
def test_api_and_core_agree(name: str) -> None:
    scene, valid = CASES[name]
    assert _core_ok(scene) is valid, f"core: {name}"
    assert _api_ok(scene) is valid, f"API: {name}"


def test_schema_publishes_the_core_limits() -> None:
    """The OpenAPI schema (what the viewer and SDK users read) names the core's limits and shapes."""
    schema = SceneCreate.model_json_schema()
    assert schema["properties"]["objects"]["maxItems"] == planner.MAX_SCENE_OBJECTS
    size = next(s for s in schema["properties"]["size"]["anyOf"] if s.get("type") == "integer")
    assert (size["minimum"], size["maximum"]) == (planner.MIN_SCENE_SIZE, planner.MAX_SCENE_SIZE)
    shape = schema["$defs"]["SceneObjectCreate"]["properties"]["shape"]
    assert next(s for s in shape["anyOf"] if "enum" in s)["enum"] == list(planner.SHAPES)
    obj = schema["$defs"]["SceneObjectCreate"]["properties"]
    assert obj["shadows"]["enum"] == list(planner.SHADOW_MODES)
    assert schema["properties"]["lighting"]["enum"] == list(planner.LIGHTING_MODES)
