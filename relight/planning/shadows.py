"""Shadows in a scene plan: diffuse self-shadowing of Lambertian objects on meshes by precomputed radiance transfer
(Sloan, Kautz & Snyder 2002; ``relight.visibility``), and what stays unsimulated (issue 13, item 7).

* **Lambertian lobes on a mesh** are shadowed: the run computes the mesh's per-vertex transfer vectors
  (``diffuse_transfer``: ``T = int V max(0, n.w) / pi Yr``) and the exit radiance is ``albedo T . L``. The plan
  states the order, the rays per vertex and the predicted Monte Carlo error:

  - order ``F = max(F_B, MIN_ORDER)`` with F_B the diffuse lobe's irradiance order: shadowed transfer is not
    band-limited like the clamped cosine, and seed 002's 16-coefficient visibility (F = 3) is the floor;
  - rays: the smallest power of two in ``[MIN_RAYS, MAX_RAYS]`` whose i.i.d. error bound
    (``relight.visibility.predict``: ``(F+1) sqrt(2 / (3 pi R))`` on the per-vertex norm of T) is at most
    ``sqrt(epsilon)`` of an unoccluded vertex's transfer norm ``|T_0| = sqrt(sum_l (2l+1) / (4 pi) (2 I_l)^2)``
    (``relight.gl.prt.cosine_zonal``) — the plan's tolerance in the units of the relative RMS error; the stratified
    directions do better than the bound (``tests/relight/test_visibility.py``);
  - predicted seconds: rays cast at ``relight.visibility.PREDICTED_RAYS_PER_SECOND``.

* **Glossy lobes** (anything not Lambertian) are *not* shadowed: glossy shadows need visibility inside the lobe
  (seeds 002-004) and stay listed as not simulated.
* **The analytic sphere** is convex: it never shadows itself, so there is nothing to simulate (and no mesh).
"""

from __future__ import annotations

import math
from typing import Final

from relight.planning.report import Computation, Effect, LobeRepresentation, ShadowPlan
from relight.planning.scene import SceneObject

MIN_ORDER: Final = 3
MIN_RAYS: Final = 256
MAX_RAYS: Final = 16384
GLOSSY_REASON: Final = ("not simulated: not yet supported for glossy lobes (visibility inside the lobe: seeds "
                        "002-004); the lobe sees the whole environment")


def unoccluded_norm(order: int) -> float:
    """``|T_0|``: the transfer norm of an unoccluded vertex to order F (module docstring)."""
    from relight.gl.prt import cosine_zonal

    z = cosine_zonal(order)
    return math.sqrt(sum((2 * l + 1) / (4 * math.pi) * float(z[l]) ** 2 for l in range(order + 1)))


def _is_lambertian(c: Computation) -> bool:
    return c.kind == "lambert"


def shadow_plan(obj: SceneObject, comps: list[Computation], epsilon: float, vertices: int) -> ShadowPlan | None:
    """The transfer to compute for ``obj`` (None: a sphere, ``shadows: none``, or no Lambertian lobe)."""
    from relight.visibility import TransferSettings, predict

    diffuse = [c for c in comps if _is_lambertian(c)]
    if obj.mesh_ref is None or obj.shadowed == "none" or not diffuse:
        return None
    order = max(MIN_ORDER, max(c.F_B for c in diffuse))
    target = math.sqrt(epsilon) * unoccluded_norm(order)
    need = (order + 1) ** 2 * 2.0 / (3.0 * math.pi) / (target * target)
    rays = min(MAX_RAYS, max(MIN_RAYS, 1 << max(0, math.ceil(math.log2(need)))))
    pred = predict(TransferSettings(order=order, rays=rays, kind="diffuse_transfer"), vertices)
    err = float(pred["monte_carlo_error_bound"]["transfer_error"])
    return ShadowPlan(kind="diffuse_transfer", mesh=obj.mesh_ref, vertices=vertices, order=order,
                      coefficients=(order + 1) ** 2, rays=rays, predicted_monte_carlo_error=err,
                      predicted_relative_error=err / unoccluded_norm(order), predicted_seconds=pred["seconds"],
                      lobes=[c.id for c in diffuse])


def shadow_effects(obj: SceneObject, comps: list[Computation], plan: ShadowPlan | None,
                   reps: list[LobeRepresentation] | None = None) -> list[Effect]:
    """The shadowing and interreflection entries of an object's effects (module docstring): the diffuse transfer,
    and per glossy lobe what its planner-v2 representation simulates (``relight.planning.represent``)."""
    out = []
    if obj.mesh_ref is None:
        out.append(Effect(effect="shadowing", simulated=False,
                          reason="nothing to simulate: the sphere is convex and never shadows itself"))
    elif plan is not None:
        out.append(Effect(
            effect="shadowing (diffuse: " + ", ".join(plan.lobes) + ")", simulated=True,
            reason=f"per-vertex shadowed transfer of the {plan.mesh} mesh ({plan.vertices} vertices; Sloan, Kautz "
            f"& Snyder 2002): order F = {plan.order} ({plan.coefficients} coefficients), {plan.rays} rays per "
            f"vertex, predicted Monte Carlo error <= {plan.predicted_monte_carlo_error:.3g} "
            f"({100 * plan.predicted_relative_error:.2g} % of an unoccluded vertex's transfer)"))
    for r in reps or []:
        if r.kind == "lambert" or obj.mesh_ref is None:
            continue
        what = f"shadowing (glossy: {r.kind}, {r.representation})"
        if obj.shadowed == "none":
            out.append(Effect(effect=what, simulated=False, reason="not simulated: the object asks for shadows: none"))
        elif r.shadows == "approximate":
            out.append(Effect(effect=what, simulated=True, reason=(
                f"shadowing approximate: visibility constant over each Gaussian lobe, taken at its centre from the "
                f"per-vertex order-3 SH visibility ({r.terms.get('visibility_coefficients')} coefficients, "
                f"{r.terms.get('visibility_rays')} rays per vertex; seed 002 eq. 7); no error bound, measured "
                "against Mitsuba in the tests")))
        elif r.shadows == "exact":
            out.append(Effect(effect=what, simulated=True, reason=(
                f"shadowing exact within SH order {r.terms.get('F', r.terms.get('lighting_order'))}: visibility "
                f"inside the transfer ({r.terms.get('rays')} rays per vertex; "
                + ("seed 003 §5 transfer matrices)" if r.representation == "prt_matrix" else "seed 004 eq. 3)"))))
        else:
            out.append(Effect(effect=what, simulated=False, reason=GLOSSY_REASON))
    if obj.mesh_ref is not None:
        out.append(Effect(effect="shadows cast by other objects", simulated=False,
                          reason="not simulated: each transfer is computed on the object's own mesh; objects do "
                          "not occlude each other"))
    bounce = any(r.representation == "diffuse_transfer" and r.terms.get("bounces") for r in reps or [])
    if obj.interreflections and bounce:
        out.append(Effect(effect="interreflection (diffuse)", simulated=True,
                          reason="one bounce of the Lambertian lobe's own light within the mesh (SKS02 §4)"))
    glossy_inter = obj.interreflections and any(r.kind != "lambert" for r in reps or [])
    out.append(Effect(effect="interreflection" + (" (glossy)" if bounce else ""), simulated=False, reason=(
        "not simulated: glossy interreflections need a BRDF-dependent transfer, which relight.sh_prt does not "
        "implement (shadows only)" if glossy_inter else
        "not simulated: not requested (interreflections: false); objects do not light each other"
        if not obj.interreflections else "not simulated: objects do not light each other")))
    return out
