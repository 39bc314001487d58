"""The order reduction a sun extraction buys (issue 17, item 6: "the plan shows the order reduction it buys").

The planner's orders (``relight.planning.job``) follow the core's minimum-of-orders rule ``F_B = min(F_rho, F_L)``;
on a map with a sun ``F_L`` is not reached below the map's order at any useful tolerance (a sun's band energies do
not decay), so ``F_B`` is the lobe's own ``F_rho`` with or without the sun. What the sun changes is the order the
*output* needs: the lobe's prediction per view band under the map's lighting (``relight.shrm.view_bands``, the
orientation average ``epsilon`` per fine band) falls below the tolerance at a lower order when the lighting has no
sun. Per lobe:

    order(lighting) = the smallest F <= F_B whose predicted ``epsilon`` is <= the tolerance in every enforced view
    band (N.V at least the grazing limit), at the lobe's planned view order P_B; F_B when no F <= F_B meets it
    (``met`` False: the lobe's own order is the limit).

The prediction falls monotonically with F (each band l <= F contributes its P-truncation ``D^P_l <= K_l`` instead of
``K_l``), so a bisection finds it. :func:`sun_orders` gives the orders (the map as uploaded and its residual after
``relight.sun.extract_sun``) and their ratio; :func:`plan_job_with_sun` plans a job on a map file with them.

Without the sun the output is the residual's SHRM plus the sun as a point light (``directional_view``), and the
tolerance is the same one the user asked of that output: ``order_without_sun`` holds the residual SHRM's error energy
plus the point light's (:func:`point_error_lighting`, rendered without truncation, so all of it is error), combined
by the triangle inequality in RMS, to ``epsilon`` times the *original* map's output energy per band.
``order_residual_alone`` holds the residual to its own output energy (as if it were the whole map).

city.exr, microfacet sigma = 0.2, 512 rows, grazing limit 0.1 (tests/relight/test_sun_orders.py): epsilon = 1e-3:
31 (not met, F_B) -> 13 (2.4x), residual alone 18; epsilon = 1e-2: 32 -> 4 (8x), residual alone 7. Issue 17 asks
4x at 1e-3. What limits it, per band N.V in [0.1, 0.2] (the worst) as fractions of the original output energy: the
residual's own error at F = 7 is 1.17e-3 (1.0e-3 of it its bands 8..15: the city's skyline and facades, far from the
sun; the removed disc's size changes it by 1 %: 1.29e-3 with the core alone, 1.16e-3 at 6 deg), above epsilon by
itself, so no extraction reaches F = 7 (4x of 31 is 7.75); the point light's own error there is 1.9e-4
(the sun's 12 pixels span 0.56 deg where the grazing lobe is narrow), which with the bound lifts the order to 13
(combined exactly, R + delta per band above F and Cauchy-Schwarz below, it is 8 = 3.9x: measured, not built).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from relight.planning.job import JobPlan, StoredLighting, plan_job

#: How far the lobe is read for the point light's error (``exact_part``; at most the map's own order H - 1): its
#: band energies ``Lambda_l^2 E^delta_l`` grow with l up to the pixel scale (city.exr: 2.5e-9 at l = 1, 0.04 at 96,
#: 5.3 at 511), so a flat continuation beyond a shorter read misjudges it either way. City.exr's point error at N.V
#: in [0.1, 0.2], as a fraction of the output energy, read to 96 / 160 / 256 / 384 / 511: 2.9e-4 / 1.9e-4 / 1.5e-4
#: / 1.6e-4 / 1.9e-4 (511: the map's band limit, 16 s on the shared 2-core machine, then cached).
EXACT_PART_ORDER = 511


def lighting_order(lobe: Any, lighting: StoredLighting, f_b: int, p_b: int, epsilon: float, *, height: int,
                   grazing_limit: float, output: StoredLighting | None = None,
                   exact_part: StoredLighting | None = None) -> tuple[int, bool]:
    """(order, met): the smallest F <= ``f_b`` whose predicted error under ``lighting`` meets ``epsilon`` in every
    enforced view band (module docstring); (``f_b``, False) when none does.

    ``output``: the lighting whose output energy the error is held to (default ``lighting`` itself: the prediction's
    own relative error). ``exact_part``: a lighting rendered without truncation whose whole output is error (the
    extracted sun's difference from its point light), added to the SHRM's error by the triangle inequality in RMS,
    ``(sqrt(e_SHRM) + sqrt(e_part))^2`` per band and channel, an upper bound whatever their correlation."""
    from relight.shrm.creation import spectrum_order
    from relight.shrm.order_search import cached_spectrum
    from relight.shrm.view_bands import error_and_output_by_band
    from relight.shrm.view_spectrum import band_edges

    edges = band_edges(grazing_limit)
    spec = cached_spectrum(lobe, spectrum_order(f_b, height - 1), p_b, edges)
    enforced = np.asarray(spec.edges[:-1]) >= grazing_limit - 1e-9
    den = error_and_output_by_band(spec, output if output is not None else lighting, 0, p_b)[1]
    part: Any = 0.0
    if exact_part is not None:  # its whole output, read to EXACT_PART_ORDER: a point's error grows with l
        f_part = max(spec.F, min(EXACT_PART_ORDER, exact_part.lmax))
        part_spec = spec if f_part == spec.F else cached_spectrum(lobe, f_part, p_b, edges)
        part = np.sqrt(np.clip(error_and_output_by_band(part_spec, exact_part, 0, p_b)[0], 0.0, None))

    def worst(f: int) -> float:
        num = (np.sqrt(np.clip(error_and_output_by_band(spec, lighting, f, p_b)[0], 0.0, None)) + part) ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = np.where(den > 0.0, num / den, 0.0).max(axis=-1)
        return float(eps[enforced].max())

    if worst(f_b) > epsilon:
        return f_b, False
    lo, hi = 0, f_b  # meets(hi); find the smallest
    while lo < hi:
        mid = (lo + hi) // 2
        if worst(mid) <= epsilon:
            hi = mid
        else:
            lo = mid + 1
    return lo, True


def sun_orders(plan: JobPlan, brdf: Any, original: StoredLighting, residual: StoredLighting, epsilon: float, *,
               height: int, grazing_limit: float | None = None,
               point_error: StoredLighting | None = None) -> list[dict[str, Any]]:
    """Per lobe of ``plan``: its planned (F_B, P_B), the order the output needs with the sun (``original``), the
    order the residual's SHRM needs when the output is the residual's SHRM plus the sun as a point light
    (``order_without_sun``: its error plus ``point_error``'s held to the original output's energy), the order the
    residual needs held to its own output's energy (``order_residual_alone``), and ``factor``, with / without."""
    from relight.settings import SETTINGS
    from relight.shrm import brdf_lobes

    limit = float(grazing_limit if grazing_limit is not None else SETTINGS.grazing_limit)
    if plan.component_plans is None:  # one reflection map: a radially symmetric lobe, P = 0
        lobes = [(brdf, plan.orders.F_B, 0, getattr(brdf, "kind", ""), str(getattr(brdf, "center", "")))]
    else:
        lobes = [(lobe, c.F_B, c.P_B, c.kind, c.center)
                 for lobe, c in zip(brdf_lobes(brdf), plan.component_plans, strict=True)]
    out = []
    for lobe, f_b, p_b, kind, center in lobes:
        kw: dict[str, Any] = {"height": height, "grazing_limit": limit}
        with_sun, met_with = lighting_order(lobe, original, f_b, p_b, epsilon, **kw)
        without, met_without = lighting_order(lobe, residual, f_b, p_b, epsilon, output=original,
                                              exact_part=point_error, **kw)
        alone, met_alone = lighting_order(lobe, residual, f_b, p_b, epsilon, **kw)
        out.append({"kind": kind, "center": center, "F_B": f_b, "P_B": p_b, "order_with_sun": with_sun,
                    "met_with_sun": met_with, "order_without_sun": without, "met_without_sun": met_without,
                    "order_residual_alone": alone, "met_residual_alone": met_alone,
                    "factor": with_sun / max(without, 1)})
    return out


def point_error_lighting(pixels: Any, residual: Any, report: Mapping[str, Any], lmax: int) -> StoredLighting:
    """Luminance band energies (to ``lmax``) of what the sun's point light gets wrong: the removed light
    ``X = Y(pixels) - Y(residual)`` (point masses ``w_k = X_k dOmega_k`` at the pixel centres, as every quadrature
    here reads a map) minus ``E delta(s)``, ``E = sum_k w_k`` its illuminance at ``s`` its direction. By the
    addition theorem ``E^delta_l = E^X_l - 2 E (2l+1)/(4 pi) sum_k w_k P_l(d_k . s) + E^2 (2l+1)/(4 pi)``;
    ``E^X_l`` by the exact-area projection (``relight.sh.project``, ``weights="area"``: the same point sums)."""
    from relight import sh
    from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, pixel_solid_angles

    px = np.asarray(pixels, dtype=np.float64)
    x = (px - np.asarray(residual, dtype=np.float64)) @ LUMINANCE_WEIGHTS
    h, w = x.shape
    e_x = sh.power_spectrum(sh.project(x, lmax, weights="area"), lmax)
    sel = x != 0.0
    wk = (x * pixel_solid_angles(h, w)[:, None])[sel]
    s = np.asarray(report["direction"], dtype=np.float64)
    c = np.clip(latlong_dirs(h, w)[sel] @ (s / np.linalg.norm(s)), -1.0, 1.0)
    e = float(wk.sum())
    cross = np.empty(lmax + 1)  # sum_k w_k P_l(d_k . s)
    cross[0] = e
    p_prev, p_cur = np.ones_like(c), c.copy()  # P_0, P_1; Bonnet's recurrence
    for n in range(1, lmax + 1):
        cross[n] = wk @ p_cur
        p_prev, p_cur = p_cur, ((2 * n + 1) * c * p_cur - n * p_prev) / (n + 1)
    g = (2.0 * np.arange(lmax + 1) + 1.0) / (4.0 * np.pi)
    energies = np.clip(e_x - 2.0 * e * g * cross + e * e * g, 0.0, None)
    return StoredLighting(energies, float(energies.sum()))


def residual_lighting(pixels: Any, lmax: int) -> tuple[StoredLighting, dict[str, Any], StoredLighting]:
    """The residual's stored-form spectrum (luminance band energies to ``lmax``, total energy) after
    ``relight.sun.extract_sun``, the sun's report, and :func:`point_error_lighting`."""
    from relight.prefilter import project_lighting
    from relight.sun import extract_sun

    sun = extract_sun(pixels)
    lit = project_lighting(sun.pixels, lmax)
    return (StoredLighting(lit.band_energy(), float(lit.total_energy)), sun.report,
            point_error_lighting(pixels, sun.pixels, sun.report, lmax))


def plan_job_with_sun(info: Mapping[str, Any], brdf_spec: Any, params: Mapping[str, Any], map_path: str | Path,
                      **kw: Any) -> JobPlan:
    """:func:`relight.planning.job.plan_job`, plus, when ``params["sun"]`` is ``extract`` and the plan has a
    tolerance, its ``sun`` block: the sun's report and :func:`sun_orders` per lobe (the map read from
    ``map_path``, the file the job would decode)."""
    from dataclasses import replace

    from relight.brdf.spec import parse_brdf
    from relight.envmap import read_envmap

    plan = plan_job(info, brdf_spec, params, **kw)
    eps = params.get("epsilon")
    if params.get("sun") != "extract" or eps is None:
        return plan
    env = read_envmap(Path(map_path))
    original = StoredLighting(np.asarray(info["sh_power_spectrum"], dtype=np.float64), float(info["total_energy"]))
    residual, report, point_error = residual_lighting(np.asarray(env.pixels, dtype=np.float64), original.lmax)
    brdf = parse_brdf(brdf_spec)
    lobes = sun_orders(plan, brdf, original, residual, float(eps), height=int(info["height"]),
                       grazing_limit=params.get("grazing_limit"), point_error=point_error)
    return replace(plan, sun={"extracted": report, "epsilon": float(eps), "lobes": lobes})
