"""Creating an SHRM from an environment map and a BRDF (seed 000 Fig. 3, App. C): order selection (§5.1),
predicted errors (App. B generalised), lighting projection and local synthesis.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, validate
from relight.brdf import lpq
from relight.brdf.base import Lobe
from relight.brdf.coefficients import lambda_l
from relight.conventions import (
    require_rgb_latlong,
)
from relight.errors import InputError
from relight.orders import order_for_tolerance, rms_from_energy, uncaptured
from relight.prefilter import DEFAULT_EPSILON, LightingSpectrum, Timer, project_lighting, size_for_order
from relight.reports import ShrmComponentReport, ShrmPredicted, ShrmReport
from relight.settings import SETTINGS
from relight.shrm import order_search
from relight.shrm.basis import (
    Backend,
    structure_of,
    terms_for,
)
from relight.shrm.model import SHRM, SHRMComponent
from relight.shrm.synthesis import synthesize_local
from relight.shrm.view_bands import view_prediction
from relight.shrm.view_spectrum import ViewSpectrum, band_edges


# ------------------------------------------------------------------------------------------------ creation
def brdf_lobes(brdf: Any) -> list[Lobe]:
    """The lobes of a material: the BRDF itself if it is a lobe, else its ``lobes`` (a sum of lobes)."""
    if isinstance(brdf, Lobe):  # a lobe may have its own ``lobes`` (Lafortune's cosine lobes): it is one lobe
        return [brdf]
    lobes = getattr(brdf, "lobes", None)
    if lobes is None:
        raise InputError(f"not a BRDF lobe or sum of lobes: {type(brdf).__name__}")
    out = list(lobes)
    if not out or not all(isinstance(x, Lobe) for x in out):
        raise InputError("a sum of lobes needs at least one lobe, and only lobes")
    return out


def _spec(obj: Any) -> dict[str, Any] | None:
    try:
        from relight.brdf.spec import brdf_to_spec

        spec = brdf_to_spec(obj)
        return spec if isinstance(spec, dict) else {"spec": spec}
    except Exception:  # noqa: BLE001 - the spec module is optional; fall back to the lobe's own spec
        s = getattr(obj, "spec", None)
        return s() if callable(s) else None


def predicted_errors(
    coeffs: lpq.BRDFCoefficients, lighting: LightingSpectrum, f_b: int, p_b: int
) -> dict[str, float]:
    """Predicted uncaptured energy fractions of the 4-D light field at (F_B, P_B) (§5.1, App. B generalised).

    * ``epsilon_brdf``: the BRDF's uncaptured energy (the paper's choice, §5.1, Fig. 7);
    * ``epsilon_lighting``: the lighting's at F_B; ``epsilon_min_of_errors`` = min of the two;
    * ``epsilon_appendix_b``: App. B's bound with ``B_lmpq`` in place of ``B_lm``. By Parseval over (alpha, beta)
      and w_o the output energy is ``sum_l Lambda_l^2 E^L_l E^rho_lp`` (``E^L_l = sum_m |L_lm|^2``). The residual is
      ``Lambda_{F+1}^2 (eps_L L_tot)(eps_rho rho_tot)`` for l > F (App. B: Lambda_l decreases, all terms are
      non-negative) plus, for l <= F and p > P, ``sum_{l<=F} Lambda_l^2 E^L_l E^rho_{l,P<p<=P0}`` over the computed
      bands and ``max_{l<=F}(Lambda_l^2 E^L_l)`` times the BRDF energy outside the computed range (App. B's "worst
      case: all in one mode"); ``epsilon_B <= B_res / (B_captured + B_res)``.

    Each also as a relative RMS (``sqrt``). These are energies of the whole light field; a single view's map
    can have a larger or smaller relative error.
    """
    e_rho = coeffs.band_energy().max(axis=2)  # (F+1, P+1)
    rho_tot = float(coeffs.total_energy.max())
    table = coeffs.epsilon_table()
    eps_rho = float(table[f_b, p_b])
    e_light = lighting.band_energy()
    f_l = min(f_b, lighting.lmax)
    eps_l = float(uncaptured(e_light, lighting.total_energy)[f_l])
    lam2 = lambda_l(f_b + 1) ** 2
    captured = float(np.sum(lam2[: f_l + 1] * e_light[: f_l + 1] * e_rho[: f_l + 1, : p_b + 1].sum(axis=1)))
    outside = max(rho_tot - float(e_rho.sum()), 0.0)
    a_l = lam2[: f_l + 1] * e_light[: f_l + 1]
    res_p = float(np.sum(a_l * e_rho[: f_l + 1, p_b + 1 :].sum(axis=1)) + a_l.max() * outside)
    res_f = float(lam2[f_b + 1] * eps_l * lighting.total_energy * eps_rho * rho_tot)
    res = res_p + res_f
    eps_b = res / (captured + res) if captured + res > 0.0 else 0.0
    eps_min = min(eps_l, eps_rho)
    return {
        "epsilon_brdf": eps_rho,
        "epsilon_lighting": eps_l,
        "epsilon_min_of_errors": eps_min,
        "epsilon_appendix_b": eps_b,
        "rms_brdf": rms_from_energy(eps_rho),
        "rms_min_of_errors": rms_from_energy(eps_min),
        "rms_appendix_b": rms_from_energy(eps_b),
    }


#: Largest coefficient-map set create_shrm builds (float64, before any file is written).
MAX_SHRM_BYTES = order_search.MAX_SHRM_BYTES


#: The view spectrum of an SHRM reaches at least this order (or the map's H - 1): the prediction then reads the
#: bands l > F_B from the lobe itself rather than from App. B's step (``relight.shrm.view_bands``); 96 costs
#: about 0.3 s for a general lobe at P = 16.
SPECTRUM_MIN_ORDER = 96


def spectrum_order(f_order: int, f_cap: int) -> int:
    """Order of the view spectrum tabulated for an SHRM at F: F plus half again (at least 16 more), and at least
    ``min(H - 1, SPECTRUM_MIN_ORDER)``."""
    return max(f_order + max(16, f_order // 2), min(f_cap, SPECTRUM_MIN_ORDER))


def create_shrm(
    pixels: NDArray[np.floating],
    brdf: Any,
    *,
    epsilon: float | None = None,
    order: int | None = None,
    p_order: int | None = None,
    size: int | None = None,
    backend: Backend = "ducc0",
    grazing_limit: float | None = None,
) -> SHRM:
    """Prefilter a lat-long environment map (H, W, 3) into an SHRM (seed 000 Fig. 3, App. C).

    Per lobe: orders (F_rho, P_rho) from ``epsilon`` (default 0.01) held in every view band with N.V >=
    ``grazing_limit`` (default ``relight.settings.SETTINGS.grazing_limit``, 0.1; ``relight.shrm.order_search``),
    or the explicit ``order`` F and ``p_order`` P (P from the default tolerance when only F is given); the lobe's
    view spectrum gives the coefficients ``rho_hat_lpq`` (``relight.shrm.view_spectrum``); lighting coefficients by
    pixel quadrature once, to the largest order needed; ``F_B = min(F_rho, F_L, H - 1)`` (minimum-of-orders rule,
    §5.1), ``P_B = P_rho``; ``B_lmpq = L_lm rho_hat_lpq`` (eq. 5, App. A) synthesised into the local maps (App. C
    step 3). ``size`` is the output rows S (default S ~ 10 max F_B, §5.2). The report says, per component, which
    structure and why, the orders, the predicted errors overall and per view band (``predicted.by_view``,
    ``relight.shrm.view_bands``) and timings.
    """
    if epsilon is not None and (order is not None or p_order is not None):
        raise InputError("give either epsilon or explicit orders, not both")
    if epsilon is None and order is None:
        epsilon = DEFAULT_EPSILON
    if epsilon is not None:
        epsilon = validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    if order is not None:
        order = validate.at_least("order F", order, 0)
    if p_order is not None:
        p_order = validate.at_least("order P", p_order, 0)
    if size is not None:
        size = validate.at_least("size", size, 2)
    limit = SETTINGS.grazing_limit if grazing_limit is None else grazing_limit
    limit = validate.in_range("grazing_limit", limit, 0.0, 1.0, hi_open=True)
    pixels = require_rgb_latlong(pixels)
    h, w = pixels.shape[:2]
    lobes = brdf_lobes(brdf)
    f_cap = h - 1
    edges = band_edges(limit)
    timer = Timer()

    chosen: list[tuple[Lobe, ViewSpectrum, int, int, dict[str, Any]]] = []
    achievable: dict[int, tuple[float, ...]] = {}
    for lobe in lobes:
        structure = structure_of(lobe)[0]
        if order is not None:
            if lobe.radially_symmetric:
                p = 0
            elif p_order is not None:
                p = p_order
            else:  # F alone: P from the default tolerance (the view-band search)
                p = order_search.cached_search(lobe, DEFAULT_EPSILON, grazing_limit=limit, structure=structure)[0].P
            f_req = min(order, f_cap)  # orders above the map's resolution are never used (F_B <= H - 1)
            spec = order_search.cached_spectrum(lobe, spectrum_order(f_req, f_cap), p, edges)
            sel: dict[str, Any] = {"F_rho": f_req, "P_rho": p, "explicit": True, "grazing_limit": limit}
            chosen.append((lobe, spec, f_req, p, sel))
        else:
            assert epsilon is not None
            res, cached = order_search.cached_search(lobe, epsilon, grazing_limit=limit, structure=structure,
                                                     size=size)
            sel = {**res.as_dict(), "cached": cached}
            achievable[len(chosen)] = res.achievable
            spec = res.spectrum
            if spec.F < res.F or spec.P < res.P:  # beyond the search's tabulation: tabulate at the orders found
                spec = order_search.cached_spectrum(lobe, res.F, res.P, edges)
            chosen.append((lobe, spec, res.F, res.P, sel))
    timer.lap("brdf_coefficients")

    # The prediction reads the lobe and the lighting to spectrum_order(F) (at least min(H - 1, 96)), so the bands
    # beyond F_B come from both spectra rather than from App. B's step (which puts all the lighting beyond the
    # tabulated order at one band: 3-18 times too much on city's lamps, docs/accuracy/grazing.md).
    pred_specs = [order_search.cached_spectrum(lobe, spectrum_order(f, f_cap), p, edges)
                  if sp.F < spectrum_order(f, f_cap) else sp for lobe, sp, f, p, _ in chosen]
    f_proj = min(max(max(f, sp.F, ps.F) for (_, sp, f, _, _), ps in zip(chosen, pred_specs, strict=True)), f_cap)
    lighting = project_lighting(pixels, f_proj)
    timer.lap("lighting_projection")
    f_l = None
    if epsilon is not None:
        f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, epsilon)
    timer.lap("order_selection")

    plans = []
    for lobe, spec, f_rho, p_rho, sel in chosen:
        f_b = min(f_rho, f_cap) if order is not None else min(f_rho, f_cap, f_l if f_l is not None else f_rho)
        structure, reason = structure_of(lobe)
        p_b = 0 if structure == "radial" else p_rho
        plans.append((lobe, spec, f_b, p_b, structure, reason, sel))
    s = size if size is not None else size_for_order(max(f for _, _, f, _, _, _, _ in plans))
    # Refuse plans whose coefficient maps cannot fit in memory (a sharp lobe at a tight tolerance can ask for
    # hundreds of S x 2S float64 maps): a clear error instead of an out-of-memory crash.
    n_maps = sum(len(terms_for(structure, p_b)) for _, _, _, p_b, structure, _, _ in plans)
    need = n_maps * s * 2 * s * 3 * 8
    if need > MAX_SHRM_BYTES:
        raise InputError(
            f"this SHRM needs {n_maps} maps of {s} x {2 * s} ({need / 2**30:.1f} GiB, limit "
            f"{MAX_SHRM_BYTES / 2**30:.0f} GiB): loosen epsilon, or give explicit orders and a smaller size"
        )

    components = []
    for k, (lobe, spec, f_b, p_b, structure, reason, sel) in enumerate(plans):
        coeffs = spec.coefficients()
        rho = coeffs.rho[: f_b + 1, : p_b + 1, : min(coeffs.Q, p_b) + 1]
        terms = terms_for(structure, p_b)
        maps = synthesize_local(lighting.alm, lighting.lmax, rho, terms, s, backend=backend)
        views = view_prediction(pred_specs[k], lighting, f_b, p_b, epsilon=epsilon, grazing_limit=limit,
                                achievable=achievable.get(k))
        predicted = ShrmPredicted(**predicted_errors(coeffs, lighting, f_b, p_b), grazing_limit=limit,
                                  by_view=views.by_view, by_view_fine=views.by_view_fine)
        comp_report = ShrmComponentReport(
            center=str(lobe.center),
            structure=structure,
            reason=reason,
            lobe=lobe.spec(),
            orders={"F_B": f_b, "P_B": p_b, "F_L": f_l, **{k: v for k, v in sel.items() if k != "probes"}},
            probes=list(sel.get("probes", [])),
            n_maps=len(terms),
            predicted=predicted,
            brdf_energy=float(coeffs.total_energy.max()),
        )
        components.append(
            SHRMComponent(
                center=str(lobe.center), structure=structure, F=f_b, P=p_b, terms=terms, maps=maps,
                lobe=lobe.spec(), report=comp_report,
            )
        )
    timer.lap("synthesis")

    reports = [c.report for c in components]
    assert all(isinstance(r, ShrmComponentReport) for r in reports)
    typed = [r for r in reports if isinstance(r, ShrmComponentReport)]
    worst = max(typed, key=lambda r: r.predicted.epsilon_brdf or 0.0)
    report = ShrmReport(
        brdf=_spec(brdf),
        epsilon=epsilon,
        order_requested=None if order is None else [order, p_order],
        grazing_limit=limit,
        components=typed,
        predicted=worst.predicted,
        input={"height": h, "width": w},
        output={"height": s, "width": 2 * s, "layout": "latlong", "maps": sum(len(c.terms) for c in components)},
        timings=dict(timer.seconds),
        total_seconds=float(sum(timer.seconds.values())),
        backend=backend,
        relight_version=__version__,
    )
    return SHRM(components=components, brdf=report.brdf, report=report)
