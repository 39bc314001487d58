"""Analysis tasks the server submits to Dask workers: the accuracy–time sweep and scenes (task functions of the
``tradeoff`` and ``scene`` job kinds, run by :func:`relight.worker.progress.run_job`), and the cost-model
calibration. Plain functions: plain data in, plain data out; they never import FastAPI.

* :func:`compute_tradeoff` — ``relight.tradeoff.sweep`` on an uploaded map (area-averaged to ``rows``).
* :func:`run_scene` — ``relight.planning``: plan a scene and run it; every output file goes into the blob store and
  the result lists their digests.
* :func:`calibrate_costmodel` — ``relight.costmodel.load_calibration``: calibrates this machine once (a few seconds)
  and caches it in a file, which the server's ``/plan`` then reads.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from relight.jsonable import jsonable as _jsonable
from relight.planning.report import ObjectResult
from relight.worker.blobs import BlobStore
from relight.worker.progress import JobContext
from relight.worker.specs import from_core, to_core

#: Input rows a tradeoff works on unless the request says otherwise (its reference is O(S_L^2 S_B^2)).
TRADEOFF_ROWS = 64
#: Media types of the scene files, by suffix.
MEDIA_TYPES = {".exr": "image/x-exr", ".json": "application/json", ".png": "image/png"}




def _pixels(store: BlobStore, digest: str, max_pixels: int | None, rows: int | None) -> np.ndarray:
    from relight.envmap import read_envmap, resample_latlong

    env = read_envmap(store.read(store.stored_envmap(digest)), max_pixels=max_pixels)
    px = np.asarray(env.pixels, dtype=np.float64)
    if rows is not None and rows < px.shape[0]:
        px = np.asarray(resample_latlong(px, rows), dtype=np.float64)
    return px


def compute_tradeoff(ctx: JobContext, job: dict[str, Any]) -> dict[str, Any]:
    """The ``tradeoff`` job kind: sweep both methods for one (map, BRDF) pair (``relight.tradeoff``).

    ``job`` (the canonical request): ``envmap`` (blob digest), ``brdf`` (service spec), ``params`` (``rows``,
    ``size``, ``epsilons``, ``truncations``, ``view``; None for the defaults). Returns
    ``{"points": [...], "meta": {...}}`` (the CLI's ``tradeoff.json`` and ``tradeoff_meta.json``).
    """
    from relight.brdf.spec import parse_brdf
    from relight.tradeoff import sweep

    store = ctx.store
    params: dict[str, Any] = job.get("params") or {}
    rows = int(params.get("rows") or TRADEOFF_ROWS)
    ctx.report("loading", 0.5)
    px = _pixels(store, job["envmap"], ctx.max_pixels, rows)
    brdf = parse_brdf(to_core(job["brdf"], store))
    ctx.report("sweeping", 0.55)
    kwargs: dict[str, Any] = {}
    if params.get("truncations") is not None:
        kwargs["truncations"] = params["truncations"]
    if params.get("view") is not None:
        kwargs["view"] = params["view"]
    res = sweep(px, brdf, epsilons=params.get("epsilons"), size=params.get("size"), **kwargs)
    ctx.report("storing", 0.95)
    res.meta = dataclasses.replace(res.meta, input=dataclasses.replace(res.meta.input, envmap=job["envmap"]))
    out: dict[str, Any] = _jsonable({"points": [p.to_json() for p in res.points],
                                     "meta": from_core(res.meta.to_json(), store)})
    return out


def run_scene(ctx: JobContext, job: dict[str, Any]) -> dict[str, Any]:
    """The ``scene`` job kind: plan and run a scene (``relight.planning``) on an uploaded map.

    ``job`` (the canonical request): ``scene`` (the scene's JSON form with ``environment`` = the map's digest and
    service BRDF specs) and ``preview_size``. The files of :func:`relight.planning.run_plan` go into the blob store;
    the result maps each file name to its digest and media type; every object with an SHRM also gets its viewer
    texture (:func:`_add_texture`).
    """
    from relight.planning import plan_scene, run_plan, scene_from_dict

    store = ctx.store
    spec = dict(job["scene"])
    spec["objects"] = [{**o, "material": to_core(o["material"], store)} for o in spec["objects"]]
    scene = scene_from_dict(spec)
    ctx.report("loading", 0.5)
    px = _pixels(store, scene.environment, ctx.max_pixels, None)
    ctx.report("planning", 0.55)
    meshes = _uploaded_meshes(store, job.get("meshes") or {})
    plan = plan_scene(scene, px, meshes=meshes)
    files: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="relight-scene-") as tmp:
        ctx.report("running", 0.6)
        result = run_plan(plan, tmp, preview_size=int(job.get("preview_size") or 0)).result
        ctx.report("storing", 0.95)
        for path in sorted(Path(tmp).iterdir()):
            if path.name in ("plan.json", "result.json"):
                continue
            files[path.name] = {"sha256": store.put_file(path), "bytes": path.stat().st_size,
                                "media_type": MEDIA_TYPES.get(path.suffix, "application/octet-stream")}
        objects = [_add_texture(store, Path(tmp) / entry.files.shrm, entry, files) if entry.files.shrm else entry
                   for entry in result.objects]
        objects = [_add_prt(store, plan, Path(tmp), entry, files) if entry.files.transfer else entry
                   for entry in objects]
        jobs = [_add_job_textures(store, plan, Path(tmp), run, files) for run in result.jobs]
        result = dataclasses.replace(result, objects=objects, jobs=jobs)
    out: dict[str, Any] = _jsonable({"plan": from_core(plan.report.to_json(), store),
                                     "result": from_core(result.to_json(), store), "files": files})
    return out


def _uploaded_meshes(store: BlobStore, geometry: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The scene's uploaded meshes by id, from their stored ``geometry.bin`` (``relight.mesh.geometry``: exactly the
    vertices the viewer draws and the transfer is computed for)."""
    from relight.mesh import geometry as mesh_geometry

    return {mesh_id: mesh_geometry.from_bytes(store.read(g["sha256"]), int(g["vertices"]), int(g["faces"]),
                                              source=f"geometry {g['sha256']}")
            for mesh_id, g in geometry.items()}


def _add_prt(store: BlobStore, plan: Any, tmp: Path, entry: ObjectResult,
             files: dict[str, dict[str, Any]]) -> ObjectResult:
    """The viewer's form of an object's diffuse transfer (``relight.worker.scene_prt``), for the plan's mesh."""
    from relight.worker.scene_prt import add_transfer_texture

    shadows = next(o.shadows for o in plan.report.objects if o.name == entry.name)
    assert shadows is not None and entry.files.transfer is not None
    return add_transfer_texture(store, (tmp / entry.files.transfer).read_bytes(), plan.meshes[shadows.mesh], entry,
                                files)


def _add_job_textures(store: BlobStore, plan: Any, tmp: Path, run: Any, files: dict[str, dict[str, Any]]) -> Any:
    """The viewer's form of a planned in-out transport or shadow-matrix transfer (for the plan's mesh) or SH table
    (``relight.worker.scene_prt``); other runs as they are."""
    from relight.worker.scene_prt import add_inout_textures, add_matrix_texture, add_table_texture

    if not run.executed or run.kind not in ("inout_transport", "sh_table", "shadow_matrix"):
        return run
    npz = (tmp / next(f for f in run.files if f.endswith(".npz"))).read_bytes()
    if run.kind == "sh_table":
        return add_table_texture(store, npz, run, files)
    job = next(j for j in plan.report.jobs if j.id == run.id)
    add = add_inout_textures if run.kind == "inout_transport" else add_matrix_texture
    return add(store, npz, plan.meshes[job.params["mesh"]], run, files)


def _add_texture(store: BlobStore, shrm_path: Path, entry: ObjectResult,
                 files: dict[str, dict[str, Any]]) -> ObjectResult:
    """The viewer's form of one object's SHRM: ``{name}.coefficients.bin`` (float16 layers, exactly the
    ``coefficients.bin`` of ``/shrms``) and ``{name}.texture.json`` (a result manifest for it, read by
    ``web/src/layout.js``); both added to the scene's file list, and the object named with them returned."""
    from relight.shrm_io import manifest, read_shrm
    from relight.worker.results import (
        BIN_NAME,
        MANIFEST_FORMAT,
        MANIFEST_VERSION,
        canonical_json,
        layer_entries,
        put_texture,
        strip_volatile,
    )
    from relight.worker.shrm_adapter import shrm_layers

    shrm = read_shrm(shrm_path)
    layers = shrm_layers(shrm)
    bin_name, json_name = f"{entry.name}.coefficients.bin", f"{entry.name}.texture.json"
    texture = put_texture(store, layers)
    files[bin_name] = {"sha256": texture["sha256"], "bytes": texture["bytes"],
                       "media_type": "application/octet-stream"}
    described = strip_volatile(manifest(shrm))
    man = {"format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "id": entry.name,
           "representation": "shrm", "layout": described["layout"], "height": shrm.height, "width": shrm.width,
           "layers": layer_entries(layers), "components": described["components"],
           "files": {BIN_NAME: {**texture, "name": bin_name}}, "object": entry.name}
    data = canonical_json(_jsonable(man))
    files[json_name] = {"sha256": store.put_bytes(data), "bytes": len(data), "media_type": "application/json"}
    return dataclasses.replace(entry, files=dataclasses.replace(entry.files, coefficients_bin=bin_name,
                                                                texture=json_name))


def calibrate_costmodel() -> dict[str, Any]:
    """Calibrate the cost model on this worker's machine unless a cached calibration exists; a summary."""
    from relight import costmodel

    cal = costmodel.load_calibration()
    lo, hi = cal.ratio_range()
    out: dict[str, Any] = _jsonable({"key": cal.key, "calibrated": cal.calibrated, "created": cal.created,
                                     "seconds": cal.calibration_seconds, "ratio_range": [lo, hi]})
    return out
