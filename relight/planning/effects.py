"""Distant or near viewer, and what a plan simulates and skips for each object (seed 000 §3, eqs. 6–7, §5.1).

The viewer at distance d sees an object of bounding radius r under the view directions of a cone of full angle
``delta = 2 asin(r / d)``. A global SHRM (eq. 7) uses one V for the whole object; an order-P expansion in V varies
at the scale of its angular resolution ``pi / P`` (the half period of ``Y_P``), and to first order a change of V by
delta changes it by about ``P delta`` relative to its size (``|dY_p / dtheta| <~ p |Y_p|``). The plan keeps the
global SHRM while ``P_B delta <= sqrt(epsilon)`` (that change stays below the tolerance's relative RMS) and switches
to the local SHRM (eq. 6, per-pixel V) beyond, i.e. for ``d < r / sin(sqrt(epsilon) / (2 P_B))``. Lobes with
P_B = 0 need no V at all (the map is indexed by R or N, computed per pixel), so near or far makes no difference.

Every plan lists each effect simulated and each effect skipped with the reason (view dependence of a radially
symmetric lobe, q != 0 terms of an azimuthally symmetric one, orders above the tolerance, near-viewer variation,
self-shadowing and interreflection (``relight.planning.shadows``), and per lobe what its planner-v2 representation
simulates and skips (``relight.planning.represent``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from relight.planning.report import Computation, Effect, LobeRepresentation, ShadowPlan
from relight.planning.scene import SceneObject
from relight.planning.shadows import shadow_effects


def view_spread(size: float, distance: float) -> float:
    """Full angle (radians) of the cone of view directions over an object: ``2 asin(r / d)``."""
    return 2.0 * math.asin(min(1.0, size / distance))


def near_threshold_distance(size: float, p_b: int, epsilon: float) -> float:
    """Distance below which the local SHRM is used: ``r / sin(sqrt(epsilon) / (2 P_B))`` (0 for P_B = 0)."""
    if p_b <= 0:
        return 0.0
    half = math.sqrt(epsilon) / (2.0 * p_b)
    return math.inf if half <= 0.0 else (size / math.sin(half) if half < math.pi / 2 else size)


@dataclass(frozen=True)
class Viewer:
    """The viewer of one object (module docstring)."""

    view_dependent: bool
    near: bool
    view_spread_deg: float
    p_delta: float
    near_below_distance: float

    @property
    def viewer(self) -> str:
        return "near" if self.near else "distant"

    @property
    def shrm(self) -> str:
        if not self.view_dependent:
            return "none (P = 0)"
        return "local (eq. 6)" if self.near else "global (eq. 7)"


def viewer_of(obj: SceneObject, comps: list[Computation], epsilon: float) -> Viewer:
    """Distant or near viewer for an object with these computations at this tolerance (module docstring)."""
    delta = view_spread(obj.size, obj.distance)
    p_max = max((c.P_B for c in comps if c.structure != "radial"), default=0)
    view_dependent = p_max > 0
    return Viewer(view_dependent=view_dependent, near=view_dependent and p_max * delta > math.sqrt(epsilon),
                  view_spread_deg=math.degrees(delta), p_delta=p_max * delta,
                  near_below_distance=near_threshold_distance(obj.size, p_max, epsilon))


def effects(obj: SceneObject, comps: list[Computation], viewer: Viewer, epsilon: float,
            shadows: ShadowPlan | None = None, reps: list[LobeRepresentation] | None = None) -> list[Effect]:
    """What is simulated and what is skipped for one object, with reasons (``shadows``: its diffuse transfer,
    :func:`relight.planning.shadows.shadow_plan`)."""
    out: list[Effect] = []
    for c in comps:
        lobe = f"{c.kind} ({c.center}-centred)"
        if c.representation == "irradiance":
            out.append(Effect(effect=f"diffuse reflection: {lobe}", simulated=True,
                              reason=f"irradiance to order F = {c.F_B}: {(c.F_B + 1) ** 2} coefficients"
                              + ("" if c.F_B <= 2 else f" (the tolerance {epsilon:g} is below the 1/128 that F = 2 "
                                 "leaves out, so F > 2)")))
        elif c.representation == "reflection_map":
            out.append(Effect(effect=f"glossy reflection: {lobe}", simulated=True,
                              reason=f"2-D reflection map to order F = {c.F_B}"))
        else:
            out.append(Effect(effect=f"view-dependent reflection: {lobe}", simulated=True,
                              reason=f"SHRM to orders F = {c.F_B}, P = {c.P_B}: {c.n_maps} maps"))
        if c.structure == "radial":
            out.append(Effect(effect=f"view dependence: {lobe}", simulated=False,
                              reason="BRDF is radially symmetric: it depends on the angle to its centre only (P = 0)"))
        elif c.structure == "azimuthal":
            out.append(Effect(effect=f"azimuthal view dependence (q != 0): {lobe}", simulated=False,
                              reason="the lobe has no azimuthal dependence: only the q = 0 terms are non-zero"))
        cut = c.F_B < c.F_rho
        out.append(Effect(
            effect=f"orders above F = {c.F_B}" + (f", P = {c.P_B}" if c.P_B else "") + f": {lobe}", simulated=False,
            reason=(f"the lighting holds less than epsilon = {epsilon:g} of its energy above F_L = {c.F_L} "
                    "(minimum-of-orders rule, §5.1)") if cut else
            (f"their share of the lobe's energy is below the tolerance: epsilon_rho = {c.epsilon_rho:.3g} "
             f"<= {epsilon:g} (§5.1)")))
    if viewer.view_dependent:
        near = viewer.near
        out.append(Effect(
            effect="near-viewer variation of the view direction (local SHRM, eq. 6)", simulated=near,
            reason=(f"view spread {viewer.view_spread_deg:.3g} deg over the object: P_B delta = {viewer.p_delta:.3g} "
                    f"{'>' if near else '<='} sqrt(epsilon) = {math.sqrt(epsilon):.3g}; "
                    + ("local SHRM, V per pixel" if near else "one V for the object (global SHRM, eq. 7)"))))
    else:
        out.append(Effect(effect="near-viewer variation of the view direction", simulated=False,
                          reason="no view-dependent lobe: every map is indexed by R or N, computed per pixel, exact "
                          "for any viewer distance"))
    out.append(Effect(effect=f"shape: {obj.shape}", simulated=True,
                      reason="the maps do not depend on the shape; it only sets the normals looked up per pixel"))
    out.append(Effect(effect="parallax of the environment", simulated=False,
                      reason="the environment is distant (seed 000 §3): the same lighting at every point"))
    out.extend(representation_effects(reps or [], epsilon))
    out.extend(shadow_effects(obj, comps, shadows, reps))
    return out


def representation_effects(reps: list[LobeRepresentation], epsilon: float) -> list[Effect]:
    """Per lobe: its planner-v2 representation, anisotropy, the lighting bands it discards and run-time edits."""
    out = []
    for r in reps:
        out.append(Effect(effect=f"representation: {r.kind} -> {r.representation} (seed {r.seed})",
                          simulated=r.executed, reason=r.reason + ("" if r.executed else
                                                                   f"; not executed: {r.not_executed_reason}")))
        if r.representation in ("sh_table", "prt_matrix"):
            f = r.terms["F"]
            out.append(Effect(effect=f"lighting and BRDF above band {f}: {r.kind}", simulated=False, reason=(
                f"an order-{f} table ({(f + 1) ** 2} coefficients) sees bands <= {f} only: predicted relative RMS "
                f"{r.predicted_error:.3g}" + (f" ({r.note})" if r.note else f" <= sqrt(epsilon) = "
                                                                            f"{math.sqrt(epsilon):.3g}"))))
            if r.terms.get("anisotropic"):
                out.append(Effect(effect=f"anisotropy: {r.kind}", simulated=True,
                                  reason="per-view SH table in the tangent frame (seed 003)"))
        if r.representation == "gaussian_lobes":
            out.append(Effect(effect=f"material edits at run time: {r.kind}", simulated=True,
                              reason="the K Gaussian lobes are the material: edit mu, sigma, w without reprocessing "
                              "(seed 002 §1); the chain is shared"))
    return out
