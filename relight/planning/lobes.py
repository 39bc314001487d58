"""Per-lobe planning: which representation a lobe needs and its orders at a tolerance (seed 000 §3.1, §4, §5.1,
§5.2, §7.1, App. B, App. C).

* **Lambertian** lobe -> irradiance coefficients only: F = 2 (9 coefficients, seed 000 §5.2 footnote 1) whenever
  ``epsilon >= 1/128``, the clamped cosine's energy beyond l = 2; a stricter tolerance raises F (4, 6, ...);
* other **radially symmetric** lobe (Phong, tabulated 1-D lobes) -> a 2-D reflection map (P = 0, §3.1);
* lobe **without azimuthal dependence** (Kajiya–Kay) -> q = 0 terms only, P + 1 maps (§7.1, §7.3);
* **general** isotropic lobe -> the full ``(P + 1)^2``-map SHRM (§4).

Orders follow the core exactly: ``spectrum_for_tolerance`` and ``relight.prefilter.choose_orders`` for radial lobes
(as ``prefilter_radial``), the view-band order search of ``create_shrm`` and ``plan_job`` for the others
(``relight.shrm.order_search.cached_search``, the tolerance held in every view band with N.V >= the grazing limit;
about a second per material, cached; App. C's whole-lobe search took minutes for a Torrance–Sparrow lobe, issue 16)
and ``relight.shrm.predicted_errors`` on the search's spectrum, with ``F_B = min(F_rho, F_L, H - 1)``
(minimum-of-orders rule, §5.1).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from relight.brdf.base import Lobe, RadialLobe


def representation_of(lobe: Lobe) -> tuple[str, str, str]:
    """(representation, SHRM structure, reason) of a lobe (module docstring)."""
    from relight.brdf.radial import Lambert

    if isinstance(lobe, Lambert):
        return ("irradiance", "radial", "Lambertian lobe: irradiance coefficients only, centred on N (seed 000 §5.2, "
                "footnote 1: F = 2, 9 coefficients)")
    if lobe.radially_symmetric:
        return ("reflection_map", "radial", f"radially symmetric lobe about {lobe.center}: one 2-D reflection map "
                "(P = 0, §3.1)")
    if lobe.azimuthally_symmetric:
        return ("shrm_q0", "azimuthal", "no azimuthal dependence: q = 0 terms only, P + 1 maps (§7.1)")
    return ("shrm", "general", "general isotropic lobe: (P + 1)^2 maps B_pq (§4)")


def lobe_key(lobe: Lobe) -> str:
    """Identity of a lobe (its class and spec): identical lobes are planned and computed once."""
    return json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)


@dataclass
class LobeChoice:
    """Orders of one lobe at one tolerance."""

    lobe: Lobe
    representation: str
    structure: str
    reason: str
    f_rho: int
    p_rho: int
    eps_rho: float  # the lobe's uncaptured energy at (F_rho, P_rho) (SHRM lobes: the worst enforced view band)
    eps_rho_below: dict[str, float]  # at F_rho - 1 (and P_rho - 1)
    probes: tuple[tuple[int, int], ...] | None
    coefficients: Any  # lpq.BRDFCoefficients (SHRM lobes: the search's tabulation) or RadialSpectrum
    edges: tuple[float, ...] | None = None  # the view bands of the search (SHRM lobes)
    search: dict[str, Any] | None = None  # the search's verdict (SHRM lobes: tolerance met, unmet bands, ...)

    def coefficients_to(self, f_order: int, p_order: int) -> Any:
        """SHRM coefficients covering (F, P): the search's own tabulation, or, when the search extrapolated beyond
        it (``order_search`` step 2), the lobe's view spectrum at the orders found, as ``create_shrm`` does."""
        from relight.shrm import order_search

        c = self.coefficients
        if c.F >= f_order and c.P >= p_order:
            return c
        assert self.edges is not None
        return order_search.cached_spectrum(self.lobe, max(self.f_rho, f_order), max(self.p_rho, p_order),
                                            self.edges).coefficients()


def choose(lobe: Lobe, epsilon: float) -> LobeChoice:
    """Smallest orders meeting ``epsilon`` for one lobe: ``spectrum_for_tolerance`` for radial lobes (as
    ``prefilter_radial``), the view-band search of ``create_shrm`` (``order_search.cached_search``) otherwise."""
    from relight.brdf.coefficients import spectrum_for_tolerance
    from relight.settings import SETTINGS
    from relight.shrm import order_search

    representation, structure, reason = representation_of(lobe)
    if isinstance(lobe, RadialLobe):
        spec, f_rho = spectrum_for_tolerance(lobe, epsilon)
        eps = spec.epsilon()
        below = {"F_rho_minus_1": float(eps[f_rho - 1]) if f_rho > 0 else 1.0}
        return LobeChoice(lobe, representation, structure, reason, f_rho, 0, float(eps[min(f_rho, spec.lmax)]),
                          below, None, spec)
    res, _ = order_search.cached_search(lobe, epsilon, grazing_limit=SETTINGS.grazing_limit, structure=structure)
    p_rho = 0 if structure == "radial" else res.P
    below = {"F_rho_minus_1": order_search.enforced_epsilon(res, res.F - 1, res.P),
             "P_rho_minus_1": order_search.enforced_epsilon(res, res.F, res.P - 1)}
    probes = tuple((int(q["F"]), int(q["P"])) for q in res.probes)
    return LobeChoice(lobe, representation, structure, reason, res.F, p_rho,
                      order_search.enforced_epsilon(res, res.F, res.P), below, probes,
                      res.spectrum.coefficients(), res.edges,
                      {k: v for k, v in res.as_dict().items() if k in (
                          "tolerance_met", "grazing_limit", "unmet_bands", "achievable_by_view")})


def predicted_radial(choice: LobeChoice, lighting: Any, epsilon: float, f_cap: int) -> tuple[int, int | None, dict[
        str, float]]:
    """F_B, F_L and predicted errors of a radial lobe, exactly as ``prefilter_radial`` (§5.1, App. B)."""
    from relight.brdf.coefficients import radial_transfer
    from relight.prefilter import choose_orders

    spec = choice.coefficients
    f_proj = min(choice.f_rho, f_cap)
    assert isinstance(choice.lobe, RadialLobe)
    transfer = spec.transfer if spec.transfer.shape[0] > f_proj else radial_transfer(choice.lobe, f_proj).transfer
    oc = choose_orders(spec, lighting, epsilon, None, choice.f_rho, f_cap, transfer)
    pred = {k: float(v) for k, v in oc.report().predicted().to_json().items() if v is not None}
    return oc.F_B, oc.F_L, pred


def predicted_shrm(choice: LobeChoice, lighting: Any, epsilon: float, f_cap: int) -> tuple[int, int | None, dict[
        str, float]]:
    """F_B, F_L and predicted errors of an SHRM lobe, exactly as ``create_shrm`` (§5.1, App. B generalised)."""
    from relight.orders import order_for_tolerance
    from relight.shrm import predicted_errors

    f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, epsilon)
    f_b = min(choice.f_rho, f_cap, f_l if f_l is not None else choice.f_rho)
    # beyond the search's tabulation (order_search step 2) the prediction reads its F0, as plan_job does
    coeffs = choice.coefficients
    return f_b, f_l, predicted_errors(coeffs, lighting, min(f_b, coeffs.F), choice.p_rho)
