"""Job planning without computing: orders, predicted error, representation and a time estimate.

Cheap by construction: it uses the lighting's SH power spectrum stored at upload time (``sh_power_spectrum``,
``total_energy``) and the BRDF's spectrum, and follows the same order rules as the core:

* radially symmetric lobe -> one reflection map (``relight.prefilter.prefilter_radial``): F_rho from
  ``spectrum_for_tolerance``, ``F_B = min(F_rho, F_L, H - 1)`` (seed 000 §5.1), App. B bound as in
  ``relight.prefilter.choose_orders`` but from the stored band energies;
* otherwise an SHRM (``relight.shrm.create_shrm``): per lobe ``lpq.cached_select_orders`` and
  ``relight.shrm.predicted_errors``.

The time model is deliberately simple (see :func:`predict_seconds`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Time model constants, measured on the 2-core development machine with city.exr (1024 x 512, DWAB) and
#: Phong lobes at F = 12 ... 100 (bench/service.py prints the prediction next to the measurement). Per channel
#: sample: projection (quadrature over the input pixels), synthesis (per output pixel, larger outputs cost more
#: per pixel), the Legendre part per (ring x l^2); decoding the input and writing the results per pixel.
T_FIXED = 0.004
T_PIXEL_FFT = 6.0e-9
T_SYNTH_PIXEL = 1.0e-8
T_RING_L2 = 5.0e-11
T_DECODE_PIXEL = 2.6e-8
T_WRITE_PIXEL = 5.0e-8


@dataclass(frozen=True)
class StoredLighting:
    """The lighting spectrum saved at upload, with the interface order selection reads
    (``lmax``, ``total_energy``, ``band_energy()``; cf. ``relight.prefilter.LightingSpectrum``)."""

    energies: NDArray[np.float64]
    total_energy: float

    @property
    def lmax(self) -> int:
        return int(self.energies.shape[0] - 1)

    def band_energy(self) -> NDArray[np.float64]:
        return self.energies


def predict_seconds(height: int, width: int, size: int, components: list[tuple[int, int]]) -> float:
    """Seconds for one job: decode the input, project the lighting to max F, synthesise every map, write.

    ``components`` lists (F_B, number of maps) per lobe. Transform cost ~ rings x (W log-ish + F^2) per channel
    (FACTS.md: 6 ms at L = 32, 25 ms at L = 511 on 512 x 1024 x 3).
    """
    f_max = max((f for f, _ in components), default=0)
    in_px = height * width
    out_px = size * 2 * size
    t = T_FIXED + T_DECODE_PIXEL * in_px
    t += 3 * (T_PIXEL_FFT * in_px + T_RING_L2 * height * (f_max + 1) ** 2)
    for f_b, n_maps in components:
        t += n_maps * 3 * (T_SYNTH_PIXEL * out_px + T_RING_L2 * size * (f_b + 1) ** 2)
    n_total = sum(n for _, n in components)
    t += T_WRITE_PIXEL * out_px * n_total
    return float(t)


def _radial(lobe: Any, lighting: StoredLighting, h: int, params: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.coefficients import lambda_l, radial_transfer, spectrum_for_tolerance
    from relight.orders import appendix_b_bound, order_for_tolerance, rms_from_energy, uncaptured
    from relight.prefilter import size_for_order

    eps, order = params.get("epsilon"), params.get("order")
    f_cap = h - 1
    if order is not None:
        spectrum, f_rho = radial_transfer(lobe, order), int(order)
    elif eps is not None:
        spectrum, f_rho = spectrum_for_tolerance(lobe, float(eps))
    else:
        raise ValueError("planning needs epsilon or order")
    e_light = lighting.band_energy()
    f_l = order_for_tolerance(e_light, lighting.total_energy, eps) if eps is not None else None
    f_b = min(order, f_cap) if order is not None else min(f_rho, f_cap, f_l if f_l is not None else f_rho)
    transfer = spectrum.transfer if spectrum.lmax >= f_b + 1 else radial_transfer(lobe, f_b + 1).transfer
    eps_rho = float(spectrum.epsilon()[min(f_b, spectrum.lmax)])
    k = min(f_b, lighting.lmax)
    eps_l = float(uncaptured(e_light, lighting.total_energy)[k])
    captured = float(np.sum(e_light[: k + 1] * np.mean(transfer[: k + 1] ** 2, axis=1)))
    eps_b = appendix_b_bound(
        lambda_next=float(lambda_l(f_b + 1)[-1]), eps_lighting=eps_l, lighting_total=lighting.total_energy,
        eps_brdf=eps_rho, brdf_total=float(np.max(spectrum.total_energy)), captured_output_energy=captured,
    )
    eps_min = min(eps_l, eps_rho)
    size = params.get("size") or size_for_order(f_b)
    return {
        "representation": "reflection_map",
        "reason": f"{lobe.kind or type(lobe).__name__} is radially symmetric about {lobe.center}: one 2-D "
                  "reflection map (P = 0, seed 000 §3.1)",
        "orders": {"F_L": f_l, "F_rho": f_rho, "F_B": f_b, "P_B": 0},
        "predicted_error": {
            "epsilon_lighting": eps_l, "epsilon_brdf": eps_rho, "epsilon_min_of_errors": eps_min,
            "rms_min_of_errors": rms_from_energy(eps_min), "epsilon_appendix_b": eps_b,
            "rms_appendix_b": rms_from_energy(eps_b),
        },
        "size": int(size),
        "components": [(f_b, 1)],
    }


def _shrm(lobe_or_sum: Any, lighting: StoredLighting, h: int, params: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf import lpq
    from relight.orders import order_for_tolerance
    from relight.prefilter import size_for_order
    from relight.shrm import brdf_lobes, predicted_errors, structure_of, terms_for

    eps, order, p_order = params.get("epsilon"), params.get("order"), params.get("p_order")
    if eps is None and order is None:
        raise ValueError("planning needs epsilon or order")
    f_cap = h - 1
    f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, eps) if eps is not None else None
    comps: list[dict[str, Any]] = []
    for lobe in brdf_lobes(lobe_or_sum):
        if order is not None:
            p = 0 if lobe.radially_symmetric else (p_order if p_order is not None else 0)
            coeffs, _ = lpq.cached_coefficients(lobe, order, p)
            f_rho, p_rho = int(order), int(p)
            f_b = min(f_rho, f_cap)
        else:
            assert eps is not None  # checked above: one of epsilon, order
            sel, _ = lpq.cached_select_orders(lobe, float(eps))
            coeffs, f_rho, p_rho = sel.coefficients, sel.F, sel.P
            f_b = min(f_rho, f_cap, f_l if f_l is not None else f_rho)
        structure, reason = structure_of(lobe)
        p_b = 0 if structure == "radial" else p_rho
        errs = predicted_errors(coeffs, lighting, f_b, p_b)  # type: ignore[arg-type]  # duck-typed spectrum
        comps.append({"kind": lobe.kind, "center": lobe.center, "structure": structure, "reason": reason,
                      "F_rho": f_rho, "F_B": f_b, "P_B": p_b, "maps": len(terms_for(structure, p_b)),
                      "predicted": errs})
    worst = max(comps, key=lambda c: c["predicted"]["epsilon_brdf"])
    size = params.get("size") or size_for_order(max(c["F_B"] for c in comps))
    reasons = "; ".join(f"{c['kind']} ({c['center']}-centred): {c['reason']}" for c in comps)
    return {
        "representation": "shrm",
        "reason": f"view-dependent BRDF, so an SHRM (seed 000 §4): {reasons}",
        "orders": {"F_L": f_l, "F_rho": worst["F_rho"], "F_B": max(c["F_B"] for c in comps),
                   "P_B": max(c["P_B"] for c in comps)},
        "predicted_error": {k: worst["predicted"].get(k) for k in (
            "epsilon_lighting", "epsilon_brdf", "epsilon_min_of_errors", "rms_min_of_errors",
            "epsilon_appendix_b", "rms_appendix_b")},
        "size": int(size),
        "components": [(c["F_B"], c["maps"]) for c in comps],
        "component_plans": comps,
    }


def plan_job(info: dict[str, Any], brdf_spec: dict[str, Any], params: dict[str, Any]) -> dict[str, Any]:
    """Plan a job for an uploaded map (its stored ``info``), a BRDF spec in the core's form
    (``relight.worker.specs.to_core``) and canonical parameters.

    Returns representation and reason, orders, predicted error, output size and predicted seconds.
    """
    from relight.brdf.spec import parse_brdf

    lobe = parse_brdf(brdf_spec)
    h, w = int(info["height"]), int(info["width"])
    lighting = StoredLighting(np.asarray(info["sh_power_spectrum"], dtype=np.float64), float(info["total_energy"]))
    from relight.worker.tasks import uses_reflection_map

    if uses_reflection_map(lobe, params):
        plan = _radial(lobe, lighting, h, params)
    else:
        plan = _shrm(lobe, lighting, h, params)
    size = plan["size"]
    n_maps = sum(n for _, n in plan["components"])
    plan["output"] = {
        "height": size, "width": 2 * size, "layers": n_maps,
        "bin_bytes": n_maps * size * 2 * size * 3 * 2,
        "exr_bytes_estimate": int(n_maps * size * 2 * size * 3 * 4 * 0.8),  # zip on float32 saves ~20 %
    }
    plan["predicted_seconds"] = predict_seconds(h, w, size, plan["components"])
    out: dict[str, Any] = _finite(plan)
    return out


def _finite(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return _finite(obj.item())
    return obj
