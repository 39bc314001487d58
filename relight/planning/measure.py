"""Measured errors of a plan's representations against the brute force (issue 16 item 4: "every object's measured
error within its predicted error, or marked approximate with the measured value shown").

:func:`measure_lobes` renders each isotropic lobe of an object on the unit sphere seen from the object's view with
the representation the plan chose, exactly as it would be drawn — the seed-000 maps of :func:`relight.planning
.run_plan`, the plan's own Gaussian-lobe fit (``relight.planning.predict.gaussian_fit``) on a Gaussian chain of the
plan's environment (``relight.sg_render``), or the SH table at the planned order (``relight.sh_render``) — and
compares it with the brute-force angular reference of the same lobe (``relight.reference_view.reference_sphere``,
the untruncated integral over every environment pixel) by relative RMS over the sphere's pixels
(``sqrt(sum |a - ref|^2 / sum |ref|^2)``, RGB). Shadows are not part of this measurement (the sphere is convex);
anisotropic lobes have no brute force here and are not measured.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from relight.planning.scene_plan import Plan


def render_lobe(plan: Plan, name: str, index: int, size: int) -> Any:
    """The object's ``index``-th lobe on the unit sphere (size x size x 3) drawn with its planned representation;
    None for representations without a sphere renderer here (PRT and in-out terms need a mesh)."""
    from relight.brdf.spec import parse_frame_brdf

    o = next(x for x in plan.report.objects if x.name == name)
    r = o.representations[index]
    view = np.asarray(o.view)
    if r.representation in ("irradiance", "reflection_map", "shrm_q0", "shrm"):
        from relight.planning.execute import compute_component
        from relight.shrm import SHRM, render_sphere

        comp = next(c for c in plan.report.computations if c.id == r.computation)
        shrm = SHRM(components=[compute_component(plan, comp)], brdf=None, report={})
        return render_sphere(shrm, view, size, local=o.viewer == "near")
    if r.representation == "gaussian_lobes":
        from relight.gaussian_chain import build_chain
        from relight.planning.predict import CHAIN_RATIO, gaussian_fit
        from relight.sg_render import render_sphere_gaussian

        chain = build_chain(plan.pixels, epsilon=plan.report.epsilon, ratio=CHAIN_RATIO)
        return render_sphere_gaussian(gaussian_fit(r.lobe), chain, view, size)
    if r.representation == "sh_table" and not r.terms.get("anisotropic"):
        from relight.sh_render import environment_coefficients
        from relight.sh_render import render_sphere as table_sphere
        from relight.sh_table import build_table

        f = int(r.terms["F"])
        table = build_table(parse_frame_brdf(r.lobe), order=f, resolution=int(r.terms["resolution"]))
        return table_sphere(table, environment_coefficients(plan.pixels, f), view, size)
    return None


def measure_lobes(plan: Plan, name: str, size: int = 24) -> list[dict[str, Any]]:
    """Per lobe of object ``name``: representation, predicted and measured relative RMS (module docstring)."""
    from relight.brdf.spec import parse_brdf
    from relight.reference_view import reference_sphere
    from relight.shrm import sphere_geometry, unit_view

    o = next(x for x in plan.report.objects if x.name == name)
    out = []
    for i, r in enumerate(o.representations):
        img = render_lobe(plan, name, i, size)
        entry: dict[str, Any] = {"lobe": r.kind, "representation": r.representation, "predicted": r.predicted_error,
                                 "error_kind": r.error_kind, "measured": None}
        if img is not None:
            ref = reference_sphere(plan.pixels, parse_brdf(r.lobe), np.asarray(o.view), size, truncation=0.0)
            _, mask = sphere_geometry(unit_view(np.asarray(o.view)), size)
            d = np.asarray(img)[mask] - ref[mask]
            entry["measured"] = float(np.sqrt(np.sum(d * d) / np.sum(ref[mask] ** 2)))
        out.append(entry)
    return out


def within_prediction(entry: dict[str, Any]) -> bool:
    """Issue 16's rule for one measured lobe (an entry of :func:`measure_lobes` or ``relight.planning.measure_mesh
    .measure_mesh_lobes``): measured, and either within its predicted error or marked ``approximate`` (the measured
    value stands next to the prediction in the entry)."""
    measured = entry["measured"]
    if measured is None:
        return False
    return bool(measured <= entry["predicted"] or entry["error_kind"] == "approximate")
