"""Accuracy against time: the frequency method at several tolerances and the angular method at several truncations
(seed 000 §5.1, §6.2 Table 3, §7.4 Tables 4–5, App. D).

:func:`sweep` runs, for one (environment, BRDF) pair on one output grid (``S x 2S``):

* the **frequency method** for every tolerance ``epsilon``: a reflection map (``relight.prefilter.prefilter_radial``)
  for a single radially symmetric lobe, otherwise an SHRM (``relight.shrm.create_shrm``) and its eq. 12 map for one
  distant view (``relight.shrm.reflect``), since the angular method produces one view's map too (Table 5);
* the **angular method** (``relight.reference.reference_radial`` / ``relight.reference_view.reference_view``) for
  every lobe truncation (App. D: the cone holding ``1 - truncation`` of the lobe);
* the **reference**: the angular method without truncation (every pixel of the sphere), the ground truth of every
  measured error.

Each point records the predicted error (the frequency method's minimum-of-errors estimate ``sqrt(epsilon_B)``,
§5.1, with App. B's bound alongside; the angular method's dropped lobe fraction, which is its exact relative error
for a uniform environment), the measured error (``relight.metrics.relative_rms`` against the reference), the
predicted seconds (``relight.costmodel``, for the orders the run chose) and the measured seconds (wall clock; the
BRDF coefficient cache is cleared first, so every point pays for its own order search; runs under a quarter second
are repeated and the fastest kept). ``pareto`` marks the points
no other point of the same method beats in both measured error and measured time; ``pareto_overall`` the same over
both methods.

**Against Mitsuba 3.** When the material has an exact Mitsuba 3 twin (``relight.mitsuba_twin.twin``:
Torrance–Sparrow with ``fresnel="none"``, Beckmann or GGX, and Lambert), Mitsuba is installed and the map can be
shown to it exactly (H even), every point also records ``mitsuba_error``: its error against an independent renderer.
Mitsuba renders once per sweep (the image does not depend on the point): a unit sphere under the map, seen by an
orthographic camera along the sweep's view (``view``, also for view-independent maps), direct light only,
:class:`~relight.mitsuba_twin.TwinSettings` (64 x 64 pixels, 8192 samples per pixel). Each point's output map
becomes the same image (per sub-pixel, 4 x 4 per pixel: N from the sphere, ``R = 2 (N.V) N - V``, the map looked up
bilinearly at its centre direction: R for view maps and R-centred lobes, N for Lambert's map), and the two images
are compared on 4 x 4-pixel block means of Rec. 709 luminance over the blocks lying entirely within image radius
0.8 (N within 53 degrees of V; grazing views are excluded, where both the SHRM's orders and the pixel footprints
diverge): ``mitsuba_error`` is the relative RMS over those blocks. ``image_error`` is the same metric against the
angular reference's image instead of Mitsuba's, so that it can be compared with ``mitsuba_error`` on equal terms;
the sphere-wide ``measured_error`` is not comparable with either: it also counts grazing views, where an SHRM's
error is largest.

``meta["mitsuba"]`` records the settings, the render's seconds (not part of any point's), and two floors:

* ``noise``: the relative RMS of the blocks' Monte Carlo standard deviations (estimated by Mitsuba's ``moment``
  integrator from the render's own samples): the expected ``mitsuba_error`` of a perfect map. It is 1.5–5.5e-3 on
  the five sample maps (64 rows; Beckmann 0.05 and 0.2, GGX 0.2, Lambert) at the default settings, for renders of
  2–6 s on a 2-core machine (``llvm_ad_rgb``), so ``mitsuba_error`` resolves errors of about 1e-2 and above, and a
  finer point's ``mitsuba_error`` stops falling at the floor; below it only the angular reference measures. One
  render's actual noise scatters widely about the floor (0.5 to 2.2 times it over 12 seeds on the studio map): the
  few brightest blocks dominate the relative RMS and their Monte Carlo estimates are heavy-tailed.
* ``reference_error``: the angular reference itself turned into the same image, against Mitsuba. It is the
  consistency check of the whole comparison (camera, map orientation, BSDF, units) and the floor below which
  ``mitsuba_error`` cannot separate points: the noise, plus what every map shares, the bilinear lookup of the
  ``S x 2S`` output grid and the reference's pixel-centre sum over the map (Mitsuba integrates the pixels' areas).
  With S equal to the input rows it is at the noise level (``tests/test_tradeoff_mitsuba.py``); at a coarser grid
  the interpolation shows (2.6 % for Beckmann alpha = 0.2 on the studio map at 32 rows and S = 16).

Otherwise ``meta["mitsuba"]`` is ``{"computed": False, "reason": ...}`` (no twin, Mitsuba not installed, an odd
map height, a failed render, or ``mitsuba=False``) and the points carry ``mitsuba_error`` and ``image_error`` None.

:func:`window_tradeoff` reports what optional windowing (``prefilter_radial(window=...)``) costs in accuracy and
gains in ringing (the negative lobe of the band-limited kernel, Gibbs overshoot).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, costmodel
from relight.brdf.base import Lobe, RadialLobe
from relight.conventions import luminance
from relight.errors import InputError, RelightError
from relight.jsonable import jsonable as _jsonable
from relight.metrics import relative_rms
from relight.mitsuba_twin import TwinSettings

FloatArray = NDArray[np.float64]
Progress = Callable[[str, float], None]

#: Tolerances of the frequency method (the paper's epsilon, §5.1) swept by default: to 1e-4 when every lobe is
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

    points: list[dict[str, Any]]
    meta: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"points": self.points, "meta": self.meta}


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


#: Runs faster than this are repeated (best of :data:`REPEAT`): the machines are noisy (FACTS.md).
QUICK_SECONDS = 0.25
REPEAT = 3


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
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


def _finite_or_none(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _check_pixels(pixels: NDArray[np.floating]) -> FloatArray:
    """The environment map as float64 (H, W, 3), validated by ``require_rgb_latlong``."""
    from relight.conventions import require_rgb_latlong

    return np.asarray(require_rgb_latlong(pixels), dtype=np.float64)



def default_size(height: int) -> int:
    """Output rows of a sweep: half the input's rows, at most :data:`MAX_DEFAULT_SIZE`, at least 8."""
    return int(max(8, min(height // 2, MAX_DEFAULT_SIZE)))


def _frequency_radial(
    px: FloatArray, lobe: RadialLobe, eps: float, size: int, ref: FloatArray, cal: costmodel.Calibration
) -> tuple[dict[str, Any], FloatArray]:
    from relight.prefilter import prefilter_radial

    h, w = px.shape[:2]
    seconds, res = _timed(lambda: prefilter_radial(px, lobe, epsilon=eps, size=size))
    o = res.report.orders
    f_rho = o.F_rho if o.F_rho is not None else o.F_B
    f_proj = min(f_rho, h - 1)
    pred = cal.predict(costmodel.prefilter_report_features(lobe, res.report, height=h, width=w))
    return {
        "method": "frequency",
        "representation": "reflection_map",
        "setting": {"epsilon": eps},
        "orders": {"F_B": o.F_B, "P_B": 0, "F_rho": f_rho, "F_L": o.F_L, "F_proj": f_proj},
        "predicted_error": _finite_or_none(o.rms_min_of_errors),
        "predicted_error_bound": _finite_or_none(o.rms_appendix_b),
        "measured_error": relative_rms(res.map, ref),
        "predicted_seconds": pred.seconds,
        "measured_seconds": seconds,
        "predicted_stages": pred.stages,
        "measured_stages": costmodel.report_stages(res.report.timings),
    }, np.asarray(res.map, dtype=np.float64)


def _frequency_shrm(
    px: FloatArray, brdf: Any, eps: float, size: int, view: FloatArray, ref: FloatArray, cal: costmodel.Calibration
) -> tuple[dict[str, Any], FloatArray]:
    from relight.brdf import lpq
    from relight.shrm import create_shrm, reflect

    h, w = px.shape[:2]
    def create() -> Any:
        lpq.clear_cache()  # every point pays for its own order search (App. C step 1)
        t0 = time.perf_counter()
        out = create_shrm(px, brdf, epsilon=eps, size=size)
        t1 = time.perf_counter()
        image = reflect(out, view)  # a fresh SHRM: the view's cost includes eq. 8
        return t1 - t0, time.perf_counter() - t1, out, image

    _, (t_create, t_view, shrm, image) = _timed(create)
    comps = shrm.report["components"]
    plans = costmodel.shrm_lobe_plans(brdf, shrm.report)
    f_proj = min(max(p.f_rho for p in plans), h - 1)
    pred = cal.predict(costmodel.shrm_report_features(brdf, shrm.report, height=h, width=w, views=1))
    measured_stages = costmodel.report_stages(shrm.report["timings"])
    measured_stages["view"] = t_view
    worst = shrm.report["predicted"]
    return {
        "method": "frequency",
        "representation": "shrm",
        "setting": {"epsilon": eps},
        "orders": {
            "F_B": max(p.f_b for p in plans), "P_B": max(p.p_b for p in plans), "F_proj": f_proj,
            "components": [{"kind": c["lobe"].get("kind"), "center": c["center"], "structure": c["structure"],
                            "F_rho": p.f_rho, "F_B": p.f_b, "P_B": p.p_b, "maps": c["n_maps"],
                            "probes": [list(q) for q in p.probes] if p.probes else None}
                           for c, p in zip(comps, plans, strict=True)],
        },
        "predicted_error": _finite_or_none(worst.get("rms_min_of_errors")),
        "predicted_error_bound": _finite_or_none(worst.get("rms_appendix_b")),
        "measured_error": relative_rms(image, ref),
        "predicted_seconds": pred.seconds,
        "measured_seconds": t_create + t_view,
        "predicted_stages": pred.stages,
        "measured_stages": measured_stages,
    }, np.asarray(image, dtype=np.float64)


def _angular(
    px: FloatArray, brdf: Any, truncation: float, size: int, view: FloatArray | None, ref: FloatArray,
    cal: costmodel.Calibration,
) -> tuple[dict[str, Any], FloatArray]:
    h = px.shape[0]
    if view is None:
        from relight.reference import reference_radial, truncation_angle

        theta_star = truncation_angle(brdf, truncation)
        pairs = costmodel.angular_pairs(h, size, theta_star)
        pred = cal.predict(costmodel.angular_features(h, size, theta_star))
        seconds, out = _timed(lambda: reference_radial(px, brdf, size, epsilon=truncation))
        w_d = 0.5 * (1.0 - math.cos(theta_star))
        orders: dict[str, Any] = {"truncation": truncation, "theta_star_deg": math.degrees(theta_star),
                                  "W": w_d, "W_visited": pairs / float(h * 2 * h * size * 2 * size)}
    else:
        from relight.reference_view import reference_view

        feats = costmodel.angular_view_features(brdf, view, h, size, truncation)  # also builds the cone table
        pairs, _, w_d = costmodel.angular_view_counts(brdf, view, h, size, truncation)
        pred = cal.predict(feats)
        seconds, out = _timed(lambda: reference_view(px, brdf, view, size, truncation=truncation))
        orders = {"truncation": truncation, "W": w_d, "W_visited": pairs / float(h * 2 * h * size * 2 * size)}
    return {
        "method": "angular",
        "representation": "reflection_map",
        "setting": {"truncation": truncation},
        "orders": orders,
        "predicted_error": truncation,
        "predicted_error_bound": None,
        "measured_error": relative_rms(out, ref),
        "predicted_seconds": pred.seconds,
        "measured_seconds": seconds,
        "predicted_stages": pred.stages,
        "measured_stages": {"angular_view" if view is not None else "angular": seconds},
    }, np.asarray(out, dtype=np.float64)


def _warm_up(brdf: Any, view: FloatArray | None) -> None:
    """Run every code path once on a tiny map, untimed: imports and one-time caches belong to no point."""
    tiny = np.ones((8, 16, 3))
    if view is None:
        from relight.prefilter import prefilter_radial
        from relight.reference import reference_radial

        prefilter_radial(tiny, brdf, order=4, size=4)
        reference_radial(tiny, brdf, 2, epsilon=0.1)
    else:
        from relight.brdf import lpq
        from relight.reference_view import reference_view
        from relight.shrm import create_shrm, reflect

        reflect(create_shrm(tiny, brdf, order=4, p_order=2, size=4), view)
        reference_view(tiny, brdf, view, 2, truncation=0.1)
        lpq.clear_cache()


def _mitsuba_plan(brdf: Any, px: FloatArray, mitsuba: bool | None) -> tuple[dict[str, Any] | None, str | None]:
    """The Mitsuba twin to render against, or None and why not; ``mitsuba=True`` turns every why-not into an error
    (InputError for the material or the map, RelightError when Mitsuba cannot run here)."""
    from relight import mitsuba_twin

    if mitsuba is False:
        return None, "switched off (mitsuba=False, --mitsuba off)"
    bsdf = mitsuba_twin.twin(brdf)
    why: str | None = None
    if bsdf is None:
        kind = getattr(brdf, "kind", type(brdf).__name__)
        why = (f"{kind} has no Mitsuba 3 twin (relight.mitsuba_twin.twin: Torrance-Sparrow with fresnel='none' and "
               "Lambert only)")
    else:
        why = mitsuba_twin.check_bitmap_shape(px.shape)
    if why is not None and mitsuba:
        raise InputError(f"mitsuba=True (--mitsuba on): {why}")
    if why is None:
        why = mitsuba_twin.unavailable_reason()
        if why is not None and mitsuba:
            raise RelightError(f"mitsuba=True (--mitsuba on): {why}")
    return (bsdf, None) if why is None else (None, why)


def _mitsuba_errors(
    px: FloatArray, brdf: Any, bsdf: dict[str, Any], view: FloatArray, ref: FloatArray, maps: list[FloatArray],
    settings: TwinSettings,
) -> tuple[list[tuple[float, float]], dict[str, Any]]:
    """Each map's relative RMS against Mitsuba's sphere image (one render) and against the reference's, and the meta
    entry (module docstring)."""
    from relight import mitsuba_twin

    center = str(brdf.center) if is_reflection_map(brdf) else "R"  # view maps are indexed by R (reflect, reference)
    t0 = time.perf_counter()
    cmp = mitsuba_twin.compare_sphere(px, bsdf, view, settings)
    render_seconds = time.perf_counter() - t0
    ref_blocks = cmp.blocks(ref, center)
    errors = []
    for m in maps:
        y = cmp.blocks(m, center)
        errors.append((mitsuba_twin.block_rms(y, cmp.truth), mitsuba_twin.block_rms(y, ref_blocks)))
    meta = {
        "computed": True,
        "variant": cmp.render.variant,
        "bsdf": bsdf,
        "view": [float(x) for x in view],
        "image": {"height": settings.size, "width": settings.size},
        "spp": settings.spp,
        "seed": settings.seed,
        "block": settings.block,
        "radius": settings.radius,
        "max_angle_nv_deg": math.degrees(math.asin(settings.radius)),
        "blocks": int(cmp.truth.size),
        "supersample": settings.supersample,
        "texels_per_pixel": cmp.texels,
        "map_center": center,
        "seconds": render_seconds,
        "noise": cmp.noise,
        "reference_error": mitsuba_twin.block_rms(ref_blocks, cmp.truth),
        "metric": (f"relative RMS over the {cmp.truth.size} blocks of {settings.block} x {settings.block} pixels lying "
                   f"within image radius {settings.radius:g} of a {settings.size} x {settings.size} orthographic "
                   "sphere image, Rec. 709 luminance; relight's map looked up bilinearly at its centre direction, "
                   f"{settings.supersample} x {settings.supersample} samples per pixel"),
    }
    return errors, meta


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
    ``mitsuba_settings`` defaults to :class:`relight.mitsuba_twin.TwinSettings` ``()``.
    """
    px = _check_pixels(pixels)
    h = px.shape[0]
    if epsilons is None:
        from relight.shrm import brdf_lobes

        cheap = all(lobe.radially_symmetric for lobe in brdf_lobes(brdf))
        epsilons = DEFAULT_EPSILONS if cheap else DEFAULT_SHRM_EPSILONS
    if not epsilons and not truncations:
        raise InputError("a sweep needs at least one epsilon or one truncation")
    for e in epsilons:
        if not 0.0 < float(e) < 1.0:
            raise InputError(f"epsilon must lie in (0, 1), got {e}")
    for t in truncations:
        if not 0.0 < float(t) < 1.0:
            raise InputError(f"truncation must lie in (0, 1), got {t}")
    s = default_size(h) if size is None else int(size)
    if not 2 <= s <= 4 * h:
        raise InputError(f"size must lie in 2..{4 * h} for a {h}-row map, got {s}")
    if not isinstance(brdf, Lobe) and not hasattr(brdf, "lobes"):
        raise InputError(f"not a BRDF: {type(brdf).__name__}")
    radial = is_reflection_map(brdf)
    twin_bsdf, no_twin = _mitsuba_plan(brdf, px, mitsuba)
    from relight.shrm import unit_view

    camera = unit_view(view) if not radial or twin_bsdf is not None else None
    v: FloatArray | None = None if radial else camera
    cal = calibration if calibration is not None else costmodel.load_calibration()
    report = progress or (lambda stage, fraction: None)
    _warm_up(brdf, v)
    n_total = len(epsilons) + len(truncations) + 1 + (twin_bsdf is not None)

    report("reference", 0.0)
    if v is None:
        from relight.reference import reference_radial

        t_ref, ref = _timed(lambda: reference_radial(px, brdf, s, epsilon=0.0))
    else:
        from relight.reference_view import reference_view

        vv = v
        t_ref, ref = _timed(lambda: reference_view(px, brdf, vv, s, truncation=0.0))
    if not np.any(luminance(ref)):
        raise InputError("the reference is zero everywhere (a black environment): relative errors are undefined")

    points: list[dict[str, Any]] = []
    maps: list[FloatArray] = []
    done = 1
    for eps in sorted({float(e) for e in epsilons}, reverse=True):
        report("frequency", done / n_total)
        if v is None:
            assert isinstance(brdf, RadialLobe)
            point, out = _frequency_radial(px, brdf, eps, s, ref, cal)
        else:
            point, out = _frequency_shrm(px, brdf, eps, s, v, ref, cal)
        points.append(point)
        maps.append(out)
        done += 1
    for tr in sorted({float(t) for t in truncations}, reverse=True):
        report("angular", done / n_total)
        point, out = _angular(px, brdf, tr, s, v, ref, cal)
        points.append(point)
        maps.append(out)
        done += 1

    # after every timed point: the render is not part of any point's seconds
    errors: list[tuple[float, float]] = []
    mitsuba_meta: dict[str, Any] = {"computed": False, "reason": no_twin}
    if twin_bsdf is not None and camera is not None:
        report("mitsuba", done / n_total)
        try:
            errors, mitsuba_meta = _mitsuba_errors(px, brdf, twin_bsdf, camera, ref, maps,
                                                   mitsuba_settings or TwinSettings())
        except (RelightError, RuntimeError) as exc:  # Mitsuba's own errors are RuntimeErrors
            if mitsuba:
                raise
            mitsuba_meta = {"computed": False, "reason": f"the Mitsuba 3 render failed: {exc}"}
    for i, p in enumerate(points):
        p["mitsuba_error"] = _finite_or_none(errors[i][0]) if errors else None
        p["image_error"] = _finite_or_none(errors[i][1]) if errors else None

    for method in ("frequency", "angular"):
        idx = [i for i, p in enumerate(points) if p["method"] == method]
        flags = pareto_flags([points[i]["measured_error"] for i in idx], [points[i]["measured_seconds"] for i in idx])
        for i, f in zip(idx, flags, strict=True):
            points[i]["pareto"] = f
    overall = pareto_flags([p["measured_error"] for p in points], [p["measured_seconds"] for p in points])
    for p, f in zip(points, overall, strict=True):
        p["pareto_overall"] = f

    ratios = [p["predicted_seconds"] / p["measured_seconds"] for p in points if p["measured_seconds"] > 0]
    spec = brdf.spec() if hasattr(brdf, "spec") else None
    meta = {
        "relight_version": __version__,
        "brdf": spec,
        "representation": "reflection_map" if radial else "shrm",
        "input": {"height": h, "width": 2 * h},
        "output": {"height": s, "width": 2 * s},
        "view": None if v is None else [float(x) for x in v],
        "metric": "relative RMS error over the sphere, solid-angle weighted, Rec. 709 luminance (relight.metrics)",
        "reference": {"method": "angular", "truncation": 0.0, "seconds": t_ref},
        "calibration": {"key": cal.key, "calibrated": cal.calibrated, "created": cal.created,
                        "constants": dict(cal.constants)},
        "time_ratio_range": [min(ratios), max(ratios)] if ratios else None,
        "mitsuba": mitsuba_meta,
    }
    report("done", 1.0)
    return Tradeoff(points=points, meta=meta)


# ------------------------------------------------------------------------------------------------- windowing
def window_tradeoff(
    pixels: NDArray[np.floating],
    lobe: RadialLobe,
    *,
    order: int,
    size: int,
    reference: NDArray[np.floating] | None = None,
    windows: Sequence[str] = ("none", "hann", "lanczos"),
) -> list[dict[str, Any]]:
    """Accuracy cost and ringing gain of windowing the order-F expansion (``prefilter_radial(window=...)``).

    For each window: ``relative_rms`` against ``reference`` (default: the untruncated angular reference),
    ``kernel_min`` (the most negative value of the band-limited lobe, the prefilter report's ringing figure),
    ``kernel_min_relative`` (that over the lobe's peak ``u_F(1)``), the report's lower bound on every output texel,
    the most negative output value (luminance) relative to the output's largest, and the fraction of negative
    output texels (luminance). Negative lobes of ``u_F`` are what turn a bright sun into dark rings (Gibbs).
    """
    from relight.brdf.coefficients import kernel_on_grid, radial_transfer, window_factors
    from relight.prefilter import prefilter_radial
    from relight.reference import reference_radial

    px = _check_pixels(pixels)
    ref = np.asarray(reference, dtype=np.float64) if reference is not None else reference_radial(
        px, lobe, size, epsilon=0.0)
    transfer = radial_transfer(lobe, order).transfer
    out = []
    for w in windows:
        res = prefilter_radial(px, lobe, order=order, size=size, window=w)
        factors = transfer * window_factors(order, w)[:, None]
        peak = float(np.max(kernel_on_grid(factors, np.array([1.0]))))
        y = luminance(res.map)
        ring = res.report.ringing
        out.append({
            "window": w,
            "order": order,
            "relative_rms": relative_rms(res.map, ref),
            "kernel_min": ring.kernel_min,
            "kernel_min_relative": ring.kernel_min / peak if peak > 0 else 0.0,
            "lower_bound_rgb": list(ring.lower_bound_rgb),
            "min_output_relative": float(y.min() / y.max()) if y.max() > 0 else 0.0,
            "negative_fraction": float(np.mean(y < 0.0)),
        })
    return out


# ------------------------------------------------------------------------------------------------- output


def write_tradeoff(result: Tradeoff, out_dir: str | Path, *, title: str | None = None) -> dict[str, Path]:
    """``tradeoff.json`` (the list of points), ``tradeoff_meta.json`` and the three plots of :func:`plot`."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"tradeoff.json": out / "tradeoff.json", "tradeoff_meta.json": out / "tradeoff_meta.json"}
    paths["tradeoff.json"].write_text(json.dumps(_jsonable(result.points), indent=1, allow_nan=False))
    paths["tradeoff_meta.json"].write_text(json.dumps(_jsonable(result.meta), indent=1, allow_nan=False))
    paths.update(plot(result, out, title=title))
    return paths


_STYLE = {"frequency": ("tab:blue", "o"), "angular": ("tab:orange", "s")}


def plot(result: Tradeoff, out_dir: str | Path, *, title: str | None = None) -> dict[str, Path]:
    """PNG plots (matplotlib, Agg): error vs time with both Pareto fronts, predicted vs measured error, predicted
    vs measured time. When the sweep measured against Mitsuba 3 (``meta["mitsuba"]["computed"]``), the frequency
    points' ``mitsuba_error`` appear as hollow markers of the same colour in the first two, with the noise floor
    (dotted) and the reference's own error against Mitsuba (dash-dotted) in the first."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    name = title or str((result.meta.get("brdf") or {}).get("kind", "tradeoff"))
    paths: dict[str, Path] = {}
    pts = result.points

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for method, (colour, marker) in _STYLE.items():
        mp = [p for p in pts if p["method"] == method]
        if not mp:
            continue
        ax.scatter([p["measured_seconds"] for p in mp], [max(p["measured_error"], 1e-12) for p in mp], c=colour,
                   marker=marker, label=f"{method} method", zorder=3)
        front = sorted((p for p in mp if p.get("pareto")), key=lambda p: p["measured_seconds"])
        if front:
            ax.step([p["measured_seconds"] for p in front], [max(p["measured_error"], 1e-12) for p in front],
                    where="post", color=colour, alpha=0.6, label=f"{method} Pareto front")
        for p in mp:
            lab = (f"F={p['orders'].get('F_B')}" + (f",P={p['orders'].get('P_B')}" if p["orders"].get("P_B") else "")
                   if method == "frequency" else f"t={p['setting']['truncation']:g}")
            ax.annotate(lab, (p["measured_seconds"], max(p["measured_error"], 1e-12)), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
    mits = result.meta.get("mitsuba") or {}
    if mits.get("computed"):
        colour, marker = _STYLE["frequency"]
        mp = [p for p in pts if p["method"] == "frequency" and p.get("mitsuba_error") is not None]
        if mp:
            ax.scatter([p["measured_seconds"] for p in mp], [max(float(p["mitsuba_error"]), 1e-12) for p in mp],
                       facecolors="none", edgecolors=colour, marker=marker, label="frequency vs Mitsuba 3", zorder=3)
        ax.axhline(max(float(mits["noise"]), 1e-12), color="0.35", ls=":", lw=1.0,
                   label="Mitsuba 3 noise floor")
        ax.axhline(max(float(mits["reference_error"]), 1e-12), color="0.35", ls="-.", lw=0.8,
                   label="angular reference vs Mitsuba 3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("measured seconds")
    ax.set_ylabel("measured relative RMS error")
    ax.set_title(f"{name}\naccuracy against time", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    paths["error_vs_time.png"] = out / "error_vs_time.png"
    fig.savefig(paths["error_vs_time.png"], dpi=110)
    plt.close(fig)

    for key, pred_key, meas_key, label in (
        ("predicted_vs_measured_error.png", "predicted_error", "measured_error", "relative RMS error"),
        ("predicted_vs_measured_time.png", "predicted_seconds", "measured_seconds", "seconds"),
    ):
        fig, ax = plt.subplots(figsize=(5.2, 4.6))
        vals: list[float] = []
        for method, (colour, marker) in _STYLE.items():
            mp = [p for p in pts if p["method"] == method and p.get(pred_key) and p.get(meas_key)]
            if not mp:
                continue
            x = [max(float(p[pred_key]), 1e-12) for p in mp]
            y = [max(float(p[meas_key]), 1e-12) for p in mp]
            vals += x + y
            ax.scatter(x, y, c=colour, marker=marker, label=f"{method} method", zorder=3)
            if pred_key == "predicted_error" and method == "frequency":
                b = [(max(float(p["predicted_error_bound"]), 1e-12), max(float(p[meas_key]), 1e-12)) for p in mp
                     if p.get("predicted_error_bound")]
                if b:
                    ax.scatter([u for u, _ in b], [w for _, w in b], facecolors="none", edgecolors=colour,
                               marker="^", label="frequency, App. B bound", zorder=3)
                    vals += [u for u, _ in b]
                m = [(max(float(p[pred_key]), 1e-12), max(float(p["mitsuba_error"]), 1e-12)) for p in mp
                     if p.get("mitsuba_error") is not None]
                if m:
                    ax.scatter([u for u, _ in m], [w for _, w in m], facecolors="none", edgecolors=colour,
                               marker=marker, label="frequency vs Mitsuba 3 (sphere image)", zorder=3)
                    vals += [w for _, w in m]
        if vals:
            lo, hi = min(vals) / 2, max(vals) * 2
            ax.plot([lo, hi], [lo, hi], "k-", lw=0.8, label="predicted = measured")
            if pred_key == "predicted_seconds":
                ax.plot([lo, hi], [lo / 2, hi / 2], "k:", lw=0.6, label="factor 2")
                ax.plot([lo, hi], [lo * 2, hi * 2], "k:", lw=0.6)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"predicted {label}")
        ax.set_ylabel(f"measured {label}")
        ax.set_title(f"{name}\npredicted against measured {label.split()[-1]}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        paths[key] = out / key
        fig.savefig(paths[key], dpi=110)
        plt.close(fig)
    return paths
