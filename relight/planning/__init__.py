"""Planning: decide what to compute before computing it (seed 000 §3.1, §4 eqs. 6–8, §5.1, §5.2, §7, App. B, App. C).

* :mod:`~relight.planning.scene` — the scene schema (:class:`Scene`, its limits as named constants, shared with the
  API's ``SceneCreate``) and its strict JSON parser;
* :mod:`~relight.planning.lobes` — per lobe: representation (irradiance, reflection map, q = 0 SHRM, full SHRM) and
  orders at a tolerance, exactly as the core computes them;
* :mod:`~relight.planning.effects` — distant or near viewer (global eq. 7 or local eq. 6 SHRM) and what each object
  simulates and skips, with reasons;
* :mod:`~relight.planning.scene_plan` — :func:`plan_scene` (one tolerance, or the most accurate plan whose predicted
  seconds fit a time budget), the lighting projected once and shared;
* :mod:`~relight.planning.execute` — :func:`run_plan`;
* :mod:`~relight.planning.job` — :func:`plan_job`, one prefilter job from the stored spectrum of an uploaded map
  (``POST /plan``);
* :mod:`~relight.planning.report` — the scene plan's and the run's typed reports (:class:`ScenePlan`,
  :class:`SceneResult`).

The worker and the server call these; they hold no planning arithmetic of their own.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from relight import lazy

if TYPE_CHECKING:
    from relight.planning.effects import (
        near_threshold_distance,
        view_spread,
    )
    from relight.planning.execute import (
        SceneRun,
        compute_component,
        irradiance_coefficients,
        run_plan,
    )
    from relight.planning.job import (
        JobPlan,
        StoredLighting,
        plan_job,
        uses_reflection_map,
    )
    from relight.planning.lobes import (
        representation_of,
    )
    from relight.planning.report import (
        ObjectResult,
        ScenePlan,
        SceneResult,
    )
    from relight.planning.scene import (
        MAX_OBJECT_DISTANCE,
        MAX_OBJECT_SIZE,
        MAX_SCENE_OBJECTS,
        MAX_SCENE_SIZE,
        MAX_TIME_BUDGET_S,
        MIN_SCENE_SIZE,
        SHAPES,
        Scene,
        SceneObject,
        load_scene,
        scene_from_dict,
    )
    from relight.planning.scene_plan import (
        BUDGET_LADDER,
        SHRM_MIN_EPSILON,
        Plan,
        format_plan,
        plan_for_budget,
        plan_json,
        plan_scene,
    )

#: Public name -> defining module, imported on first use (PEP 562): importing the package stays cheap.
_EXPORTS: dict[str, str] = {
    "BUDGET_LADDER": "scene_plan",
    "JobPlan": "job",
    "MAX_OBJECT_DISTANCE": "scene",
    "MAX_OBJECT_SIZE": "scene",
    "MAX_SCENE_OBJECTS": "scene",
    "MAX_SCENE_SIZE": "scene",
    "MAX_TIME_BUDGET_S": "scene",
    "MIN_SCENE_SIZE": "scene",
    "Plan": "scene_plan",
    "SHAPES": "scene",
    "SHRM_MIN_EPSILON": "scene_plan",
    "Scene": "scene",
    "SceneObject": "scene",
    "ObjectResult": "report",
    "ScenePlan": "report",
    "SceneResult": "report",
    "SceneRun": "execute",
    "StoredLighting": "job",
    "compute_component": "execute",
    "format_plan": "scene_plan",
    "irradiance_coefficients": "execute",
    "load_scene": "scene",
    "near_threshold_distance": "effects",
    "plan_for_budget": "scene_plan",
    "plan_job": "job",
    "plan_json": "scene_plan",
    "plan_scene": "scene_plan",
    "representation_of": "lobes",
    "run_plan": "execute",
    "scene_from_dict": "scene",
    "uses_reflection_map": "job",
    "view_spread": "effects",
}

__all__ = [
    "BUDGET_LADDER",
    "JobPlan",
    "MAX_OBJECT_DISTANCE",
    "MAX_OBJECT_SIZE",
    "MAX_SCENE_OBJECTS",
    "MAX_SCENE_SIZE",
    "MAX_TIME_BUDGET_S",
    "MIN_SCENE_SIZE",
    "Plan",
    "SHAPES",
    "SHRM_MIN_EPSILON",
    "Scene",
    "SceneObject",
    "ObjectResult",
    "ScenePlan",
    "SceneResult",
    "SceneRun",
    "StoredLighting",
    "compute_component",
    "format_plan",
    "irradiance_coefficients",
    "load_scene",
    "near_threshold_distance",
    "plan_for_budget",
    "plan_job",
    "plan_json",
    "plan_scene",
    "representation_of",
    "run_plan",
    "scene_from_dict",
    "uses_reflection_map",
    "view_spread",
]


__getattr__, __dir__ = lazy.exports(__name__, _EXPORTS)
