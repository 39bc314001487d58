"""Features of the cost model: the work of each stage of relight's pipeline counted from its sizes and orders
(seed 000 §6.2 Table 3, App. C). The terms are described in :mod:`relight.costmodel`; the angular method's counts are
in :mod:`relight.costmodel.angular`, the per-evaluation seconds of a lobe in :mod:`relight.costmodel.timing`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from relight.brdf.base import Lobe
from relight.costmodel.timing import lobe_eval_seconds
from relight.reports import PrefilterReport, ShrmReport

#: Features of each stage (module docstring). Stage names match the ``timings`` of the prefilter reports.
STAGES: dict[str, tuple[str, ...]] = {
    "brdf_coefficients": ("lobe_call", "lobe1d", "brdf_evals", "brdf_ops"),
    "lighting_projection": ("proj_call", "proj_px", "proj_leg"),
    "synthesis": ("comp_call", "syn_call", "syn_px", "syn_leg", "synq_px", "synq_leg"),
    "ringing_bound": ("ring_call", "ring"),
    "other": ("call", "conv"),
    "view": ("view_base", "view_px", "eq8_px", "lookup_px"),
    "angular": ("ang_pairs",),
    "angular_view": ("angv_pairs", "angv_evals"),
}
FEATURES: tuple[str, ...] = tuple(f for feats in STAGES.values() for f in feats)

#: Channels of every environment map (RGB).
CHANNELS = 3


# --------------------------------------------------------------------------------------------------- features
def _log2(n: int) -> float:
    return math.log2(max(n, 2))


def projection_features(height: int, width: int, f_proj: int, channels: int = CHANNELS) -> dict[str, float]:
    """Features of projecting an ``H x W`` map to order ``f_proj`` (module docstring)."""
    return {
        "proj_call": float(channels),
        "proj_px": float(channels * height * width) * _log2(width),
        "proj_leg": float(channels * height) * (f_proj + 1) ** 2,
    }


def synthesis_features(size: int, f_b: int, n_spin0: int, n_spin: int) -> dict[str, float]:
    """Features of ``n_spin0`` spin-0 and ``n_spin`` spin-weighted syntheses of order F_B on ``S x 2S``."""
    px = float(size * 2 * size) * _log2(2 * size)
    leg = float(size) * (f_b + 1) ** 2
    return {
        "comp_call": 1.0,
        "syn_call": float(n_spin0 + n_spin),
        "syn_px": n_spin0 * px,
        "syn_leg": n_spin0 * leg,
        "synq_px": n_spin * px,
        "synq_leg": n_spin * leg,
    }


def synthesis_counts(structure: str, p_b: int, f_b: int, channels: int = CHANNELS) -> tuple[int, int]:
    """(spin-0, spin-weighted) syntheses of one SHRM component (``relight.shrm._synthesize_ducc0``'s groups)."""
    if structure == "radial":
        return channels, 0
    if structure == "azimuthal":
        return channels * (p_b + 1), 0
    n_q = sum(min(p, f_b) for p in range(p_b + 1))  # groups (p, |q|) with 0 < |q| <= min(p, F)
    return channels * (p_b + 1), channels * n_q


def n_maps(structure: str, p_b: int) -> int:
    """Maps stored for a component: 1, P + 1 or (P + 1)^2 (seed 000 §7.3; ``relight.shrm.terms_for``)."""
    return 1 if structure == "radial" else (p_b + 1 if structure == "azimuthal" else (p_b + 1) ** 2)


def tabulation_points(f_order: int, p_order: int, *, radial: bool, azimuthal: bool) -> tuple[int, int]:
    """(grid points, Q + 1) of ``relight.brdf.lpq.tabulation_grid(F, P)`` (App. C's S_rho x T_rho x T_rho)."""
    from relight.brdf.lpq import tabulation_grid

    n_i, n_o, n_phi = tabulation_grid(f_order, p_order, radial=radial, azimuthal=azimuthal).shape
    q = 1 if (radial or azimuthal) else p_order + 1
    return n_i * n_o * n_phi, q


def probe_orders(lobe: Lobe, f_order: int, p_order: int, *, explicit: bool) -> list[tuple[int, int]]:
    """The (F, P) at which the BRDF coefficients are tabulated to reach (F, P).

    Explicit orders: just (F, P). From a tolerance (``relight.brdf.lpq_search.select_orders``): the starting orders,
    then both grown (F doubles, P + 4) until they cover (F, P) — the path the search takes when neither order alone
    is short, an estimate (the search stops at the first probe meeting the tolerance).
    """
    if explicit:
        return [(f_order, p_order)]
    from relight.brdf.lpq_search import starting_orders

    f0, p0 = starting_orders(lobe)
    if lobe.radially_symmetric:
        p0 = 0
    probes = [(f0, p0)]
    while f0 < f_order or p0 < p_order:
        f0 = 2 * f0 if f0 < f_order else f0
        p0 = p0 + 4 if p0 < p_order else p0
        probes.append((f0, p0))
    return probes

def radial_nodes(lmax: int, width: float) -> int:
    """Quadrature nodes of ``relight.brdf.coefficients.radial_transfer`` at order lmax for a lobe of this width
    (its ``_theta_nodes``: panels of ``min(pi / (2 (lmax + 2)), width / 12, pi / 64)`` plus 2 x 40 graded ones,
    16 Gauss–Legendre nodes each)."""
    h = min(math.pi / (2.0 * (lmax + 2)), max(width, 1e-4) / 12.0, math.pi / 64)
    n_half = math.ceil((math.pi / 2) / h)
    return 16 * (2 * n_half + 80)


def radial_probes(lobe: Lobe, f_rho: int, *, explicit: bool) -> list[int]:
    """Orders at which ``spectrum_for_tolerance`` evaluates a radial lobe to find F_rho (its doubling search)."""
    if explicit:
        return [f_rho]
    from relight.brdf.coefficients import lobe_width

    probe = max(16, math.ceil(4.0 / max(lobe_width(lobe), 1e-3)))  # type: ignore[arg-type]
    probes = [probe]
    while probe < f_rho:
        probe *= 2
        probes.append(probe)
    return probes

def brdf_features(
    lobe: Lobe, f_rho: int, p_rho: int, *, explicit: bool, eval_seconds: float | None = None,
    search: str = "radial", probes: Sequence[tuple[int, int]] | None = None,
) -> dict[str, float]:
    """BRDF coefficient stage of one lobe (module docstring): ``lobe1d`` for radial lobes, else tabulation.

    ``search`` names the order search a tolerance runs: ``"radial"`` (``prefilter_radial``'s
    ``spectrum_for_tolerance``) or ``"lpq"`` (App. C's whole-lobe ``lpq_search.select_orders``). ``probes`` gives the
    (F, P) the search actually tabulated (an SHRM report's ``probes``), else they are estimated
    (:func:`radial_probes`, :func:`probe_orders`).
    """
    if lobe.radially_symmetric:
        from relight.brdf.coefficients import lobe_width

        width = lobe_width(lobe)  # type: ignore[arg-type]
        if probes is not None:
            fs = [f for f, _ in probes]
        elif search == "radial":
            fs = radial_probes(lobe, f_rho, explicit=explicit)
        else:
            fs = [f for f, _ in probe_orders(lobe, f_rho, 0, explicit=explicit)]
        work = sum((f + 1) * radial_nodes(f, width) for f in fs)
        return {"lobe_call": 1.0, "lobe1d": float(work)}
    per = lobe_eval_seconds(lobe) if eval_seconds is None else eval_seconds
    evals = ops = 0.0
    path = list(probes) if probes is not None else probe_orders(lobe, f_rho, p_rho, explicit=explicit)
    for f, p in path:
        pts, q = tabulation_points(f, p, radial=False, azimuthal=bool(lobe.azimuthally_symmetric))
        evals += pts * per
        ops += pts * q
    return {"lobe_call": 1.0, "brdf_evals": evals, "brdf_ops": ops}


def view_features(components: Iterable[tuple[str, int, str]], size: int) -> dict[str, float]:
    """One distant view's map (``relight.shrm.reflect``) on ``S x 2S``; components as (structure, P_B, centre).

    ``view_base``: the normals ``N = normalize(R + V)`` of every pixel; ``view_px``: the eq. 12 sum over a
    component's maps; ``eq8_px``: eq. 8's rotation of a general component's local maps (cached after the first
    view); ``lookup_px``: the bilinear lookup of an N- or T-centred component at N or T(N).
    """
    px = float(size * 2 * size)
    view = eq8 = lookup = 0.0
    for structure, p_b, centre in components:
        if structure != "radial":
            view += n_maps(structure, p_b) * px
        if structure == "general" and p_b > 0:
            eq8 += sum((2 * p + 1) ** 2 for p in range(p_b + 1)) * px
        if centre != "R":
            lookup += px
    return {"view_base": px, "view_px": view, "eq8_px": eq8, "lookup_px": lookup}
def add_features(*parts: Mapping[str, float]) -> dict[str, float]:
    """Sum feature dictionaries (the costs of several operations run one after the other)."""
    out: dict[str, float] = {}
    for p in parts:
        for k, v in p.items():
            out[k] = out.get(k, 0.0) + float(v)
    return out


def radial_features(
    lobe: Lobe, *, height: int, width: int, f_rho: int, f_proj: int, f_b: int, size: int, explicit: bool = True
) -> dict[str, float]:
    """``relight.prefilter.prefilter_radial`` (Table 3's 1-D BRDF row plus the projection and lobe stages);
    ``explicit=False`` when the order came from a tolerance (the order search's probes are priced too)."""
    n0, _ = synthesis_counts("radial", 0, f_b)
    return add_features(
        brdf_features(lobe, f_rho, 0, explicit=explicit),
        projection_features(height, width, f_proj),
        synthesis_features(size, f_b, n0, 0),
        {"ring_call": 1.0, "ring": float(ringing_work(f_b)), "call": 1.0, "conv": float((f_proj + 1) ** 2)},
    )


def ringing_work(f_b: int) -> int:
    """Legendre evaluations of ``relight.brdf.coefficients.ringing_minimum``: ``16 (F + 1) + 256`` samples and
    three zoom passes of 201, each ``F + 1`` polynomials."""
    return (f_b + 1) * (16 * (f_b + 1) + 256 + 3 * 201)


@dataclass(frozen=True)
class LobePlan:
    """One lobe of an SHRM for the cost model: its structure and orders (``relight.shrm.create_shrm``)."""

    lobe: Lobe
    structure: str  # "radial", "azimuthal" or "general"
    f_rho: int
    f_b: int
    p_b: int
    explicit: bool = False
    #: (F, P) the order search tabulated (``probes`` of an SHRM report); None: estimated
    probes: tuple[tuple[int, int], ...] | None = None


def shrm_features(
    lobes: Sequence[LobePlan], *, height: int, width: int, f_proj: int, size: int, views: int = 0
) -> dict[str, float]:
    """``relight.shrm.create_shrm`` (Table 3's SHRM row), plus ``views`` eq. 12 maps."""
    parts: list[Mapping[str, float]] = [
        projection_features(height, width, f_proj), {"call": 1.0, "conv": float((f_proj + 1) ** 2)},
    ]
    for lp in lobes:
        parts.append(brdf_features(lp.lobe, lp.f_rho, lp.p_b, explicit=lp.explicit, search="lpq", probes=lp.probes))
        n0, nq = synthesis_counts(lp.structure, lp.p_b, lp.f_b)
        parts.append(synthesis_features(size, lp.f_b, n0, nq))
    if views:
        vf = view_features([(lp.structure, lp.p_b, str(lp.lobe.center)) for lp in lobes], size)
        parts.append({k: views * v for k, v in vf.items()})
    return add_features(*parts)


def prefilter_report_features(lobe: Lobe, report: PrefilterReport, *, height: int, width: int) -> dict[str, float]:
    """Features of a finished ``prefilter_radial`` run from its report (orders and whether they were explicit)."""
    o = report.orders
    size = report.output.height
    f_b = o.F_B
    f_rho = o.F_rho if o.F_rho is not None else f_b  # prefilter_radial always reports F_rho
    explicit = report.order_requested is not None
    f_proj = min(f_rho, height - 1)
    return radial_features(lobe, height=height, width=width, f_rho=f_rho, f_proj=f_proj, f_b=f_b, size=size,
                           explicit=explicit)


def shrm_lobe_plans(brdf: Any, report: ShrmReport) -> list[LobePlan]:
    """:class:`LobePlan` per component of a finished ``create_shrm`` run (orders and the search's probes)."""
    from relight.shrm import brdf_lobes

    plans = []
    for lobe, c in zip(brdf_lobes(brdf), report.components, strict=True):
        o = c.orders
        probes = tuple((int(q["F"]), int(q["P"])) for q in c.probes or [])
        plans.append(LobePlan(lobe=lobe, structure=str(c.structure), f_rho=int(o["F_rho"]), f_b=int(o["F_B"]),
                              p_b=int(o["P_B"]), explicit=bool(o.get("explicit")), probes=probes or None))
    return plans


def shrm_report_features(
    brdf: Any, report: ShrmReport, *, height: int, width: int, views: int = 0
) -> dict[str, float]:
    """Features of a finished ``create_shrm`` run (plus ``views`` eq. 12 maps) from its report."""
    plans = shrm_lobe_plans(brdf, report)
    f_proj = min(max(p.f_rho for p in plans), height - 1)
    size = int(report.output["height"])
    return shrm_features(plans, height=height, width=width, f_proj=f_proj, size=size, views=views)
