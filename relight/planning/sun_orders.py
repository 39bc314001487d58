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
``K_l``), so a bisection finds it. :func:`sun_orders` gives both orders (the map as uploaded and its residual after
``relight.sun.extract_sun``) and their ratio; :func:`plan_job_with_sun` plans a job on a map file with them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from relight.planning.job import JobPlan, StoredLighting, plan_job


def lighting_order(lobe: Any, lighting: StoredLighting, f_b: int, p_b: int, epsilon: float, *, height: int,
                   grazing_limit: float) -> tuple[int, bool]:
    """(order, met): the smallest F <= ``f_b`` whose predicted error under ``lighting`` meets ``epsilon`` in every
    enforced view band (module docstring); (``f_b``, False) when none does."""
    from relight.shrm.creation import spectrum_order
    from relight.shrm.order_search import cached_spectrum
    from relight.shrm.view_bands import predicted_by_view
    from relight.shrm.view_spectrum import band_edges

    spec = cached_spectrum(lobe, spectrum_order(f_b, height - 1), p_b, band_edges(grazing_limit))

    def meets(f: int) -> bool:
        bands = predicted_by_view(spec, lighting, f, p_b, epsilon=epsilon, grazing_limit=grazing_limit)
        return max(b.epsilon for b in bands if b.enforced) <= epsilon

    if not meets(f_b):
        return f_b, False
    lo, hi = 0, f_b  # meets(hi); find the smallest
    while lo < hi:
        mid = (lo + hi) // 2
        if meets(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo, True


def sun_orders(plan: JobPlan, brdf: Any, original: StoredLighting, residual: StoredLighting, epsilon: float, *,
               height: int, grazing_limit: float | None = None) -> list[dict[str, Any]]:
    """Per lobe of ``plan``: its planned (F_B, P_B), the order the output needs with the sun (``original``) and
    without it (``residual``), and their ratio ``factor``."""
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
        with_sun, met_with = lighting_order(lobe, original, f_b, p_b, epsilon, height=height, grazing_limit=limit)
        without, met_without = lighting_order(lobe, residual, f_b, p_b, epsilon, height=height,
                                              grazing_limit=limit)
        out.append({"kind": kind, "center": center, "F_B": f_b, "P_B": p_b, "order_with_sun": with_sun,
                    "met_with_sun": met_with, "order_without_sun": without, "met_without_sun": met_without,
                    "factor": with_sun / max(without, 1)})
    return out


def residual_lighting(pixels: Any, lmax: int) -> tuple[StoredLighting, dict[str, Any]]:
    """The residual's stored-form spectrum (luminance band energies to ``lmax``, total energy) after
    ``relight.sun.extract_sun``, and the sun's report."""
    from relight.prefilter import project_lighting
    from relight.sun import extract_sun

    sun = extract_sun(pixels)
    lit = project_lighting(sun.pixels, lmax)
    return StoredLighting(lit.band_energy(), float(lit.total_energy)), sun.report


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
    residual, report = residual_lighting(np.asarray(env.pixels, dtype=np.float64), original.lmax)
    brdf = parse_brdf(brdf_spec)
    lobes = sun_orders(plan, brdf, original, residual, float(eps), height=int(info["height"]),
                       grazing_limit=params.get("grazing_limit"))
    return replace(plan, sun={"extracted": report, "epsilon": float(eps), "lobes": lobes})
