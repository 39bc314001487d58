"""The sweep: both methods over their accuracy settings on one output grid, against the untruncated reference
(``relight.tradeoff`` module docstring; seed 000 §5.1, §7.4 Tables 4–5, App. D)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, costmodel, validate
from relight.brdf.base import Lobe, RadialLobe
from relight.conventions import luminance
from relight.errors import InputError, RelightError
from relight.mitsuba_compare import TwinSettings
from relight.tradeoff.mitsuba import mitsuba_errors, mitsuba_plan
from relight.tradeoff.points import (
    angular_point,
    check_pixels,
    finite_or_none,
    frequency_radial_point,
    frequency_shrm_point,
    is_reflection_map,
    pareto_flags,
    timed,
    warm_up,
)
from relight.tradeoff.report import (
    Grid,
    MitsubaComparison,
    SweepCalibration,
    SweepInput,
    SweepReference,
    TradeoffMeta,
    TradeoffPoint,
)

FloatArray = NDArray[np.float64]
Progress = Callable[[str, float], None]

#: radially symmetric; materials with a general lobe stop at 1e-3 (below it a microfacet lobe needs P > 16 and
#: minutes of BRDF tabulation, App. C).
DEFAULT_EPSILONS: tuple[float, ...] = (0.3, 0.1, 0.03, 0.01, 3e-3, 1e-3, 3e-4, 1e-4)
DEFAULT_SHRM_EPSILONS: tuple[float, ...] = (0.3, 0.1, 0.03, 0.01, 3e-3, 1e-3)
#: Lobe truncations of the angular method (App. D) swept by default; §7.4 used 0.05.
DEFAULT_TRUNCATIONS: tuple[float, ...] = (0.3, 0.1, 0.03, 0.01, 1e-3, 1e-4)
#: Default view of view-dependent BRDFs (towards +Z, 30 degrees above the horizon).
DEFAULT_VIEW: tuple[float, float, float] = (0.0, 0.5, 0.8660254037844386)
#: Largest default output rows (the reference costs O(S_L^2 S_B^2)).
MAX_DEFAULT_SIZE = 64


@dataclass
class Tradeoff:
    """The points of a sweep and what they were measured on (:func:`sweep`)."""

    points: list[TradeoffPoint]
    meta: TradeoffMeta

    def as_dict(self) -> dict[str, Any]:
        """``{"points": [...], "meta": {...}}`` as JSON types (the worker's stored result)."""
        return {"points": [p.to_json() for p in self.points], "meta": self.meta.to_json()}


def default_size(height: int) -> int:
    """Output rows of a sweep: half the input's rows, at most :data:`MAX_DEFAULT_SIZE`, at least 8."""
    return int(max(8, min(height // 2, MAX_DEFAULT_SIZE)))

def sweep(
    pixels: NDArray[np.floating],
    brdf: Any,
    *,
    epsilons: Sequence[float] | None = None,
    truncations: Sequence[float] = DEFAULT_TRUNCATIONS,
    size: int | None = None,
    view: Sequence[float] = DEFAULT_VIEW,
    calibration: costmodel.Calibration | None = None,
    progress: Progress | None = None,
    mitsuba: bool | None = None,
    mitsuba_settings: TwinSettings | None = None,
) -> Tradeoff:
    """Run both methods over their accuracy settings on one ``S x 2S`` grid (module docstring).

    ``epsilons`` default to :data:`DEFAULT_EPSILONS` (only radially symmetric lobes) or
    :data:`DEFAULT_SHRM_EPSILONS`.
    ``view`` is the view of view-dependent materials, and the Mitsuba camera's for every material.
    ``calibration`` defaults to :func:`relight.costmodel.load_calibration` (calibrating on first use).
    ``mitsuba``: None (default) measures every point against Mitsuba 3 too when the material has a twin
    (``relight.mitsuba_twin.twin``), the map's shape allows an exact Mitsuba bitmap (H even) and Mitsuba runs here,
    and records why not otherwise (also when the render fails); True raises instead of skipping; False skips.
    ``mitsuba_settings`` defaults to :class:`relight.mitsuba_compare.TwinSettings` ``()``.
    """
    px = check_pixels(pixels)
    h = px.shape[0]
    if epsilons is None:
        from relight.shrm import brdf_lobes

        cheap = all(lobe.radially_symmetric for lobe in brdf_lobes(brdf))
        epsilons = DEFAULT_EPSILONS if cheap else DEFAULT_SHRM_EPSILONS
    if not epsilons and not truncations:
        raise InputError("a sweep needs at least one epsilon or one truncation")
    for e in epsilons:
        validate.in_range("epsilon", e, 0.0, 1.0, lo_open=True, hi_open=True)
    for t in truncations:
        validate.in_range("truncation", t, 0.0, 1.0, lo_open=True, hi_open=True)
    s = default_size(h) if size is None else validate.int_in_range(f"size (for a {h}-row map)", size, 2, 4 * h)
    if not isinstance(brdf, Lobe) and not hasattr(brdf, "lobes"):
        raise InputError(f"not a BRDF: {type(brdf).__name__}")
    radial = is_reflection_map(brdf)
    twin_bsdf, no_twin = mitsuba_plan(brdf, px, mitsuba)
    from relight.shrm import unit_view

    camera = unit_view(view) if not radial or twin_bsdf is not None else None
    v: FloatArray | None = None if radial else camera
    cal = calibration if calibration is not None else costmodel.load_calibration()
    report = progress or (lambda stage, fraction: None)
    warm_up(brdf, v)
    n_total = len(epsilons) + len(truncations) + 1 + (twin_bsdf is not None)

    report("reference", 0.0)
    if v is None:
        from relight.reference import reference_radial

        t_ref, ref = timed(lambda: reference_radial(px, brdf, s, epsilon=0.0))
    else:
        from relight.reference_view import reference_view

        vv = v
        t_ref, ref = timed(lambda: reference_view(px, brdf, vv, s, truncation=0.0))
    if not np.any(luminance(ref)):
        raise InputError("the reference is zero everywhere (a black environment): relative errors are undefined")

    points: list[TradeoffPoint] = []
    maps: list[FloatArray] = []
    done = 1
    for eps in sorted({float(e) for e in epsilons}, reverse=True):
        report("frequency", done / n_total)
        if v is None:
            assert isinstance(brdf, RadialLobe)
            point, out = frequency_radial_point(px, brdf, eps, s, ref, cal)
        else:
            point, out = frequency_shrm_point(px, brdf, eps, s, v, ref, cal)
        points.append(point)
        maps.append(out)
        done += 1
    for tr in sorted({float(t) for t in truncations}, reverse=True):
        report("angular", done / n_total)
        point, out = angular_point(px, brdf, tr, s, v, ref, cal)
        points.append(point)
        maps.append(out)
        done += 1

    # after every timed point: the render is not part of any point's seconds
    errors: list[tuple[float, float]] = []
    mitsuba_meta = MitsubaComparison(computed=False, reason=no_twin)
    if twin_bsdf is not None and camera is not None:
        report("mitsuba", done / n_total)
        try:
            errors, mitsuba_meta = mitsuba_errors(px, brdf, twin_bsdf, camera, ref, maps,
                                                   mitsuba_settings or TwinSettings())
        except (RelightError, RuntimeError) as exc:  # Mitsuba's own errors are RuntimeErrors
            if mitsuba:
                raise
            mitsuba_meta = MitsubaComparison(computed=False, reason=f"the Mitsuba 3 render failed: {exc}")
    for i, p in enumerate(points):
        p.mitsuba_error = finite_or_none(errors[i][0]) if errors else None
        p.image_error = finite_or_none(errors[i][1]) if errors else None

    for method in ("frequency", "angular"):
        idx = [i for i, p in enumerate(points) if p.method == method]
        flags = pareto_flags([points[i].measured_error for i in idx], [points[i].measured_seconds for i in idx])
        for i, f in zip(idx, flags, strict=True):
            points[i].pareto = f
    overall = pareto_flags([p.measured_error for p in points], [p.measured_seconds for p in points])
    for p, f in zip(points, overall, strict=True):
        p.pareto_overall = f

    ratios = [p.predicted_seconds / p.measured_seconds for p in points if p.measured_seconds > 0]
    spec = brdf.spec() if hasattr(brdf, "spec") else None
    meta = TradeoffMeta(
        relight_version=__version__,
        brdf=spec,
        representation="reflection_map" if radial else "shrm",
        input=SweepInput(height=h, width=2 * h),
        output=Grid(height=s, width=2 * s),
        view=None if v is None else (float(v[0]), float(v[1]), float(v[2])),
        metric="relative RMS error over the sphere, solid-angle weighted, Rec. 709 luminance (relight.metrics)",
        reference=SweepReference(method="angular", truncation=0.0, seconds=t_ref),
        calibration=SweepCalibration(key=cal.key, calibrated=cal.calibrated, created=cal.created,
                                     constants=dict(cal.constants)),
        time_ratio_range=(min(ratios), max(ratios)) if ratios else None,
        mitsuba=mitsuba_meta,
    )
    report("done", 1.0)
    return Tradeoff(points=points, meta=meta)

