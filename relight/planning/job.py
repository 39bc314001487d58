"""Planning one prefilter job before computing it: representation, orders, predicted error, output shape and
predicted seconds (seed 000 §3.1, §4, §5.1, App. B, App. C; ``POST /plan``).

Cheap by construction: it uses the lighting's SH power spectrum stored at upload time (``sh_power_spectrum``,
``total_energy``) and the BRDF's spectrum, and follows the same order rules as the core:

* radially symmetric lobe -> one reflection map (``relight.prefilter.prefilter_radial``): F_rho from
  ``spectrum_for_tolerance``, ``F_B = min(F_rho, F_L, H - 1)`` (seed 000 §5.1), App. B bound as in
  ``relight.prefilter.choose_orders`` but from the stored band energies;
* otherwise an SHRM (``relight.shrm.create_shrm``): per lobe the view-band order search
  (``relight.shrm.order_search``, the tolerance held down to the grazing limit) and ``relight.shrm.predicted_errors``
  with ``predicted.by_view`` (``relight.shrm.view_bands``; issue 18).

Seconds: the calibrated cost model (``relight.costmodel``; never calibrating here: without a cached calibration the
built-in constants, ``cost_model.calibrated = False``) for the computation, plus decoding the input and writing the
result (:data:`T_FIXED`, :data:`T_DECODE_PIXEL`, :data:`T_WRITE_PIXEL`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import costmodel
from relight.jsonable import jsonable
from relight.reports import OMIT_NONE, Orders, PredictedError, Report

#: I/O terms of a job, measured on the 2-core development machine with city.exr (1024 x 512, DWAB;
#: ``bench/service.py`` prints the prediction next to the measurement): a fixed cost, decoding per input pixel and
#: writing per output pixel and layer (EXR + the viewer's float16 texture).
T_FIXED = 0.004
T_DECODE_PIXEL = 2.6e-8
T_WRITE_PIXEL = 5.0e-8
#: Zip on float32 layers saves about 20 % (the output's EXR size estimate).
EXR_ZIP_RATIO = 0.8


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


@dataclass(frozen=True, kw_only=True)
class ComponentPlan(Report):
    """One lobe of a planned SHRM."""

    kind: str
    center: str
    structure: str
    reason: str
    F_rho: int
    F_B: int
    P_B: int
    maps: int
    predicted: dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class OutputShape(Report):
    """The job's output: ``height x width`` maps, ``layers`` of them, and their sizes in bytes (float16 texture;
    EXR estimated)."""

    height: int
    width: int
    layers: int
    bin_bytes: int
    exr_bytes_estimate: int


@dataclass(frozen=True, kw_only=True)
class JobCostModel(Report):
    """The cost model behind ``predicted_seconds``: whether it is calibrated on this machine, which calibration, the
    computation's and the I/O's seconds and the computation per stage."""

    calibrated: bool
    key: str
    created: str
    compute_seconds: float
    io_seconds: float
    stages: dict[str, float]


@dataclass(frozen=True, kw_only=True)
class JobPlan(Report):
    """A planned job (module docstring). ``components`` lists (F_B, maps) per lobe; ``component_plans`` (SHRMs only)
    the lobes in full."""

    representation: str
    reason: str
    orders: Orders
    predicted_error: PredictedError
    size: int
    components: list[tuple[int, int]]
    component_plans: list[ComponentPlan] | None = field(default=None, metadata=OMIT_NONE)
    output: OutputShape
    predicted_seconds: float
    cost_model: JobCostModel
    #: ``sun=extract`` with a tolerance: the sun's report and per lobe the order with and without it
    #: (``relight.planning.sun_orders``).
    sun: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)

    def to_json(self) -> dict[str, Any]:
        """Plain JSON (non-finite numbers as None, ``relight.jsonable``)."""
        out: dict[str, Any] = jsonable(super().to_json())
        return out


def uses_reflection_map(brdf: Any, params: Mapping[str, Any]) -> bool:
    """The dispatch rule: one radially symmetric lobe (and no view order asked for) is a plain reflection map
    (``prefilter_radial``); everything else, sums of lobes included, is an SHRM (``create_shrm``)."""
    from relight.brdf.base import RadialLobe

    return isinstance(brdf, RadialLobe) and not params.get("p_order")


def _errors(d: Mapping[str, Any], by_view: Any = None, grazing_limit: float | None = None) -> PredictedError:
    return PredictedError(**{k: d.get(k) for k in (
        "epsilon_lighting", "epsilon_brdf", "epsilon_min_of_errors", "rms_min_of_errors", "epsilon_appendix_b",
        "rms_appendix_b")}, by_view=by_view, grazing_limit=grazing_limit)


@dataclass(frozen=True)
class _Planned:
    representation: str
    reason: str
    orders: Orders
    predicted_error: PredictedError
    size: int
    components: list[tuple[int, int]]
    component_plans: list[ComponentPlan] | None
    features: dict[str, float]


def _radial(lobe: Any, lighting: StoredLighting, h: int, w: int, params: Mapping[str, Any]) -> _Planned:
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
    size = int(params.get("size") or size_for_order(f_b))
    from relight.shrm.view_bands import radial_by_view

    by_view = radial_by_view(lobe, lighting, f_b)
    feats = costmodel.radial_features(lobe, height=h, width=w, f_rho=f_rho, f_proj=min(f_rho, h - 1), f_b=f_b,
                                      size=size, explicit=eps is None)
    return _Planned(
        representation="reflection_map",
        reason=f"{lobe.kind or type(lobe).__name__} is radially symmetric about {lobe.center}: one 2-D "
               "reflection map (P = 0, seed 000 §3.1)",
        orders=Orders(F_L=f_l, F_rho=f_rho, F_B=f_b, P_B=0),
        predicted_error=PredictedError(
            epsilon_lighting=eps_l, epsilon_brdf=eps_rho, epsilon_min_of_errors=eps_min,
            rms_min_of_errors=rms_from_energy(eps_min), epsilon_appendix_b=eps_b,
            rms_appendix_b=rms_from_energy(eps_b), by_view=by_view,
        ),
        size=size, components=[(f_b, 1)], component_plans=None, features=feats,
    )


def _shrm(lobe_or_sum: Any, lighting: StoredLighting, h: int, w: int, params: Mapping[str, Any]) -> _Planned:
    from relight.orders import order_for_tolerance
    from relight.prefilter import size_for_order
    from relight.settings import SETTINGS
    from relight.shrm import brdf_lobes, order_search, predicted_errors, structure_of, terms_for
    from relight.shrm.creation import spectrum_order
    from relight.shrm.view_bands import view_prediction
    from relight.shrm.view_spectrum import band_edges

    eps, order, p_order = params.get("epsilon"), params.get("order"), params.get("p_order")
    if eps is None and order is None:
        raise ValueError("planning needs epsilon or order")
    limit = float(params.get("grazing_limit") or SETTINGS.grazing_limit)
    edges = band_edges(limit)
    f_cap = h - 1
    f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, eps) if eps is not None else None
    comps: list[ComponentPlan] = []
    views: list[Any] = []
    lobe_plans: list[costmodel.LobePlan] = []
    for lobe in brdf_lobes(lobe_or_sum):
        probes = None
        structure, reason = structure_of(lobe)
        if order is not None:
            p = 0 if lobe.radially_symmetric else (p_order if p_order is not None else 0)
            spec = order_search.cached_spectrum(lobe, spectrum_order(int(order), f_cap), int(p), edges)
            f_rho, p_rho = int(order), int(p)
            f_b = min(f_rho, f_cap)
            search: dict[str, Any] = {}
            achievable = None
        else:
            assert eps is not None  # checked above: one of epsilon, order
            sel, _ = order_search.cached_search(lobe, float(eps), grazing_limit=limit, structure=structure,
                                                size=params.get("size"))
            spec, f_rho, p_rho = sel.spectrum, sel.F, sel.P
            f_b = min(f_rho, f_cap, f_l if f_l is not None else f_rho)
            search = {k: v for k, v in sel.as_dict().items() if k in (
                "tolerance_met", "grazing_limit", "extrapolated", "unmet_bands", "achievable_by_view")}
            achievable = sel.achievable
            if not lobe.radially_symmetric:  # the (F, P) the search tabulated, priced by the cost model
                probes = tuple((int(q["F"]), int(q["P"])) for q in sel.probes)
        p_b = 0 if structure == "radial" else p_rho
        f_pred = min(f_b, spec.F)  # beyond the search's tabulation (step 2 of order_search) the plan reads its F0
        errs = predicted_errors(spec.coefficients(), lighting, f_pred, p_b)  # type: ignore[arg-type]
        # per view band as create_shrm predicts: the lobe read to spectrum_order(F_B), not App. B's step beyond F0
        view_spec = (order_search.cached_spectrum(lobe, spectrum_order(f_b, f_cap), p_b, edges)
                     if spec.F < spectrum_order(f_b, f_cap) else spec)
        vp = view_prediction(view_spec, lighting, min(f_b, view_spec.F), p_b, epsilon=eps, grazing_limit=limit,
                             achievable=achievable)
        bands, fine = vp.by_view, vp.by_view_fine
        views.append(bands)
        comps.append(ComponentPlan(kind=lobe.kind, center=str(lobe.center), structure=structure, reason=reason,
                                   F_rho=f_rho, F_B=f_b, P_B=p_b, maps=len(terms_for(structure, p_b)),
                                   predicted={**errs, **search, "grazing_limit": limit,
                                              "extrapolated_prediction": f_pred < f_b,
                                              "by_view": [b.to_json() for b in bands],
                                              "by_view_fine": [b.to_json() for b in fine]}))
        lobe_plans.append(costmodel.LobePlan(lobe=lobe, structure=structure, f_rho=f_rho, f_b=f_b, p_b=p_b,
                                             explicit=eps is None, probes=probes))
    k_worst = max(range(len(comps)), key=lambda k: comps[k].predicted["epsilon_brdf"])
    worst = comps[k_worst]
    size = int(params.get("size") or size_for_order(max(c.F_B for c in comps)))
    reasons = "; ".join(f"{c.kind} ({c.center}-centred): {c.reason}" for c in comps)
    f_proj = min(max(p.f_rho for p in lobe_plans), h - 1)
    return _Planned(
        representation="shrm",
        reason=f"view-dependent BRDF, so an SHRM (seed 000 §4): {reasons}",
        orders=Orders(F_L=f_l, F_rho=worst.F_rho, F_B=max(c.F_B for c in comps), P_B=max(c.P_B for c in comps)),
        predicted_error=_errors(worst.predicted, views[k_worst], limit),
        size=size, components=[(c.F_B, c.maps) for c in comps], component_plans=comps,
        features=costmodel.shrm_features(lobe_plans, height=h, width=w, f_proj=f_proj, size=size),
    )


def plan_job(info: Mapping[str, Any], brdf_spec: Any, params: Mapping[str, Any], *,
             calibration: costmodel.Calibration | None = None) -> JobPlan:
    """Plan a job for an uploaded map (its stored ``info``: ``height``, ``width``, ``sh_power_spectrum``,
    ``total_energy``), a BRDF spec in the core's form and canonical parameters (``epsilon``, ``order``,
    ``p_order``, ``size``). ``calibration`` defaults to this machine's cached one, else the built-in constants."""
    from relight.brdf.spec import parse_brdf

    lobe = parse_brdf(brdf_spec)
    h, w = int(info["height"]), int(info["width"])
    lighting = StoredLighting(np.asarray(info["sh_power_spectrum"], dtype=np.float64), float(info["total_energy"]))
    planned = (_radial if uses_reflection_map(lobe, params) else _shrm)(lobe, lighting, h, w, params)
    size = planned.size
    n_maps = sum(n for _, n in planned.components)
    cal = calibration if calibration is not None else costmodel.load_calibration(run=False)
    pred = cal.predict(planned.features)
    io = T_FIXED + T_DECODE_PIXEL * h * w + T_WRITE_PIXEL * size * 2 * size * n_maps
    return JobPlan(
        representation=planned.representation, reason=planned.reason, orders=planned.orders,
        predicted_error=planned.predicted_error, size=size, components=planned.components,
        component_plans=planned.component_plans,
        output=OutputShape(height=size, width=2 * size, layers=n_maps, bin_bytes=n_maps * size * 2 * size * 3 * 2,
                           exr_bytes_estimate=int(n_maps * size * 2 * size * 3 * 4 * EXR_ZIP_RATIO)),
        predicted_seconds=pred.seconds + io,
        cost_model=JobCostModel(calibrated=cal.calibrated, key=cal.key, created=cal.created,
                                compute_seconds=pred.seconds, io_seconds=io, stages=pred.stages),
    )
