"""Planner v2's assignment: every lobe of every object gets a representation (``relight.planning.represent``) with
its predicted error (``relight.planning.predict``), precompute seconds and per-frame milliseconds
(``relight.planning.costs``); jobs are shared across objects where the representation allows; a frame budget moves
lobes down their candidate lists until the scene fits (issue 16 item 4; design notes §5.4).

Sharing (design notes §5.4 "service economics"): seed 000 computations are shared per identical lobe (as before);
one Gaussian chain per environment and tolerance serves every Gaussian-lobe material; one fit per material; one SH
table per material and order; one transfer per mesh, kind, order and rays (every object on the same mesh shares
it).

Frame budget: while the predicted milliseconds of the scene exceed ``frame_budget_ms``, the lobe whose next
cheaper candidate saves the most per frame moves to it (each move is listed in ``FramePlan.downgrades``); when no
lobe can move, the plan says the budget is not met.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from relight.planning import costs, predict
from relight.planning.report import Alternative, Computation, FramePlan, LobeRepresentation, PlannedJob, ShadowPlan
from relight.planning.represent import SEED, VISIBILITY_ORDER, Candidate, LobeCase, candidates, per_lobe_note
from relight.planning.scene import Scene, SceneObject

#: Representations computed by seed 000's pipeline (``run_plan``'s SHRM path; the transfer uses the irradiance lobe).
SEED000 = frozenset({"irradiance", "reflection_map", "shrm_q0", "shrm", "diffuse_transfer"})

#: SH-table view resolution the plan asks for: 128 texels (the paper's; a 1-D table of 128 elevations for isotropic
#: lobes) and 64 x 64 views for anisotropic ones (the run's cost; issue 15's 128 x 128 remains `relight sh-table`'s).
TABLE_RESOLUTION_ISO = 128
TABLE_RESOLUTION_ANISO = 64
#: Rays per vertex bounds for the transfer jobs (as ``relight.planning.shadows``).
MIN_RAYS, MAX_RAYS = 256, 16384


@dataclass
class Part:
    """One lobe of one object: its case, the seed-000 computation when it is an isotropic lobe, its spec."""

    obj: SceneObject
    case: LobeCase
    spec: Any
    isotropic: bool
    comp: Computation | None
    options: list[Candidate]
    index: int = 0
    chosen: LobeRepresentation | None = None
    rejected: list[Alternative] = field(default_factory=list)


@dataclass
class Context:
    scene: Scene
    epsilon: float
    band_energy: Any  # lighting power per band (luminance)
    total_energy: float
    height: int
    width: int
    vertices: dict[str, int]  # mesh reference -> vertex count
    comp_seconds: dict[str, float]  # seed-000 computation id -> predicted seconds
    shadow_plans: dict[str, ShadowPlan]  # object name -> its diffuse transfer
    f_l: int | None


def rays_for(relative_error: float, coefficient_norm: float) -> int:
    """Smallest power of two of rays in [MIN_RAYS, MAX_RAYS] with ``coefficient_norm / sqrt(R) <= relative_error``.
    ``relight.visibility.predict``'s i.i.d. bounds relative to an unoccluded vertex are ``(F+1) / sqrt(R)`` for the
    visibility (``(F+1) sqrt(4 pi / R)`` against ``|v| = sqrt(4 pi)``) and for the shadow matrix (``(F+1)^2 /
    sqrt(R)`` against ``|I| = F + 1``), so ``coefficient_norm = F + 1`` for both."""
    need = (coefficient_norm / max(relative_error, 1e-12)) ** 2
    return int(min(MAX_RAYS, max(MIN_RAYS, 1 << max(0, math.ceil(math.log2(max(need, 1.0)))))))


def _job(kind: str, key: str, params: dict[str, Any], feats: dict[str, float], runnable: bool = True
         ) -> tuple[str, str, dict[str, Any], dict[str, float], bool]:
    return kind, f"{kind}:{key}", params, feats, runnable


def evaluate(part: Part, cand: Candidate, ctx: Context) -> tuple[LobeRepresentation, list[Any]]:
    """Predictions for one candidate of one lobe (module docstring): the report entry and its job requests."""
    obj, eps = part.obj, ctx.epsilon
    mesh = obj.mesh_ref
    verts = ctx.vertices.get(mesh, 0) if mesh is not None else 0
    pixels = costs.screen_pixels(obj.size, obj.distance)
    rep = cand.representation
    terms = dict(cand.terms)
    jobs: list[Any] = []
    parts: dict[str, float]
    kind = "bounded"
    c = part.comp
    if rep in ("irradiance", "reflection_map", "shrm_q0", "shrm"):
        assert c is not None
        err = float(c.predicted.get("rms_min_of_errors", math.sqrt(c.predicted.get("epsilon_min_of_errors", eps))))
        parts = {"min_of_errors": err}
        terms.update({"F": c.F_B, "P": c.P_B, "maps": c.n_maps})
        jobs.append(_job("shrm", c.id, {"computation": c.id}, {}))
    elif rep == "diffuse_transfer":
        sp = ctx.shadow_plans[obj.name]
        assert c is not None
        base = float(c.predicted.get("rms_min_of_errors", 0.0))
        err = math.sqrt(base**2 + sp.predicted_relative_error**2)
        parts = {"irradiance_order": base, "monte_carlo": sp.predicted_relative_error}
        terms.update({"F": sp.order, "coefficients": sp.coefficients, "rays": sp.rays})
        jobs.append(_job("diffuse_transfer", f"{mesh}:{sp.order}:{sp.rays}:{terms.get('bounces', 0)}",
                         {"mesh": mesh, "order": sp.order, "rays": sp.rays, "bounces": terms.get("bounces", 0)},
                         costs.transfer_features(verts, sp.rays * (1 + terms.get("bounces", 0)), sp.coefficients)))
    elif rep in ("sh_table", "prt_matrix"):
        loss = predict.table_band_loss(part.spec, part.isotropic, ctx.band_energy)
        f = int(terms["F"]) if "F" in terms else predict.table_order(loss, eps)[0]
        err = float(loss[f])
        parts = {"order_truncation": err}
        kind = "approximate"  # an average over views and lighting orientations (represent.ORIENTATION_AVERAGE)
        n = (f + 1) ** 2
        res = TABLE_RESOLUTION_ISO if part.isotropic else TABLE_RESOLUTION_ANISO
        from relight.brdf.spec import parse_frame_brdf
        from relight.sh_table import lobe_quadrature

        width = parse_frame_brdf(part.spec).lobe_width
        nodes = int(lobe_quadrature(width)[1].size)
        jobs.append(_job("sh_table", f"{predict.spec_key(part.spec)}:{f}:{res}",
                         {"brdf": part.spec, "order": f, "resolution": res},
                         costs.table_features(res if part.isotropic else res * res, nodes, f)))
        terms.update({"F": f, "coefficients": n, "resolution": res, "anisotropic": part.case.anisotropic})
        if rep == "prt_matrix":
            rays = rays_for(math.sqrt(eps), float(f + 1))
            mc = (f + 1) / math.sqrt(rays)
            err = math.sqrt(err**2 + mc**2)
            parts["monte_carlo"] = mc
            terms["rays"] = rays
            jobs.append(_job("shadow_matrix", f"{mesh}:{f}:{rays}", {"mesh": mesh, "order": f, "rays": rays},
                             costs.transfer_features(verts, rays, n * n)))
    elif rep == "gaussian_lobes":
        g = predict.gaussian_error(part.spec, eps)
        err, parts = g["rms"], {k: v for k, v in g.items() if k != "rms"}
        terms.update({"K": predict.FIT_LOBES, "elevations": predict.FIT_ELEVATIONS, "chain_ratio": "sqrt2"})
        nodes = predict.FIT_GRID[0] * predict.FIT_GRID[1]
        jobs.append(_job("gaussian_fit", predict.spec_key(part.spec), {"brdf": part.spec, "lobes": predict.FIT_LOBES,
                                                                        "elevations": predict.FIT_ELEVATIONS},
                         costs.fit_features(predict.FIT_ELEVATIONS, nodes, predict.FIT_LOBES)))
        orders, rows, sig = predict.chain_levels(ctx.height, eps, ctx.f_l)
        # every level at the sharpest level's size: the viewer and relight.gl.gaussian hold the chain in one
        # texture array (build_chain(..., uniform_size=True, size_cap=size), relight.planning.run_jobs)
        size = max(rows)
        jobs.append(_job("gaussian_chain", f"{ctx.scene.environment}:{eps:g}",
                         {"environment": ctx.scene.environment, "epsilon": eps, "ratio": "sqrt2",
                          "levels": len(sig), "size": size},
                         costs.chain_features(ctx.height, ctx.width, orders, [size] * len(rows))))
        if cand.shadows != "none":
            kind = "approximate"
            rays = rays_for(math.sqrt(eps), float(VISIBILITY_ORDER + 1))
            terms.update({"visibility_coefficients": (VISIBILITY_ORDER + 1) ** 2, "visibility_rays": rays})
            jobs.append(_job("visibility", f"{mesh}:{VISIBILITY_ORDER}:{rays}",
                             {"mesh": mesh, "order": VISIBILITY_ORDER, "rays": rays},
                             costs.transfer_features(verts, rays, (VISIBILITY_ORDER + 1) ** 2)))
    elif rep == "inout_prt":
        from relight.orders import uncaptured

        k = int(terms["K"])
        f_n = min(ctx.f_l if ctx.f_l is not None else predict.F_MAX, predict.F_MAX)
        eps_l = float(uncaptured(ctx.band_energy, ctx.total_energy)[min(f_n, len(ctx.band_energy) - 1)])
        rays = rays_for(math.sqrt(eps), float(f_n + 1))
        mc = (f_n + 1) / math.sqrt(rays)
        err = math.sqrt(eps + eps_l + mc**2)
        parts = {"uncaptured_singular_energy": math.sqrt(eps), "lighting_order": math.sqrt(eps_l), "monte_carlo": mc}
        terms.update({"coefficients": (f_n + 1) ** 2, "lighting_order": f_n, "rays": rays})
        jobs.append(_job("inout_transport", f"{mesh}:{predict.spec_key(part.spec)}:{k}:{f_n}:{rays}",
                         {"mesh": mesh, "brdf": part.spec, "terms": k, "order": f_n, "rays": rays},
                         costs.transfer_features(verts, rays, k * (f_n + 1) ** 2), cand.runnable))
    else:
        raise ValueError(f"unknown representation {rep!r}")
    frame = costs.frame_features(rep, terms, pixels, verts, cand.shadows)
    seconds = sum(ctx.comp_seconds.get(j[2].get("computation", ""), 0.0) if j[0] == "shrm"
                  else costs.Cost(j[3], {}).seconds() for j in jobs)
    entry = LobeRepresentation(
        lobe=part.spec, kind=part.case.kind, representation=rep, seed=SEED[rep], reason=cand.reason, terms=terms,
        shadows=cand.shadows, predicted_error=float(err), error_kind=kind, error_parts=parts,
        predicted_precompute_s=float(seconds), per_frame_ms=costs.Cost({}, frame).frame_ms(),
        jobs=[j[1] for j in jobs], computation=c.id if c is not None else None, executed=cand.runnable,
        not_executed_reason=cand.not_run_reason, note=per_lobe_note(cand, terms, float(err), eps),
    )
    return entry, jobs


def choose_all(parts: list[Part], ctx: Context) -> tuple[dict[str, PlannedJob], FramePlan]:
    """Choose every part's representation, enforce the frame budget and collect the shared jobs."""
    job_reqs: dict[int, list[Any]] = {}
    for i, part in enumerate(parts):
        _settle(part, ctx, job_reqs, i)
    budget = ctx.scene.frame_budget_ms
    downgrades: list[str] = []

    def total() -> float:
        return sum(p.chosen.per_frame_ms for p in parts if p.chosen is not None)

    while budget is not None and total() > budget:
        best: tuple[float, int, int, LobeRepresentation, list[Any]] | None = None
        for i, part in enumerate(parts):
            assert part.chosen is not None
            for j in range(part.index + 1, len(part.options)):
                cand = part.options[j]
                if not cand.runnable:
                    continue
                entry, jobs = evaluate(part, cand, ctx)
                saving = part.chosen.per_frame_ms - entry.per_frame_ms
                if saving > 0 and (best is None or saving > best[0]):
                    best = (saving, i, j, entry, jobs)
        if best is None:
            break
        _, i, j, entry, jobs = best
        part = parts[i]
        assert part.chosen is not None
        downgrades.append(f"{part.obj.name}/{part.case.kind}: {part.chosen.representation} -> {entry.representation}"
                          f" ({part.chosen.per_frame_ms:.3g} -> {entry.per_frame_ms:.3g} ms per frame)")
        part.rejected.append(Alternative(representation=part.chosen.representation,
                                         why_not=f"over the frame budget of {budget:g} ms"))
        part.index, part.chosen, job_reqs[i] = j, entry, jobs
        part.chosen = _with_alternatives(part, entry)
    jobs_out: dict[str, PlannedJob] = {}
    for i, part in enumerate(parts):
        for kind, key, params, feats, runnable in job_reqs[i]:
            if key not in jobs_out:
                secs = (ctx.comp_seconds.get(params.get("computation", ""), 0.0) if kind == "shrm"
                        else costs.Cost(feats, {}).seconds())
                jobs_out[key] = PlannedJob(id=key, kind=kind, params=params, predicted_seconds=secs,
                                           executed=runnable)
            if part.obj.name not in jobs_out[key].shared_by:
                jobs_out[key].shared_by.append(part.obj.name)
    per_obj: dict[str, float] = {}
    for p in parts:
        assert p.chosen is not None
        per_obj[p.obj.name] = per_obj.get(p.obj.name, 0.0) + p.chosen.per_frame_ms
    t = total()
    frame = FramePlan(budget_ms=budget, predicted_ms=t, met=None if budget is None else bool(t <= budget),
                      per_object_ms=per_obj, downgrades=downgrades)
    return jobs_out, frame


def _settle(part: Part, ctx: Context, job_reqs: dict[int, list[Any]], i: int) -> None:
    for j, cand in enumerate(part.options):
        if not cand.runnable:  # planned from its predictions, listed with why it is not run
            entry, _ = evaluate(part, cand, ctx)
            part.rejected.append(Alternative(representation=cand.representation, why_not=(
                f"{cand.reason}; predicted relative RMS {entry.predicted_error:.3g}, "
                f"{entry.predicted_precompute_s:.3g} s precompute, {entry.per_frame_ms:.3g} ms per frame; not "
                f"executed: {cand.not_run_reason}")))
            continue
        entry, jobs = evaluate(part, cand, ctx)
        part.index, job_reqs[i] = j, jobs
        part.chosen = _with_alternatives(part, entry)
        return
    raise AssertionError(f"no runnable representation for {part.obj.name}/{part.case.kind}")


def _with_alternatives(part: Part, entry: LobeRepresentation) -> LobeRepresentation:
    import dataclasses

    later = [Alternative(representation=c.representation, why_not=f"ranked after {entry.representation}: "
                         + c.reason) for c in part.options[part.index + 1:]]
    return dataclasses.replace(entry, alternatives=[*part.rejected, *later])


def vertices_of(meshes: dict[str, Any]) -> dict[str, int]:
    return {k: int(np.asarray(m.positions).shape[0]) for k, m in meshes.items()}



def rough_order(lobe: Any, epsilon: float) -> int:
    """The lobe's order for the tolerance without App. C's search: exact for radial lobes
    (``spectrum_for_tolerance``), the half-angle curve's l* at ``1 - epsilon`` for the others (seed 004 §4's recipe,
    ``relight.factor_predict``); used only to decide whether SH lighting to ``F_MAX`` is exact."""
    from relight.brdf.base import RadialLobe

    if isinstance(lobe, RadialLobe):
        return _radial_order(predict.spec_key([type(lobe).__qualname__, lobe.spec()]), lobe, float(epsilon))
    return _half_angle_order(predict.spec_key(lobe.spec()), round(1.0 - epsilon, 12))


_RADIAL_ORDERS: dict[tuple[str, float], int] = {}


def _radial_order(key: str, lobe: Any, epsilon: float) -> int:
    from relight.brdf.coefficients import spectrum_for_tolerance

    if (key, epsilon) not in _RADIAL_ORDERS:
        if len(_RADIAL_ORDERS) > 1024:
            _RADIAL_ORDERS.clear()
        _RADIAL_ORDERS[(key, epsilon)] = int(spectrum_for_tolerance(lobe, epsilon)[1])
    return _RADIAL_ORDERS[(key, epsilon)]


@lru_cache(maxsize=256)
def _half_angle_order(key: str, fraction: float) -> int:
    import json

    from relight.brdf.spec import parse_brdf
    from relight.factor_predict import half_angle_terms

    return int(half_angle_terms(parse_brdf(json.loads(key)), thresholds=(fraction,))["l_star"][fraction])


def iso_case(obj: SceneObject, lobe: Any, scene: Scene, epsilon: float, f_l: int | None, f_rho: int | None = None,
             inout_k: int | None = None) -> LobeCase:
    """The rules' view of one isotropic lobe of ``obj`` (``f_rho``: App. C's order when searched)."""
    from relight.planning.lobes import representation_of

    _, structure, _ = representation_of(lobe)
    return LobeCase(kind=lobe.kind, lambertian=lobe.kind == "lambert", anisotropic=False, radial=structure == "radial",
                    azimuthal=structure == "azimuthal", f_rho=rough_order(lobe, epsilon) if f_rho is None else f_rho,
                    f_l=f_l, shadows=obj.shadowed, interreflections=obj.interreflections, lighting=scene.lighting,
                    edited=scene.edited(obj.name), inout_k=inout_k)


def needs_seed000(case: LobeCase) -> bool:
    """Whether the rules' first choice for this lobe is a seed-000 computation (App. C's order search needed)."""
    return candidates(case)[0].representation in SEED000


def lobe_parts(obj: SceneObject, comps: list[Computation], others: list[Any], aniso: list[Any],
               ctx: Context) -> list[Part]:
    """The parts of one object: its isotropic lobes with seed-000 computations, those the rules send elsewhere
    (``others``: no order search), and its anisotropic terms."""
    out: list[Part] = []
    shadowed = obj.shadowed
    eps = ctx.epsilon

    def k_of(kind: str, spec: Any) -> int | None:
        return predict.inout_terms(spec, eps)[0] if shadowed != "none" and kind != "lambert" else None

    for c in comps:
        case = LobeCase(kind=c.kind, lambertian=c.kind == "lambert", anisotropic=False,
                        radial=c.structure == "radial", azimuthal=c.structure == "azimuthal", f_rho=c.F_rho,
                        f_l=ctx.f_l, shadows=shadowed, interreflections=obj.interreflections,
                        lighting=ctx.scene.lighting, edited=ctx.scene.edited(obj.name), inout_k=k_of(c.kind, c.lobe))
        out.append(Part(obj=obj, case=case, spec=c.lobe, isotropic=True, comp=c, options=candidates(case)))
    for lobe in others:
        spec = lobe.spec()
        case = iso_case(obj, lobe, ctx.scene, eps, ctx.f_l, inout_k=k_of(lobe.kind, spec))
        opts = [o if o.representation not in SEED000 else Candidate(
            o.representation, o.reason, o.terms, o.shadows, False,
            "App. C's order search is not run for a lobe the rules send to another representation") for o in
            candidates(case)]
        out.append(Part(obj=obj, case=case, spec=spec, isotropic=True, comp=None, options=opts))
    for t in aniso:
        case = LobeCase(kind=t.kind, lambertian=False, anisotropic=True, radial=False, azimuthal=False, f_rho=None,
                        f_l=ctx.f_l, shadows=shadowed, interreflections=obj.interreflections,
                        lighting=ctx.scene.lighting, edited=ctx.scene.edited(obj.name))
        out.append(Part(obj=obj, case=case, spec=t.spec(), isotropic=False, comp=None, options=candidates(case)))
    return out
