"""Running a scene plan (seed 000 App. C steps 2–3, eqs. 6, 12): every computation once from the plan's shared
lighting, then per object its SHRM (``relight.shrm_io``), the eq. 12 map for its view and the irradiance coefficients
of Lambertian lobes, and for Lambertian objects on meshes their per-vertex shadowed transfer
(``relight.planning.shadows``, ``<object>.transfer.npz``)."""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, indexing
from relight.brdf.base import RadialLobe
from relight.errors import InputError
from relight.jsonable import jsonable
from relight.planning.report import Computation, ObjectFiles, ObjectResult, SceneResult, ShadowPlan
from relight.planning.scene_plan import Plan, plan_json

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SceneRun:
    """:func:`run_plan`'s answer: the typed result (``result.json``) and, when nothing was written, every object's
    eq. 12 view map, SHRM and (for shadowed objects) diffuse transfer by object name."""

    result: SceneResult
    maps: dict[str, FloatArray] = field(default_factory=dict)
    shrms: dict[str, Any] = field(default_factory=dict)  # relight.shrm.SHRM
    #: per shadowed object, its ``relight.visibility.TransferResult`` (relight.planning.shadows)
    transfers: dict[str, Any] = field(default_factory=dict)
    #: per planner-v2 job id, the core object it computed (``relight.planning.run_jobs``)
    jobs: dict[str, Any] = field(default_factory=dict)


def compute_component(plan: Plan, comp: Computation) -> Any:
    """One computation of a plan as an ``relight.shrm.SHRMComponent`` from the plan's shared lighting (App. C
    steps 2–3: ``B_lmpq = L_lm rho_hat_lpq`` synthesised into the local maps)."""
    from relight.brdf import lpq
    from relight.shrm import SHRMComponent, synthesize_local, terms_for

    choice = plan.choices[plan.keys[comp.id]]
    f_b, p_b, s = comp.F_B, comp.P_B, comp.size
    if choice.structure == "radial":
        coeffs = lpq.brdf_coefficients(choice.lobe, f_b, 0)  # rho_hat_l00 = sqrt(4 pi) rho_l (exact)
    else:
        coeffs = choice.coefficients_to(f_b, p_b)
    rho = coeffs.rho[: f_b + 1, : p_b + 1, : min(coeffs.Q, p_b) + 1]
    terms = terms_for(choice.structure, p_b)  # type: ignore[arg-type]
    maps = synthesize_local(plan.lighting.alm, plan.lighting.lmax, rho, terms, s)
    report = {"center": choice.lobe.center, "structure": choice.structure, "reason": comp.reason,
              "lobe": choice.lobe.spec(), "orders": {"F_B": f_b, "P_B": p_b, "F_rho": comp.F_rho, "F_L": comp.F_L},
              "n_maps": len(terms), "predicted": comp.predicted}
    return SHRMComponent(center=str(choice.lobe.center), structure=choice.structure,  # type: ignore[arg-type]
                         F=f_b, P=p_b, terms=terms, maps=maps, lobe=choice.lobe.spec(), report=report)


def irradiance_coefficients(plan: Plan, comp: Computation) -> list[list[float]]:
    """Real SH coefficients (3 colours x (F + 1)^2) of a Lambertian lobe's output ``E(N) / pi`` times albedo."""
    from relight import sh
    from relight.brdf.coefficients import radial_transfer

    lobe = plan.choices[plan.keys[comp.id]].lobe
    f_b = comp.F_B
    assert isinstance(lobe, RadialLobe)
    transfer = radial_transfer(lobe, f_b).transfer  # (F+1, C)
    alm = sh.truncate(plan.lighting.alm, plan.lighting.lmax, f_b)
    l_idx, _ = indexing.healpy_lm(f_b)
    b = alm * transfer[l_idx].T
    return [[float(x) for x in row] for row in sh.to_real(b, f_b)]


def compute_shadows(shadows: ShadowPlan, mesh: Any, bounces: int = 0, albedo: float = 0.8) -> Any:
    """The diffuse transfer a plan states for an object (``relight.planning.shadows``): a
    ``relight.visibility.TransferResult`` of its mesh (a sample or an uploaded one, ``Plan.meshes``)."""
    from relight.visibility import TransferSettings, compute_transfer

    settings = TransferSettings(order=shadows.order, rays=shadows.rays, kind="diffuse_transfer", bounces=bounces,
                                albedo=albedo)
    return compute_transfer(mesh, settings)


def save_transfer(path: Path, mesh: Any, transfer: Any) -> None:
    """``<object>.transfer.npz``: the arrays of ``relight visibility --out`` (positions, normals, faces, ao,
    visibility, transfer and their errors, manifest), deterministic (``relight.npz``: no timings in the manifest,
    fixed member timestamps)."""
    from relight.npz import without_timings, write_npz

    manifest = json.dumps(without_timings(jsonable(transfer.manifest)), sort_keys=True)
    write_npz(path, {"positions": mesh.positions.astype(np.float32), "normals": mesh.normals.astype(np.float32),
                     "faces": mesh.faces.astype(np.int32), **transfer.arrays, "manifest": np.array(manifest)})


def run_plan(
    plan: Plan, out_dir: str | Path | None = None, *, write: bool = True, preview_size: int = 0
) -> SceneRun:
    """Execute a plan: every computation once from the plan's lighting (projected once, while planning), then per
    object its SHRM, the eq. 12 map for its view (global SHRM) and, if asked, a sphere preview (local SHRM, eq. 6,
    for near viewers).

    Returns the typed result (:class:`relight.planning.report.SceneResult`, also ``result.json`` next to
    ``plan.json`` in ``out_dir``): files, orders, measured seconds per stage next to the predicted ones. With
    ``write=False`` nothing is written and the view maps and SHRMs are returned too (``SceneRun.maps`` and
    ``.shrms``, by object name).
    """
    from relight.shrm import SHRM, reflect, render_sphere

    rep = plan.report
    if plan.lighting is None or plan.lighting.lmax < rep.lighting.F_proj:
        raise InputError("this plan has no lighting to the planned order attached; plan it again with plan_scene")
    out = Path(out_dir) if out_dir is not None else None
    if write:
        if out is None:
            raise InputError("run_plan needs an output folder to write to")
        out.mkdir(parents=True, exist_ok=True)
    # the order search (BRDF coefficients) and the lighting projection ran while planning
    stages: dict[str, float] = {"brdf_coefficients": float(rep.brdf_seconds),
                                "lighting_projection": float(rep.lighting.seconds)}

    def lap(stage: str, t0: float) -> float:
        now = time.perf_counter()
        stages[stage] = stages.get(stage, 0.0) + now - t0
        return now

    t = time.perf_counter()
    comps = {c.id: compute_component(plan, c) for c in rep.computations}
    t = lap("synthesis", t)
    objects: list[ObjectResult] = []
    maps: dict[str, FloatArray] = {}
    shrms: dict[str, Any] = {}
    transfers: dict[str, Any] = {}
    transfers_done: dict[tuple[str, int, int, int, float], Any] = {}
    for o in rep.objects:
        if not o.computations:  # every lobe drawn by a planner-v2 representation (run_jobs below)
            objects.append(ObjectResult(name=o.name, viewer=o.viewer, shrm=o.shrm, output_rows=o.output_rows))
            continue
        shrm = SHRM(components=[comps[i] for i in o.computations], brdf=None, report={
            "representation": "shrm", "layout": "local", "relight_version": __version__,
            "predicted": o.predicted_error.to_json(), "scene": rep.scene, "object": o.name})
        image = reflect(shrm, o.view)
        t = lap("view", t)
        entry = ObjectResult(name=o.name, viewer=o.viewer, shrm=o.shrm, output_rows=o.output_rows)
        irr = [c for c in rep.computations if c.id in o.computations and c.representation == "irradiance"]
        if irr:
            entry = dataclasses.replace(entry, irradiance_real_sh={c.id: irradiance_coefficients(plan, c)
                                                                   for c in irr})
        transfer_file = None
        if o.shadows is not None:
            diffuse = [r for r in o.representations if r.representation == "diffuse_transfer"]
            bounces = max([int(r.terms.get("bounces", 0)) for r in diffuse] + [0])
            # interreflected light is scaled by the surface's albedo (grey: the mean of its channels)
            albedo = float(np.mean(diffuse[0].lobe.get("albedo", 1.0))) if bounces and diffuse else 0.8
            key = (o.shadows.mesh, o.shadows.order, o.shadows.rays, bounces, albedo)
            transfer = transfers_done.get(key)
            if transfer is None:  # one transfer per mesh, order, rays and bounces, shared by its objects
                transfer = compute_shadows(o.shadows, plan.meshes[o.shadows.mesh], bounces, albedo)
                transfers_done[key] = transfer
            entry = dataclasses.replace(entry, shadows={k: transfer.manifest[k] for k in (
                "order", "rays", "vertices", "monte_carlo_error_rms", "seconds")})
            t = lap("shadows", t)
            if write and out is not None:
                path = out / f"{o.name}.transfer.npz"
                save_transfer(path, plan.meshes[o.shadows.mesh], transfer)
                transfer_file = path.name
            else:
                transfers[o.name] = transfer
        if write and out is not None:
            from relight.envmap import write_exr, write_png_preview
            from relight.shrm_io import write_shrm

            shrm_path = out / f"{o.name}.shrm.exr"
            write_shrm(shrm_path, shrm)
            view_path = out / f"{o.name}.view.exr"
            write_exr(view_path, image.astype(np.float32))
            files = ObjectFiles(shrm=shrm_path.name, manifest=shrm_path.with_suffix(".json").name,
                                view_map=view_path.name, transfer=transfer_file)
            if preview_size > 0:
                sphere = render_sphere(shrm, o.view, preview_size, local=o.viewer == "near")
                png = out / f"{o.name}.sphere.png"
                write_png_preview(png, sphere)
                files = dataclasses.replace(files, sphere_png=png.name)
            entry = dataclasses.replace(entry, files=files)
            t = lap("writing", t)
        else:
            maps[o.name] = image
            shrms[o.name] = shrm
        objects.append(entry)
    from relight.planning.run_jobs import run_jobs

    job_runs, job_objects = run_jobs(plan, out if write else None)
    for run in job_runs:
        stages[f"job:{run.kind}"] = stages.get(f"job:{run.kind}", 0.0) + float(run.measured_seconds or 0.0)
    result = SceneResult(
        relight_version=__version__, scene=rep.scene, epsilon=rep.epsilon, objects=objects, jobs=job_runs,
        computed=[c.id for c in rep.computations], lighting_projections=1,
        measured_seconds=float(sum(v for k, v in stages.items() if k != "writing")), measured_stages=stages,
        predicted_seconds=rep.predicted_seconds, predicted_stages=rep.predicted_stages,
    )
    if write and out is not None:
        (out / "plan.json").write_text(plan_json(plan))
        (out / "result.json").write_text(json.dumps(jsonable(result.to_json()), indent=1, allow_nan=False))
    return SceneRun(result, maps, shrms, transfers, {} if write else job_objects)
