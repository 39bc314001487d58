"""The points of an accuracy-time sweep (seed 000 §5.1, §6.2 Table 3, App. D): one run of the frequency method at
a tolerance or of the angular method at a truncation, timed and measured against the reference
(:func:`relight.tradeoff.sweep`), as a typed report whose JSON is one entry of ``tradeoff.json``."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import costmodel
from relight.brdf.base import RadialLobe
from relight.metrics import relative_rms
from relight.tradeoff.report import TradeoffPoint

FloatArray = NDArray[np.float64]


def is_reflection_map(brdf: Any) -> bool:
    """One radially symmetric lobe: a plain reflection map, view independent (§3.1)."""
    return isinstance(brdf, RadialLobe)


def pareto_flags(errors: Sequence[float], seconds: Sequence[float]) -> list[bool]:
    """True for each point that no other point beats in both error and time (ties in both keep both)."""
    e = np.asarray(errors, dtype=np.float64)
    t = np.asarray(seconds, dtype=np.float64)
    out = []
    for i in range(e.size):
        dominated = (e <= e[i]) & (t <= t[i]) & ((e < e[i]) | (t < t[i]))
        out.append(not bool(dominated.any()))
    return out


#: Runs faster than this are repeated (best of :data:`REPEAT`): the machines are noisy (docs/facts.md).
QUICK_SECONDS = 0.25
REPEAT = 3


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    """Wall seconds and result of ``fn``; quick runs are repeated and the fastest kept."""
    best, out = math.inf, None
    for k in range(REPEAT):
        t0 = time.perf_counter()
        res = fn()
        dt = time.perf_counter() - t0
        if dt < best:
            best, out = dt, res
        if k == 0 and dt >= QUICK_SECONDS:
            break
    return best, out


def finite_or_none(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def check_pixels(pixels: NDArray[np.floating]) -> FloatArray:
    """The environment map as float64 (H, W, 3), validated by ``require_rgb_latlong``."""
    from relight.conventions import require_rgb_latlong

    return np.asarray(require_rgb_latlong(pixels), dtype=np.float64)


def frequency_radial_point(
    px: FloatArray, lobe: RadialLobe, eps: float, size: int, ref: FloatArray, cal: costmodel.Calibration
) -> tuple[TradeoffPoint, FloatArray]:
    from relight.prefilter import prefilter_radial

    h, w = px.shape[:2]
    seconds, res = timed(lambda: prefilter_radial(px, lobe, epsilon=eps, size=size))
    o = res.report.orders
    f_rho = o.F_rho if o.F_rho is not None else o.F_B
    f_proj = min(f_rho, h - 1)
    pred = cal.predict(costmodel.prefilter_report_features(lobe, res.report, height=h, width=w))
    return TradeoffPoint(
        method="frequency",
        representation="reflection_map",
        setting={"epsilon": eps},
        orders={"F_B": o.F_B, "P_B": 0, "F_rho": f_rho, "F_L": o.F_L, "F_proj": f_proj},
        predicted_error=finite_or_none(o.rms_min_of_errors),
        predicted_error_bound=finite_or_none(o.rms_appendix_b),
        measured_error=relative_rms(res.map, ref),
        predicted_seconds=pred.seconds,
        measured_seconds=seconds,
        predicted_stages=pred.stages,
        measured_stages=costmodel.report_stages(res.report.timings),
    ), np.asarray(res.map, dtype=np.float64)


def frequency_shrm_point(
    px: FloatArray, brdf: Any, eps: float, size: int, view: FloatArray, ref: FloatArray, cal: costmodel.Calibration
) -> tuple[TradeoffPoint, FloatArray]:
    from relight.brdf import lobe_cache
    from relight.shrm import create_shrm, reflect

    h, w = px.shape[:2]
    def create() -> Any:
        lobe_cache.clear()  # every point pays for its own order search (App. C step 1)
        t0 = time.perf_counter()
        out = create_shrm(px, brdf, epsilon=eps, size=size)
        t1 = time.perf_counter()
        image = reflect(out, view)  # a fresh SHRM: the view's cost includes eq. 8
        return t1 - t0, time.perf_counter() - t1, out, image

    _, (t_create, t_view, shrm, image) = timed(create)
    report = shrm.typed_report
    plans = costmodel.shrm_lobe_plans(brdf, report)
    f_proj = min(max(p.f_rho for p in plans), h - 1)
    pred = cal.predict(costmodel.shrm_report_features(brdf, report, height=h, width=w, views=1))
    measured_stages = costmodel.report_stages(report.timings)
    measured_stages["view"] = t_view
    worst = report.predicted
    return TradeoffPoint(
        method="frequency",
        representation="shrm",
        setting={"epsilon": eps},
        orders={
            "F_B": max(p.f_b for p in plans), "P_B": max(p.p_b for p in plans), "F_proj": f_proj,
            "components": [{"kind": c.lobe.get("kind"), "center": c.center, "structure": c.structure,
                            "F_rho": p.f_rho, "F_B": p.f_b, "P_B": p.p_b, "maps": c.n_maps,
                            "probes": [list(q) for q in p.probes] if p.probes else None}
                           for c, p in zip(report.components, plans, strict=True)],
        },
        predicted_error=finite_or_none(worst.rms_min_of_errors),
        predicted_error_bound=finite_or_none(worst.rms_appendix_b),
        measured_error=relative_rms(image, ref),
        predicted_seconds=pred.seconds,
        measured_seconds=t_create + t_view,
        predicted_stages=pred.stages,
        measured_stages=measured_stages,
    ), np.asarray(image, dtype=np.float64)


def angular_point(
    px: FloatArray, brdf: Any, truncation: float, size: int, view: FloatArray | None, ref: FloatArray,
    cal: costmodel.Calibration,
) -> tuple[TradeoffPoint, FloatArray]:
    h = px.shape[0]
    if view is None:
        from relight.reference import reference_radial, truncation_angle

        theta_star = truncation_angle(brdf, truncation)
        pairs = costmodel.angular_pairs(h, size, theta_star)
        pred = cal.predict(costmodel.angular_features(h, size, theta_star))
        seconds, out = timed(lambda: reference_radial(px, brdf, size, epsilon=truncation))
        w_d = 0.5 * (1.0 - math.cos(theta_star))
        orders: dict[str, Any] = {"truncation": truncation, "theta_star_deg": math.degrees(theta_star),
                                  "W": w_d, "W_visited": pairs / float(h * 2 * h * size * 2 * size)}
    else:
        from relight.reference_view import reference_view

        feats = costmodel.angular_view_features(brdf, view, h, size, truncation)  # also builds the cone table
        pairs, _, w_d = costmodel.angular_view_counts(brdf, view, h, size, truncation)
        pred = cal.predict(feats)
        seconds, out = timed(lambda: reference_view(px, brdf, view, size, truncation=truncation))
        orders = {"truncation": truncation, "W": w_d, "W_visited": pairs / float(h * 2 * h * size * 2 * size)}
    return TradeoffPoint(
        method="angular",
        representation="reflection_map",
        setting={"truncation": truncation},
        orders=orders,
        predicted_error=truncation,
        predicted_error_bound=None,
        measured_error=relative_rms(out, ref),
        predicted_seconds=pred.seconds,
        measured_seconds=seconds,
        predicted_stages=pred.stages,
        measured_stages={"angular_view" if view is not None else "angular": seconds},
    ), np.asarray(out, dtype=np.float64)


def warm_up(brdf: Any, view: FloatArray | None) -> None:
    """Run every code path once on a tiny map, untimed: imports and one-time caches belong to no point."""
    tiny = np.ones((8, 16, 3))
    if view is None:
        from relight.prefilter import prefilter_radial
        from relight.reference import reference_radial

        prefilter_radial(tiny, brdf, order=4, size=4)
        reference_radial(tiny, brdf, 2, epsilon=0.1)
    else:
        from relight.brdf import lobe_cache
        from relight.reference_view import reference_view
        from relight.shrm import create_shrm, reflect

        reflect(create_shrm(tiny, brdf, order=4, p_order=2, size=4), view)
        reference_view(tiny, brdf, view, 2, truncation=0.1)
        lobe_cache.clear()

