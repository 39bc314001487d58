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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, costmodel
from relight.jsonable import jsonable
from relight.orders import order_for_tolerance
from relight.planning.assign import SEED000, Context, choose_all, iso_case, lobe_parts, needs_seed000, vertices_of
from relight.planning.effects import effects, viewer_of
from relight.planning.lobes import LobeChoice, choose, lobe_key, predicted_radial, predicted_shrm
from relight.planning.predict import PRED_ORDER
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
    meshes: dict[str, Any] = field(default_factory=dict)  # mesh reference -> relight.mesh.TriangleMesh
    pixels: Any = None  # the environment (H, W, 3) float64, for the planner-v2 jobs the run executes


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


def material_parts(material: Any) -> tuple[list[Any], list[Any]]:
    """The isotropic lobes of a material (``relight.shrm.brdf_lobes``) and its anisotropic terms (tangent-frame
    BRDFs, ``relight.brdf.frame.FrameBRDF``)."""
    from relight.brdf.frame import FrameSum, LobeAdapter
    from relight.brdf.spec import parse_brdf, parse_frame_brdf
    from relight.errors import InputError
    from relight.shrm import brdf_lobes

    try:
        return brdf_lobes(parse_brdf(material)), []
    except InputError:
        f = parse_frame_brdf(material)
    terms = f.terms if isinstance(f, FrameSum) else [f]
    return [t.lobe for t in terms if isinstance(t, LobeAdapter)], [t for t in terms if not isinstance(t, LobeAdapter)]


@lru_cache(maxsize=8)
def _sample(name: str) -> Any:
    """A sample mesh, decoded once per process (plans of the same scene do not read it again)."""
    from relight.mesh import sample_mesh

    return sample_mesh(name)


def resolve_meshes(scene: Scene, meshes: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Every mesh the scene's objects name: given (the service passes uploaded meshes by id), a sample shape
    (``relight.mesh.sample_mesh``) or a mesh file (``relight.mesh.load_mesh``)."""
    from pathlib import Path

    from relight.errors import InputError
    from relight.mesh import load_mesh

    out: dict[str, Any] = {}
    for o in scene.objects:
        ref = o.mesh_ref
        if ref is None or ref in out:
            continue
        if meshes is not None and ref in meshes:
            out[ref] = meshes[ref]
        elif o.mesh is None:
            out[ref] = _sample(ref)
        elif Path(ref).is_file():
            out[ref] = load_mesh(ref)
        else:
            raise InputError(f"objects {o.name!r}: mesh {ref!r} is neither a given mesh nor a readable mesh file")
    return out


def _plan_at(
    scene: Scene, pixels: FloatArray, epsilon: float, cal: costmodel.Calibration, lighting: Any = None,
    meshes: dict[str, Any] | None = None,
) -> Plan:
    """Plan every object at one tolerance (module docstring)."""
    from relight.prefilter import project_lighting, size_for_order

    meshes = meshes if meshes is not None else resolve_meshes(scene)
    h, w = pixels.shape[:2]
    f_cap = h - 1
    choices: dict[str, LobeChoice] = {}
    obj_lobes: list[list[str]] = []
    obj_others: list[list[Any]] = []
    obj_aniso: list[list[Any]] = []
    t_brdf = time.perf_counter()
    for obj in scene.objects:
        keys, others = [], []
        iso, aniso = material_parts(obj.material)
        for lobe in iso:
            # whether seed 000 draws the lobe does not depend on the lighting's order (represent.candidates)
            if not needs_seed000(iso_case(obj, lobe, scene, epsilon, None)):
                others.append(lobe)  # drawn by another representation: no App. C order search
                continue
            key = lobe_key(lobe)
            if key not in choices:
                choices[key] = choose(lobe, epsilon)
            keys.append(key)
        obj_lobes.append(keys)
        obj_others.append(others)
        obj_aniso.append(aniso)
    t_brdf = time.perf_counter() - t_brdf
    # projected once: to the largest lobe order, and at least to the SH-table predictions' bands (planner v2)
    f_proj = min(max([c.f_rho for c in choices.values()] + [PRED_ORDER + 1]), f_cap)
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
    obj_comps: list[list[Computation]] = []
    obj_shadows: list[Any] = []
    sizes: dict[str, int] = {}
    vertices = vertices_of(meshes)
    for obj, lobe_keys in zip(scene.objects, obj_lobes, strict=True):
        s = scene.size if scene.size is not None else size_for_order(max([lobe_info[k][0] for k in lobe_keys] + [2]))
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
                    order_search_probes=[list(p) for p in c.probes] if c.probes else None, order_search=c.search,
                )
            computations[ck].shared_by.append(obj.name)
            comps.append(computations[ck])
        sizes[obj.name] = s
        shadows = shadow_plan(obj, comps, epsilon, vertices.get(obj.mesh_ref or "", 0))
        obj_comps.append(comps)
        obj_shadows.append(shadows)

    # planner v2 (relight.planning.assign): a representation per lobe, shared jobs, the frame budget
    ids = {c.id: key for (key, _), c in computations.items()}
    comp_seconds = {c.id: cal.predict(_comp_features(choices[ids[c.id]], c)).seconds
                    for c in computations.values()}
    band = lighting.band_energy()
    f_l = order_for_tolerance(band, lighting.total_energy, epsilon)
    ctx = Context(scene=scene, epsilon=epsilon, band_energy=band, total_energy=lighting.total_energy, height=h,
                  width=w, vertices=vertices, comp_seconds=comp_seconds,
                  shadow_plans={o.name: sp for o, sp in zip(scene.objects, obj_shadows, strict=True)
                                if sp is not None}, f_l=f_l)
    parts = [p for obj, comps, others, aniso in zip(scene.objects, obj_comps, obj_others, obj_aniso, strict=True)
             for p in lobe_parts(obj, comps, others, aniso, ctx)]
    jobs, frame = choose_all(parts, ctx)
    reps = {o.name: [p.chosen for p in parts if p.obj.name == o.name and p.chosen is not None]
            for o in scene.objects}
    used = {r.computation for rr in reps.values() for r in rr if r.computation is not None
            and r.representation in SEED000}
    computations = {k: c for k, c in computations.items() if c.id in used}
    for obj, comps, shadows in zip(scene.objects, obj_comps, obj_shadows, strict=True):
        comps = [c for c in comps if c.id in used]
        if shadows is not None and not any(r.representation == "diffuse_transfer" for r in reps[obj.name]):
            shadows = None
        viewer = viewer_of(obj, comps, epsilon)
        errs = [r.predicted_error for r in reps[obj.name]]
        worst = ErrorSummary.of(max(comps, key=lambda c: c.predicted.get("epsilon_min_of_errors", 0.0)).predicted
                                if comps else {})
        worst = replace(worst, rms_min_of_errors=max([worst.rms_min_of_errors or 0.0, *errs]))
        objects.append(ObjectPlan(
            **obj.as_dict(), view_dependent=viewer.view_dependent, viewer=viewer.viewer, shrm=viewer.shrm,
            view_spread_deg=viewer.view_spread_deg, p_delta=viewer.p_delta,
            near_below_distance=viewer.near_below_distance, output_rows=sizes[obj.name],
            computations=[c.id for c in comps], predicted_error=worst,
            effects=effects(obj, comps, viewer, epsilon, shadows, reps[obj.name]), shadows=shadows,
            shadows_requested=obj.shadows, interreflections=obj.interreflections, mesh=obj.mesh,
            tangent=obj.tangent, material_edited=scene.edited(obj.name), representations=reps[obj.name],
            per_frame_ms=frame.per_object_ms.get(obj.name, 0.0),
        ))

    pred = cal.predict(_features({k: c for k, c in choices.items() if k in {ids[i] for i in used}}, computations,
                                 objects, h, w, f_proj))
    extra: dict[str, float] = {}
    for j in jobs.values():
        if j.kind != "shrm" and j.executed:  # ray casting, fits, chains, tables: relight.planning.costs
            stage = "shadows" if j.kind == "diffuse_transfer" else j.kind
            extra[stage] = extra.get(stage, 0.0) + j.predicted_seconds
    if extra:
        pred = replace(pred, seconds=pred.seconds + sum(extra.values()), stages={**pred.stages, **extra})
    worst_obj = max(objects, key=lambda o: o.predicted_error.rms_min_of_errors or 0.0)
    report = ScenePlan(
        relight_version=__version__, scene=scene.name, environment=scene.environment, epsilon=epsilon,
        time_budget_s=scene.time_budget_s, mode="tolerance" if scene.time_budget_s is None else "time_budget",
        lighting=LightingPlan(F_proj=f_proj, input={"height": h, "width": w}, seconds=t_proj,
                              shared_by=[o.name for o in scene.objects]),
        computations=list(computations.values()), objects=objects, brdf_seconds=t_brdf,
        predicted_seconds=pred.seconds, predicted_stages=pred.stages, predicted_error=worst_obj.predicted_error,
        cost_model=CostModelInfo(calibrated=cal.calibrated, key=cal.key), lighting_mode=scene.lighting,
        jobs=list(jobs.values()), frame=frame,
    )
    return Plan(scene=scene, report=report, lighting=lighting, choices=choices,
                keys={i: k for i, k in ids.items() if i in used}, meshes=meshes, pixels=pixels)


def _comp_features(c: LobeChoice, comp: Computation) -> dict[str, float]:
    """Cost-model features of one seed-000 computation alone (its lobe's coefficients and its maps)."""
    if c.structure == "radial":
        probes = [(f, 0) for f in costmodel.radial_probes(c.lobe, c.f_rho, explicit=False)] + [(comp.F_B, 0)]
        brdf = costmodel.brdf_features(c.lobe, c.f_rho, 0, explicit=False, probes=probes)
    else:
        brdf = costmodel.brdf_features(c.lobe, c.f_rho, c.p_rho, explicit=False, search="lpq", probes=c.probes)
    return costmodel.add_features(brdf, costmodel.synthesis_features(
        comp.size, comp.F_B, *costmodel.synthesis_counts(comp.structure, comp.P_B, comp.F_B)))


def plan_scene(
    scene: Scene, pixels: NDArray[np.floating], *, calibration: costmodel.Calibration | None = None,
    meshes: Mapping[str, Any] | None = None,
) -> Plan:
    """Plan a scene for an environment map (H, W, 3): at its tolerance, or under its time budget. ``meshes``: the
    uploaded meshes by the reference the objects give (sample shapes and mesh files are loaded here)."""
    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    resolved = resolve_meshes(scene, meshes)
    if scene.time_budget_s is not None:
        return plan_for_budget(scene, px, scene.time_budget_s, calibration=cal, meshes=resolved)
    assert scene.epsilon is not None
    return _plan_at(scene, px, scene.epsilon, cal, meshes=resolved)


def plan_for_budget(
    scene: Scene, pixels: NDArray[np.floating], budget_s: float, *, calibration: costmodel.Calibration | None = None,
    ladder: Sequence[float] = BUDGET_LADDER, meshes: Mapping[str, Any] | None = None,
) -> Plan:
    """The most accurate plan on ``ladder`` whose predicted seconds fit ``budget_s`` (module docstring).

    Predicted time grows as the tolerance tightens; the ladder is walked from the loosest tolerance and stops at the
    first plan over budget. If even the loosest does not fit, that plan is returned with ``budget_met = False``.
    """
    px = _pixels(pixels)
    cal = calibration if calibration is not None else costmodel.load_calibration()
    resolved = resolve_meshes(scene, meshes)
    general = any(not lobe.radially_symmetric for o in scene.objects for lobe in material_parts(o.material)[0])
    steps = [e for e in ladder if not (general and e < SHRM_MIN_EPSILON)]
    tried: list[BudgetStep] = []
    best: Plan | None = None
    lighting = None
    for eps in steps:
        plan = _plan_at(scene, px, eps, cal, lighting, resolved)
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
        for r in o.representations:
            terms = ", ".join(f"{k} = {v}" for k, v in r.terms.items() if k != "anisotropic")
            lines.append(f"    {r.kind}: {r.representation} (seed {r.seed}; {terms}), shadows {r.shadows}, predicted "
                         f"relative RMS {r.predicted_error:.3g} ({r.error_kind}), {r.predicted_precompute_s:.3g} s, "
                         f"{r.per_frame_ms:.3g} ms per frame" + ("" if r.executed else " [not executed]")
                         + ("" if r.note is None else f"; {r.note}"))
        for e in o.effects:
            lines.append(f"    {'+' if e.simulated else '-'} {e.effect}: {e.reason}")
    for j in d.jobs:
        lines.append(f"  job {j.kind}: {j.predicted_seconds:.3g} s, shared by {', '.join(j.shared_by)}")
    if d.frame is not None:
        fb = d.frame
        lines.append(f"  per frame {fb.predicted_ms:.3g} ms" + ("" if fb.budget_ms is None else
                     f" against a budget of {fb.budget_ms:g} ms ({'met' if fb.met else 'not met'})"))
        lines.extend(f"    frame budget: {x}" for x in fb.downgrades)
    lines.append(f"  predicted {d.predicted_seconds:.3g} s, worst predicted relative RMS "
                 f"{d.predicted_error.rms_min_of_errors:.3g}")
    return "\n".join(lines)


def plan_json(plan: Plan) -> str:
    """The plan as strict JSON (non-finite numbers as null)."""
    return json.dumps(jsonable(plan.report.to_json()), indent=1, allow_nan=False)
