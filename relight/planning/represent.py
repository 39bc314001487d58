"""Planner v2: per lobe of every object, which of relight's four separations of the rendering integral to use
(issue 16 item 4; design notes §5.3, §5.4).

Candidates, in the order the rules prefer them (each with its reason; the first is chosen, the others are kept as
alternatives with why they lost, and the frame budget may move a lobe down its list, ``relight.planning.frame``):

1. **Lambertian** lobe: ``irradiance`` (seed 000 §5.2, 9 coefficients); with shadows on a mesh
   ``diffuse_transfer`` (SKS02 per-vertex transfer, exact within its order; ``relight.planning.shadows``), with
   one interreflection bounce when asked.
2. **Anisotropic** lobe (a tangent-frame BRDF): ``sh_table`` (seed 003) — the only option — at the smallest order
   whose predicted error meets the tolerance, capped at ``F_MAX`` (81 coefficients); above the cap it is planned
   anyway and the plan says the lobe is blurred, with the predicted error. Shadows: ``prt_matrix`` (the table on
   transferred lighting, exact shadows within the order).
3. **Dynamic lighting** (isotropic): ``sh_table`` when the lighting's or the lobe's order for the tolerance is
   within ``F_MAX`` (exact to epsilon, design notes §5.2 item 4), with ``prt_matrix`` for shadows; else
   ``gaussian_lobes`` (the chain is re-prefiltered per change: its seconds are reported).
4. **Shadows** (isotropic glossy lobe on a mesh): ``inout_prt`` with K = K_hemi(epsilon) terms (seed 004) when
   K is at most ``INOUT_MAX_TERMS`` and its per-frame cost fits the frame budget; ``prt_matrix`` when order
   ``F_MAX`` is exact to epsilon; else ``gaussian_lobes`` with seed 002's SH visibility (approximate: visibility
   constant over each lobe). ``shadows: approximate`` goes to ``gaussian_lobes`` directly.
5. **Live material edits**: ``gaussian_lobes`` (the lobes are the material: edits cost nothing).
6. **Otherwise**: seed 000 — ``reflection_map`` (radial), ``shrm_q0`` (no azimuthal dependence), ``shrm``; when
   the lighting or the lobe is band-limited enough that order ``F_MAX`` is exact to epsilon, ``sh_table`` is the
   next candidate (exact too; the frame budget may pick it).

``sh_table`` and ``gaussian_lobes`` are also the fallbacks a frame budget can choose (they are cheaper per frame
than PRT and in-out terms). The in-out renderer (issue 16 item 3) is executed only where it exists on this
installation (:func:`inout_available`); otherwise the candidate is listed with that reason and the next one taken.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass, field
from typing import Any, Final

from relight.planning.predict import F_MAX

#: Seed (paper) of each representation.
SEED: Final = {"irradiance": "000", "reflection_map": "000", "shrm_q0": "000", "shrm": "000",
               "diffuse_transfer": "SKS02 (issue 13)", "gaussian_lobes": "002", "sh_table": "003",
               "prt_matrix": "003", "inout_prt": "004"}
#: Order of the per-vertex SH visibility seed 002 uses for glossy shadows (16 coefficients, eq. 7).
VISIBILITY_ORDER: Final = 3
#: Module of the in-out PRT renderer (issue 16 item 3); planned from predictions, executed only when present.
INOUT_MODULE: Final = "relight.inout_prt"
#: Most in-out terms the planner gives a lobe: seed 004 §5 ("K limited to 10-20", i.e. Phong s < 10) and design
#: notes §5.3 (low gloss, K <= ~25); sharper lobes take seed 002's approximate shadows instead.
INOUT_MAX_TERMS: Final = 25


def inout_available() -> bool:
    """Whether the in-out PRT renderer exists on this installation (module docstring)."""
    return importlib.util.find_spec(INOUT_MODULE) is not None


@dataclass
class Candidate:
    """One way to draw one lobe (module docstring); ``terms`` holds its orders / counts."""

    representation: str
    reason: str
    terms: dict[str, Any] = field(default_factory=dict)
    shadows: str = "none"  # none / approximate / exact
    runnable: bool = True
    not_run_reason: str | None = None


@dataclass(frozen=True)
class LobeCase:
    """What the rules read about one lobe of one object."""

    kind: str
    lambertian: bool
    anisotropic: bool
    radial: bool
    azimuthal: bool
    f_rho: int | None  # the lobe's order for the tolerance (None: anisotropic)
    f_l: int | None  # the lighting's order for the tolerance
    shadows: str  # the object's request, resolved: none on the sphere
    interreflections: bool
    lighting: str
    edited: bool
    inout_k: int | None = None  # K_hemi(1 - epsilon), isotropic glossy lobes on shadowed meshes


def _exact_order(case: LobeCase) -> int | None:
    """Order F <= F_MAX at which an SH-lighting representation is exact to the tolerance, or None."""
    fs = [f for f in (case.f_l, case.f_rho) if f is not None]
    f = min(fs) if fs else None
    return None if f is None or f > F_MAX else max(f, 2)


def candidates(case: LobeCase) -> list[Candidate]:
    """The candidates of one lobe in the rules' order (module docstring)."""
    shadowed = case.shadows != "none"
    if case.lambertian:
        if shadowed:
            out = [Candidate("diffuse_transfer", "Lambertian lobe on a mesh with shadows: per-vertex shadowed "
                             "transfer (SKS02), exact within its order" + (", one interreflection bounce"
                                                                            if case.interreflections else ""),
                             {"bounces": 1 if case.interreflections else 0}, "exact")]
            return [*out, Candidate("irradiance", "unshadowed irradiance (the cheaper fallback)")]
        return [Candidate("irradiance", "Lambertian lobe: irradiance coefficients only (seed 000 §5.2)")]

    exact = _exact_order(case)
    table_shadows = "exact" if shadowed else "none"
    table = "prt_matrix" if shadowed else "sh_table"
    if case.anisotropic:
        return [Candidate(table, "anisotropic lobe: per-view SH tables are the only representation of a "
                          "tangent-frame BRDF (seed 003)" + (", shadows by per-vertex transfer matrices (§5)"
                                                              if shadowed else ""), {}, table_shadows)]

    gauss_shadow = "approximate" if shadowed else "none"
    gauss = Candidate("gaussian_lobes", "", {"K": 3}, gauss_shadow)
    seed000 = _seed000(case)
    if case.lighting == "dynamic":
        if exact is not None:
            return [Candidate(table, f"dynamic lighting: order F = {exact} is exact to the tolerance (min of the "
                              f"lighting's F_L = {case.f_l} and the lobe's F_rho = {case.f_rho}), so the SH table "
                              "takes a new lighting vector per frame (seed 003)", {"F": exact}, table_shadows),
                    _why(gauss, "fallback: re-prefilter the chain on each lighting change")]
        return [_why(gauss, f"dynamic lighting above order {F_MAX} (F_L = {case.f_l}, F_rho = {case.f_rho}): SH "
                     "tables would blur it; Gaussian lobes re-prefilter the chain per change (about a second, seed "
                     "002 §5.1)"), Candidate(table, f"fallback: SH table at order {F_MAX} (blurred)", {"F": F_MAX},
                                             table_shadows)]
    if shadowed:
        out = []
        if case.shadows != "approximate":
            k = case.inout_k or 0
            why_not = (None if k <= INOUT_MAX_TERMS else f"K = {k} terms exceed the {INOUT_MAX_TERMS} a glossy lobe "
                       "is given (seed 004 §5: in-out PRT suits low gloss)")
            if not inout_available():
                why_not = f"the in-out PRT renderer ({INOUT_MODULE}, issue 16 item 3) is not on this installation"
            out.append(Candidate("inout_prt", f"glossy lobe with shadows: in-out PRT with K = {k} terms "
                                 "(K_hemi at 1 - epsilon of the BRDF's energy, seed 004), shadows exact within the "
                                 "lighting's order, view and lighting dynamic", {"K": k}, "exact", why_not is None,
                                 why_not))
            if exact is not None:
                out.append(Candidate("prt_matrix", f"glossy lobe with shadows at low frequency: order F = {exact} "
                                     "is exact to the tolerance; SH table on shadow-transferred lighting (seed 003 "
                                     "§5)", {"F": exact}, "exact"))
        out.append(_why(gauss, "glossy lobe with shadows: Gaussian lobes with per-vertex SH visibility at each "
                        "lobe's centre (seed 002 eq. 7), the only high-frequency option with shadows"))
        if exact is None and case.shadows != "approximate":
            out.append(Candidate("prt_matrix", f"exact shadows at order {F_MAX}, the lobe blurred", {"F": F_MAX},
                                 "exact"))
        return out
    if case.edited:
        return [_why(gauss, "material edited live: Gaussian lobes are the material (seed 002 §1: edits without "
                     "reprocessing); the chain is shared"), seed000]
    banded = ([Candidate("sh_table", f"band-limited enough: order F = {exact} is exact to the tolerance (min of the "
                         f"lighting's F_L = {case.f_l} and the lobe's F_rho = {case.f_rho}), so an SH table (seed "
                         "003) is exact too; under static lighting seed 000 comes first (exact at any frequency, no "
                         "per-vertex rotation)", {"F": exact})] if exact is not None else [])
    return [seed000, *banded, _why(gauss, "fallback: one shared chain + a ~1 KB fit")]


def _why(c: Candidate, reason: str) -> Candidate:
    return Candidate(c.representation, reason, dict(c.terms), c.shadows, c.runnable, c.not_run_reason)


def _seed000(case: LobeCase) -> Candidate:
    if case.radial:
        return Candidate("reflection_map", "radially symmetric lobe: one 2-D reflection map (seed 000 §3.1), exact "
                         "to the tolerance at any frequency")
    if case.azimuthal:
        return Candidate("shrm_q0", "no azimuthal dependence: q = 0 SHRM terms only (seed 000 §7.1)")
    return Candidate("shrm", "general isotropic lobe: SHRM (seed 000 §4), exact to the tolerance")


#: Why an SH table's or PRT matrix's predicted error is ``approximate`` (``relight.planning.predict``: band energies
#: weighted over view elevations (and azimuths) and a lighting in a random orientation): one object is one view of one
#: orientation and can exceed it (measured: a brushed-metal floor, PRT matrix F = 6, 0.338 against 0.280 predicted;
#: tests/relight/test_planning_run_jobs.py).
ORIENTATION_AVERAGE: Final = "predicted error is an average over views and lighting orientations"


def per_lobe_note(chosen: Candidate, terms: dict[str, Any], error: float, epsilon: float) -> str | None:
    """The plan's remark when a lobe is blurred by its order (seed 003's cap) or its error exceeds sqrt(epsilon),
    and for SH tables and PRT matrices why their error is approximate (:data:`ORIENTATION_AVERAGE`)."""
    if chosen.representation not in ("sh_table", "prt_matrix"):
        return None
    if error > math.sqrt(epsilon):
        return (f"sharp lobe blurred to order F = {terms.get('F')}: predicted relative RMS {error:.3g} "
                f"> sqrt(epsilon) = {math.sqrt(epsilon):.3g}; {ORIENTATION_AVERAGE}")
    return ORIENTATION_AVERAGE
