"""Running planner v2's jobs (issue 16 item 4): every job of a plan that seed 000's pipeline does not compute
(``relight.planning.execute.run_plan`` computes the SHRMs, irradiance and the Lambertian diffuse transfer), once,
with the same core functions as the service's own job kinds, shared by every object the plan lists for it.

========================  ==================================================================  ====================
plan job kind             core computation (parameters from the plan's job)                   files (``P`` = stem)
========================  ==================================================================  ====================
``gaussian_fit``          the plan's own fit (``relight.planning.predict.gaussian_fit``)      ``P.json`` (the
                                                                                              material's spec),
                                                                                              ``P.lobes.bin``
``gaussian_chain``        ``relight.gaussian_chain.build_chain`` of the plan's map at the     ``P.json``,
                          plan's tolerance and ratio, every level at the plan's ``size``      ``P.level_JJ.bin``
                          (one texture array: the viewer's and ``relight.gl.gaussian``'s)
``sh_table``              ``relight.sh_table.build_table`` (order, resolution)                ``P.npz``
``visibility``,           ``relight.visibility.compute_transfer`` of the object's mesh        ``P.npz``
``shadow_matrix``
``inout_transport``       ``relight.inout_factors.build_factors`` (K terms) and               ``P.npz``
                          ``relight.inout_prt.mesh_transport`` (order, rays, shadows)
========================  ==================================================================  ====================

``P`` is ``job<NN>-<kind>`` in the plan's job order. The binary layouts are the job kinds' (``lobes.bin``: float16
(N, K, 8) = mu, sigma, 0, 0, w_r, w_g, w_b, 0; ``level_JJ.bin``: float16 RGB lat-long H x 2H x 3, row 0 = +Y), so
the viewer reads a scene's job files as it reads the jobs' own. Jobs the plan marks not executed (``executed =
False``: the in-out renderer absent) are listed with the plan's reason and nothing is computed for them.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from relight.jsonable import jsonable
from relight.planning.report import JobRun, PlannedJob
from relight.planning.scene_plan import Plan

#: Job kinds ``run_plan`` computes itself (seed 000's maps and the Lambertian transfer).
SEED000_KINDS = frozenset({"shrm", "diffuse_transfer"})
OCTET = "application/octet-stream"


def _fit(job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    from relight.planning.predict import gaussian_fit

    material = gaussian_fit(job.params["brdf"])
    n, k = material.mu.shape
    tex = np.zeros((n, k, 8), dtype="<f2")
    tex[..., 0], tex[..., 1], tex[..., 4:7] = material.mu, material.sigma, material.weight
    summary = {"lobes": int(k), "elevations": int(n), "errors": [float(e) for e in material.fit["errors"]]}
    return summary, {"json": json.dumps(jsonable(material.spec())).encode(), "lobes.bin": tex.tobytes()}, material


def _chain(plan: Plan, job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    from relight.envmap import to_half_safe
    from relight.gaussian_chain import RATIOS, build_chain

    chain = build_chain(plan.pixels, epsilon=float(job.params["epsilon"]), ratio=RATIOS[job.params["ratio"]],
                        uniform_size=True, size_cap=int(job.params["size"]))
    files: dict[str, bytes] = {}
    levels = []
    for j, lv in enumerate(chain.levels):
        half, _ = to_half_safe(np.asarray(lv.map))
        files[f"level_{j:02d}.bin"] = np.ascontiguousarray(half, dtype="<f2").tobytes()
        levels.append({"file": f"level_{j:02d}.bin", "sigma": lv.sigma, "height": int(lv.map.shape[0]),
                       "width": int(lv.map.shape[1]), "orders": lv.orders})
    summary = {"sigma0": chain.sigma0, "ratio": chain.ratio, "levels": levels}
    files["json"] = json.dumps(jsonable(summary)).encode()
    return summary, files, chain


def _npz(arrays: dict[str, Any]) -> bytes:
    """A deterministic archive (``relight.npz``) whose ``manifest`` member carries no timings: a scene computed
    again stores the same bytes."""
    from relight.npz import npz_bytes, without_timings

    return npz_bytes({**arrays, "manifest": np.array(json.dumps(without_timings(arrays["manifest"]),
                                                                sort_keys=True))})


def _table(job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    from relight.brdf.spec import parse_frame_brdf
    from relight.sh_table import build_table, manifest

    table = build_table(parse_frame_brdf(job.params["brdf"]), order=int(job.params["order"]),
                        resolution=int(job.params["resolution"]))
    man = manifest(table)
    arrays = {"coefficients": table.coefficients.astype(np.float32), "views": table.views, "valid": table.valid,
              "manifest": jsonable(man)}
    return {"order": table.order, "resolution": table.resolution, "layout": table.layout}, {"npz": _npz(arrays)}, table


def _transfer(plan: Plan, job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    from relight.visibility import Kind, TransferSettings, compute_transfer

    mesh = plan.meshes[job.params["mesh"]]
    kind: Kind = "shadow_matrix" if job.kind == "shadow_matrix" else "visibility"
    res = compute_transfer(mesh, TransferSettings(order=int(job.params["order"]), rays=int(job.params["rays"]),
                                                  kind=kind))
    arrays = {"positions": mesh.positions.astype(np.float32), "normals": mesh.normals.astype(np.float32),
              "faces": mesh.faces.astype(np.int32), **res.arrays,
              "manifest": jsonable(res.manifest)}
    summary: dict[str, Any] = {k: res.manifest[k] for k in ("order", "rays", "vertices", "monte_carlo_error_rms")
                               if k in res.manifest}
    return summary, {"npz": _npz(arrays)}, res


def _inout(plan: Plan, job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    from relight.brdf.spec import parse_brdf
    from relight.gl.inout import factor_texture
    from relight.inout_factors import build_factors
    from relight.inout_prt import mesh_transport

    mesh = plan.meshes[job.params["mesh"]]
    factors = build_factors(parse_brdf(job.params["brdf"]), terms=int(job.params["terms"]))
    order = int(job.params["order"])
    out = mesh_transport(mesh, factors, order, rays=int(job.params["rays"]))
    err = out["transport_error"].reshape(mesh.n_vertices, -1)
    summary = {**factors.manifest(), "order": order, "rays": int(job.params["rays"]), "vertices": mesh.n_vertices,
               "monte_carlo_error_rms": float(np.sqrt(np.mean(np.sum(err * err, axis=1))))}
    arrays = {"transport": out["transport"].astype(np.float32), "transport_error": out["transport_error"]
              .astype(np.float32), "factors": factor_texture(factors), "positions": mesh.positions.astype(np.float32),
              "normals": mesh.normals.astype(np.float32), "faces": mesh.faces.astype(np.int32),
              "manifest": jsonable(summary)}
    return summary, {"npz": _npz(arrays)}, {"factors": factors, **out}


def compute_job(plan: Plan, job: PlannedJob) -> tuple[dict[str, Any], dict[str, bytes], Any]:
    """One planned job (module table): its summary, its files (suffix -> bytes) and the core object computed."""
    if job.kind == "gaussian_fit":
        return _fit(job)
    if job.kind == "gaussian_chain":
        return _chain(plan, job)
    if job.kind == "sh_table":
        return _table(job)
    if job.kind in ("visibility", "shadow_matrix"):
        return _transfer(plan, job)
    if job.kind == "inout_transport":
        return _inout(plan, job)
    raise ValueError(f"no computation for planned job kind {job.kind!r}")


def run_jobs(plan: Plan, out_dir: str | Path | None = None) -> tuple[list[JobRun], dict[str, Any]]:
    """Compute every planner-v2 job of ``plan`` once (module docstring). With ``out_dir`` the files are written
    there (``P.<suffix>``, ``P.json`` for a bare ``json`` suffix); returns the per-job records and, by job id, the
    core objects computed (a fit's ``GaussianLobes``, a ``GaussianChain``, an ``SHTable``, a ``TransferResult``,
    the in-out factors with their transport)."""
    if plan.pixels is None:
        from relight.errors import InputError

        raise InputError("this plan has no environment attached; plan it again with plan_scene")
    out = Path(out_dir) if out_dir is not None else None
    runs: list[JobRun] = []
    objects: dict[str, Any] = {}
    for n, job in enumerate(plan.report.jobs):
        if job.kind in SEED000_KINDS:
            continue
        stem = f"job{n:02d}-{job.kind}"
        if not job.executed:
            runs.append(JobRun(id=job.id, kind=job.kind, shared_by=list(job.shared_by), executed=False,
                               predicted_seconds=job.predicted_seconds))
            continue
        t0 = time.perf_counter()
        summary, files, obj = compute_job(plan, job)
        seconds = time.perf_counter() - t0
        names = []
        for suffix, data in files.items():
            name = f"{stem}.{suffix}"
            names.append(name)
            if out is not None:
                (out / name).write_bytes(data)
        objects[job.id] = obj
        runs.append(JobRun(id=job.id, kind=job.kind, shared_by=list(job.shared_by), executed=True, files=names,
                           summary=jsonable(summary), measured_seconds=seconds,
                           predicted_seconds=job.predicted_seconds))
    return runs, objects
