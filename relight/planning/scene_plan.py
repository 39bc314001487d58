"""Planning a scene: simulate only what it calls for (seed 000 §3.1, §4 eqs. 6–8, §5.1, §5.2, §7, App. C).

:func:`plan_scene` decides per lobe of every material its representation and orders (``relight.planning.lobes``)
and per object its viewer and effects (``relight.planning.effects``):

* a **sum of lobes**: each lobe at its own orders (F_rho, P_rho) from the tolerance, ``F_B = min(F_rho, F_L, H - 1)``
  (minimum-of-orders rule, §5.1);
* the lighting is projected **once**, to the largest order any lobe needs, and shared (App. C: ``O(F_B S_L^2)``);
  identical lobes at identical orders and resolution are computed once and shared between objects;
* under a **time budget** (:func:`plan_for_budget`): the most accurate plan on a ladder of tolerances whose
  predicted seconds (``relight.costmodel``) fit, with its predicted error.

The plan is a typed report (:class:`relight.planning.report.ScenePlan`); :func:`plan_json` is its JSON.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, costmodel
from relight.jsonable import jsonable
from relight.planning.effects import effects, viewer_of
from relight.planning.lobes import LobeChoice, choose, lobe_key, predicted_radial, predicted_shrm
from relight.planning.report import (
    BudgetStep,
    Computation,
    CostModelInfo,
    ErrorSummary,
    LightingPlan,
    ObjectPlan,
    ScenePlan,
)
from relight.planning.scene import Scene
from relight.planning.shadows import shadow_plan

FloatArray = NDArray[np.float64]

#: Tolerances tried under a time budget, loosest first. General (SHRM) lobes stop at 1e-3: below it the order
#: search of a microfacet lobe tabulates for minutes (App. C), more than any budget worth planning for.
BUDGET_LADDER: tuple[float, ...] = (0.3, 0.1, 0.05, 0.03, 0.01, 5e-3, 3e-3, 1e-3, 5e-4, 3e-4, 1e-4, 3e-5, 1e-5)
SHRM_MIN_EPSILON = 1e-3


@dataclass
class Plan:
    """A planned scene: its report (the JSON the CLI prints and the service stores) and what :func:`run_plan`
    needs to execute it without projecting the lighting again."""

    scene: Scene
    report: ScenePlan
    lighting: Any = None  # relight.prefilter.LightingSpectrum, shared with run_plan
    choices: dict[str, LobeChoice] = field(default_factory=dict)
    keys: dict[str, str] = field(default_factory=dict)  # computation id -> lobe key of ``choices``


def _pixels(pixels: NDArray[np.floating]) -> FloatArray:
    """The environment map as float64 (H, W, 3), validated by ``require_rgb_latlong``."""
    from relight.conventions import require_rgb_latlong

    return np.asarray(require_rgb_latlong(pixels), dtype=np.float64)


def _features(choices: dict[str, LobeChoice], computations: dict[tuple[str, int], Computation],
              objects: list[ObjectPlan], h: int, w: int, f_proj: int) -> dict[str, float]:
    """Cost-model features of the whole plan: order searches, projection, every map, one eq. 12 view per object."""
    comp_list = list(computations.values())
    brdf_parts = []
    for key, c in choices.items():
        if c.structure == "radial":  # the order search, then the coefficients at every F_B used (compute_component)
            f_bs = {cc.F_B for (k, _), cc in computations.items() if k == key}
            probes = [(f, 0) for f in costmodel.radial_probes(c.lobe, c.f_rho, explicit=False)] + [
                (f, 0) for f in sorted(f_bs)]
            brdf_parts.append(costmodel.brdf_features(c.lobe, c.f_rho, 0, explicit=False, probes=probes))
        else:
            brdf_parts.append(costmodel.brdf_features(c.lobe, c.f_rho, c.p_rho, explicit=False, search="lpq",
                                                      probes=c.probes))
    return costmodel.add_features(
        costmodel.projection_features(h, w, f_proj), {"call": 1.0, "conv": float((f_proj + 1) ** 2)},
        *brdf_parts,
        *(costmodel.synthesis_features(c.size, c.F_B, *costmodel.synthesis_counts(c.structure, c.P_B, c.F_B))
          for c in comp_list),
        *(costmodel.view_features([(c.structure, c.P_B, c.center) for c in comp_list if c.id in o.computations],
                                  o.output_rows) for o in objects),
    )


def _plan_at(
    scene: Scene, pixels: FloatArray, epsilon: float, cal: costmodel.Calibration, lighting: Any = None
) -> Plan:
    """Plan every object at one tolerance (module docstring)."""
    from relight.brdf.spec import parse_brdf
    from relight.prefilter import project_lighting, size_for_order
    from relight.shrm import brdf_lobes

    h, w = pixels.shape[:2]
    f_cap = h - 1
    choices: dict[str, LobeChoice] = {}
    obj_lobes: list[list[str]] = []
    t_brdf = time.perf_counter()
    for obj in scene.objects:
        keys = []
        for lobe in brdf_lobes(parse_brdf(obj.material)):
            key = lobe_key(lobe)
            if key not in choices:
                choices[key] = choose(lobe, epsilon)
            keys.append(key)
        obj_lobes.append(keys)
    t_brdf = time.perf_counter() - t_brdf
    f_proj = min(max(c.f_rho for c in choices.values()), f_cap)
    t_proj = 0.0
    if lighting is None or lighting.lmax < f_proj:
        t0 = time.perf_counter()
        lighting = project_lighting(pixels, f_proj)
        t_proj = time.perf_counter() - t0

    lobe_info: dict[str, tuple[int, int | None, dict[str, float]]] = {}
    for key, c in choices.items():
        predict = predicted_radial if c.structure == "radial" else predicted_shrm
        f_b, f_l, errors = predict(c, lighting, epsilon, f_cap)
        lobe_info[key] = (int(f_b), f_l, errors)

    computations: dict[tuple[str, int], Computation] = {}
    objects: list[ObjectPlan] = []
    for obj, lobe_keys in zip(scene.objects, obj_lobes, strict=True):
        s = scene.size if scene.size is not None else size_for_order(max(lobe_info[k][0] for k in lobe_keys))
        comps = []
        for key in lobe_keys:
            c = choices[key]
            f_b, f_l, errors = lobe_info[key]
            ck = (key, s)
            if ck not in computations:
                n = costmodel.n_maps(c.structure, c.p_rho)
                computations[ck] = Computation(
                    id=f"c{len(computations)}", lobe=c.lobe.spec(), kind=c.lobe.kind, center=str(c.lobe.center),
                    representation=c.representation, structure=c.structure, reason=c.reason, F_rho=c.f_rho,
                    P_rho=c.p_rho, F_L=f_l, F_B=f_b, P_B=c.p_rho, n_maps=n, n_coefficients=(f_b + 1) ** 2 * n,
                    size=s, epsilon_rho=c.eps_rho, epsilon_rho_below=c.eps_rho_below, predicted=errors,
                    order_search_probes=[list(p) for p in c.probes] if c.probes else None,
                )
            computations[ck].shared_by.append(obj.name)
            comps.append(computations[ck])
        viewer = viewer_of(obj, comps, epsilon)
        shadows = shadow_plan(obj, comps, epsilon)
        worst = max(comps, key=lambda c: c.predicted.get("epsilon_min_of_errors", 0.0))
        objects.append(ObjectPlan(
            **obj.as_dict(), view_dependent=viewer.view_dependent, viewer=viewer.viewer, shrm=viewer.shrm,
            view_spread_deg=viewer.view_spread_deg, p_delta=viewer.p_delta,
            near_below_distance=viewer.near_below_distance, output_rows=s, computations=[c.id for c in comps],
            predicted_error=ErrorSummary.of(worst.predicted), effects=effects(obj, comps, viewer, epsilon, shadows),
            shadows=shadows,
        ))

    pred = cal.predict(_features(choices, computations, objects, h, w, f_proj))
    shadow_s = sum(o.shadows.predicted_seconds for o in objects if o.shadows is not None)
    if shadow_s:  # ray casting is outside the cost model's features: its own rate (relight.visibility.predict)
        pred = replace(pred, seconds=pred.seconds + shadow_s, stages={**pred.stages, "shadows": shadow_s})
    worst_obj = max(objects, key=lambda o: o.predicted_error.epsilon_min_of_errors or 0.0)
    report = ScenePlan(
        relight_version=__version__, scene=scene.name, environment=scene.environment, epsilon=epsilon,
        time_budget_s=scene.time_budget_s, mode="tolerance" if scene.time_budget_s is None else "time_budget",
        lighting=LightingPlan(F_proj=f_proj, input={"height": h, "width": w}, seconds=t_proj,
                              shared_by=[o.name for o in scene.objects]),
        computations=list(computations.values()), objects=objects, brdf_seconds=t_brdf,
        predicted_seconds=pred.seconds, predicted_stages=pred.stages, predicted_error=worst_obj.predicted_error,
        cost_model=CostModelInfo(calibrated=cal.calibrated, key=cal.key),
    )
    ids = {c.id: key for (key, _), c in computations.items()}
    return Plan(scene=scene, report=report, lighting=lighting, choices=choices, keys=ids)


def plan_scene(
    scene: Scene, pixels: NDArray[np.floating], *, calibration: costmodel.Calibration | None = None
) -> Plan:
    """Plan a scene for an environment map (H, W, 3): at its tolerance, or under its time budget."""
    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    if scene.time_budget_s is not None:
        return plan_for_budget(scene, px, scene.time_budget_s, calibration=cal)
    assert scene.epsilon is not None
    return _plan_at(scene, px, scene.epsilon, cal)


def plan_for_budget(
    scene: Scene, pixels: NDArray[np.floating], budget_s: float, *, calibration: costmodel.Calibration | None = None,
    ladder: Sequence[float] = BUDGET_LADDER,
) -> Plan:
    """The most accurate plan on ``ladder`` whose predicted seconds fit ``budget_s`` (module docstring).

    Predicted time grows as the tolerance tightens; the ladder is walked from the loosest tolerance and stops at the
    first plan over budget. If even the loosest does not fit, that plan is returned with ``budget_met = False``.
    """
    from relight.brdf.spec import parse_brdf
    from relight.shrm import brdf_lobes

    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    general = any(not lobe.radially_symmetric for o in scene.objects for lobe in brdf_lobes(parse_brdf(o.material)))
    steps = [e for e in ladder if not (general and e < SHRM_MIN_EPSILON)]
    tried: list[BudgetStep] = []
    best: Plan | None = None
    lighting = None
    for eps in steps:
        plan = _plan_at(scene, px, eps, cal, lighting)
        lighting = plan.lighting
        fits = plan.report.predicted_seconds <= budget_s
        tried.append(BudgetStep(epsilon=eps, predicted_seconds=plan.report.predicted_seconds, fits=fits,
                                predicted_rms=plan.report.predicted_error.rms_min_of_errors))
        if not fits:
            if best is None:
                best = plan
            break
        best = plan
    assert best is not None
    note = (f"tolerances below {SHRM_MIN_EPSILON:g} are not tried for general lobes: their order search alone takes "
            "minutes (App. C)") if general else None
    best.report = replace(best.report, time_budget_s=budget_s,
                          budget_met=bool(best.report.predicted_seconds <= budget_s), budget_ladder=tried,
                          budget_note=note)
    return best


def format_plan(plan: Plan) -> str:
    """The plan as text: objects, computations with orders and reasons, effects, predicted error and time."""
    d = plan.report
    lines = [f"scene {d.scene}: environment {d.environment} ({d.lighting.input['width']} x "
             f"{d.lighting.input['height']})"]
    if d.mode == "time_budget":
        lines.append(f"  time budget {d.time_budget_s:g} s -> epsilon {d.epsilon:g}"
                     + ("" if d.budget_met else "  (over budget even at the loosest tolerance)"))
    else:
        lines.append(f"  tolerance epsilon {d.epsilon:g}")
    lines.append(f"  lighting projected once to F = {d.lighting.F_proj}, shared by "
                 f"{len(d.lighting.shared_by)} object(s)")
    for c in d.computations:
        lines.append(f"  [{c.id}] {c.kind} ({c.center}): {c.representation}, F_B = {c.F_B}, P_B = {c.P_B}, "
                     f"{c.n_maps} map(s) of {c.size} x {2 * c.size}; shared by {', '.join(c.shared_by)}")
        lines.append(f"       {c.reason}")
    for o in d.objects:
        pe = o.predicted_error.rms_min_of_errors
        lines.append(f"  object {o.name} ({o.shape}, size {o.size:g} at distance {o.distance:g}): "
                     f"{o.viewer} viewer, SHRM {o.shrm}, predicted relative RMS {pe:.3g}")
        for e in o.effects:
            lines.append(f"    {'+' if e.simulated else '-'} {e.effect}: {e.reason}")
    lines.append(f"  predicted {d.predicted_seconds:.3g} s, worst predicted relative RMS "
                 f"{d.predicted_error.rms_min_of_errors:.3g}")
    return "\n".join(lines)


def plan_json(plan: Plan) -> str:
    """The plan as strict JSON (non-finite numbers as null)."""
    return json.dumps(jsonable(plan.report.to_json()), indent=1, allow_nan=False)
