"""The viewer's form of a scene object's diffuse transfer (issue 16 item 4: "the viewer draws the whole scene, each
object with its chosen representation"): a Lambertian mesh object whose plan chose ``diffuse_transfer`` has its
per-vertex shadowed transfer in ``{name}.transfer.npz`` (``relight.planning.execute.save_transfer``), which the
browser cannot read. :func:`add_transfer_texture` stores, next to it, exactly what the viewer's PRT object
(``web/src/prt_object.js``) reads for a visibility job:

* ``{name}.transfer.bin``: the ``transfer`` array as a float16 RGBA vertex texture (``relight.vertex_texture``,
  the layout of a visibility job's ``transfer.bin``);
* ``{name}.geometry.bin``: the mesh the transfer was computed for (``relight.mesh.geometry``: canonical vertex
  order, so ``gl_VertexID`` indexes the texture);
* ``{name}.prt.json``: a manifest with both: ``order``, ``geometry`` (``sha256`` and the section layout),
  ``bounds`` and ``bounding_radius`` (for ``TriangleMesh.normalised``'s placement), ``files["transfer.bin"]``
  with its ``texture`` layout, and the transfer's measured Monte Carlo error.

A planned ``inout_transport`` job (seed 004, shared by the objects listed for it) has its transport in
``P.npz``; :func:`add_inout_textures` stores what ``web/src/inout_object.js`` reads for an ``inout_prt`` job:
``P.transport.bin`` (float16 RGBA vertex texture), ``P.factors.bin`` (float32 R32F rows: m, parity, sigma_k h_k),
``P.geometry.bin`` and ``P.inout.json`` (the job's summary: terms, m, parity, sigma, order, ..., with
``transport_texture``, ``factors_texture``, ``geometry``, ``bounds`` and ``bounding_radius``).

A planned ``sh_table`` job (seed 003, one per anisotropic material and order) has its table in ``P.npz``;
:func:`add_table_texture` stores what ``web/src/sh_table.js`` and the scene's ShTablePart read, as the ``sh_table``
job kind stores it (``relight.worker.sh_tables``): ``P.table.bin`` (little-endian float16 ``[(F+1)^2, R, R, C]``,
values beyond 65504 clamped and counted) and ``P.table.json`` (the table's manifest: order, layout, resolution, ...,
with ``files["table.bin"]``: name, shape, dtype, ``float16_clamped``).

A planned ``shadow_matrix`` job (seed 003 §5, shared by the objects on one mesh at one order) has its world-frame
transfer matrices ``T_p`` in ``P.npz``; :func:`add_matrix_texture` stores what the scene's PrtMatrixPart
(``web/src/scene_table_parts.js``) reads, in the layout of the ``visibility`` job kind's ``shadow_matrix.bin``
(``relight.worker.visibility_results``, read by ``web/src/sh_table_data.js`` transferLayout):
``P.shadow_matrix.bin`` (float16 RGBA vertex texture, ``ceil(n^2 / 4)`` texels per vertex, each n x n matrix
row-major), ``P.geometry.bin`` (the plan's mesh: canonical vertex order, so ``gl_VertexID`` indexes the texture) and
``P.prt_matrix.json`` (the job's summary: order, rays, vertices, ..., with ``files["shadow_matrix.bin"]`` and its
``texture`` layout, ``geometry``, ``bounds`` and ``bounding_radius``).
"""

from __future__ import annotations

import dataclasses
import io
import json
from typing import Any, Final

import numpy as np

from relight.planning.report import JobRun, ObjectResult
from relight.worker.blobs import BlobStore

MANIFEST_FORMAT: Final = "relight.scene-prt"
MANIFEST_VERSION: Final = 1
OCTET: Final = "application/octet-stream"


def _put(store: BlobStore, files: dict[str, dict[str, Any]], name: str, data: bytes, media_type: str = OCTET) -> str:
    digest = store.put_bytes(data)
    files[name] = {"sha256": digest, "bytes": len(data), "media_type": media_type}
    return digest


def _placement(mesh: Any) -> dict[str, Any]:
    lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
    return {"bounds": {"min": [float(x) for x in lo], "max": [float(x) for x in hi]},
            "bounding_radius": float(mesh.radius)}


def add_inout_textures(store: BlobStore, npz: bytes, mesh: Any, run: JobRun,
                       files: dict[str, dict[str, Any]]) -> JobRun:
    """Store the viewer's files for one ``inout_transport`` job (module docstring): ``npz`` is its ``P.npz``,
    ``mesh`` the plan's mesh it was computed for. Adds them to ``files`` and returns the run listing them too."""
    from relight.mesh import geometry
    from relight.vertex_texture import pack_float16
    from relight.worker.results import canonical_json

    stem = next(f for f in run.files if f.endswith(".npz"))[: -len(".npz")]
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        transport = np.asarray(z["transport"], dtype=np.float32)
        factors = np.ascontiguousarray(z["factors"], dtype="<f4")
        summary = json.loads(str(z["manifest"]))
    if transport.shape[0] != mesh.n_vertices:
        raise ValueError(f"planned job {run.id}: its transport does not belong to the plan's mesh")
    blob, lay = geometry.to_bytes(mesh)
    names = {k: f"{stem}.{k}" for k in ("geometry.bin", "transport.bin", "factors.bin", "inout.json")}
    digest = _put(store, files, names["geometry.bin"], blob)
    tex, layout = pack_float16(transport)
    _put(store, files, names["transport.bin"], np.ascontiguousarray(tex).astype("<f2", copy=False).tobytes())
    _put(store, files, names["factors.bin"], factors.tobytes())
    manifest = {**summary, "format": "relight.scene-inout", "format_version": MANIFEST_VERSION, "job": run.id,
                "transport_texture": {**layout, "name": names["transport.bin"]},
                "factors_texture": {"width": int(factors.shape[1]), "height": int(factors.shape[0]), "format": "R32F",
                                    "name": names["factors.bin"]},
                "geometry": {"sha256": digest, "name": names["geometry.bin"], **lay}, **_placement(mesh)}
    _put(store, files, names["inout.json"], canonical_json(manifest), "application/json")
    return dataclasses.replace(run, files=[*run.files, *names.values()])


def add_transfer_texture(store: BlobStore, npz: bytes, mesh: Any, entry: ObjectResult,
                         files: dict[str, dict[str, Any]]) -> ObjectResult:
    """Store the viewer's files for one object's diffuse transfer (module docstring): ``npz`` is the bytes of its
    ``{name}.transfer.npz``, ``mesh`` the ``relight.mesh.TriangleMesh`` it was computed for (the plan's). Adds them to
    ``files`` and returns the entry naming them."""
    from relight.mesh import geometry
    from relight.vertex_texture import pack_float16
    from relight.worker.results import canonical_json

    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        transfer = np.asarray(z["transfer"], dtype=np.float32)
        positions = np.asarray(z["positions"], dtype=np.float64)
        run = json.loads(str(z["manifest"]))
    if transfer.shape[0] != mesh.n_vertices or not np.allclose(positions, mesh.positions, atol=1e-5, rtol=1e-6):
        raise ValueError(f"scene object {entry.name}: its transfer does not belong to the plan's mesh")
    name = entry.name
    blob, lay = geometry.to_bytes(mesh)
    geometry_digest = _put(store, files, f"{name}.geometry.bin", blob)
    tex, layout = pack_float16(transfer)
    data = np.ascontiguousarray(tex).astype("<f2", copy=False).tobytes()
    transfer_digest = _put(store, files, f"{name}.transfer.bin", data)
    manifest = {
        "format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "object": name, "order": int(run["order"]),
        "rays": int(run["rays"]), "monte_carlo_error_rms": run.get("monte_carlo_error_rms"),
        "geometry": {"sha256": geometry_digest, "name": f"{name}.geometry.bin", **lay},
        **_placement(mesh),
        "files": {"transfer.bin": {"sha256": transfer_digest, "name": f"{name}.transfer.bin", "bytes": len(data),
                                   "dtype": "float16", "byte_order": "little", "texture": layout}},
    }
    _put(store, files, f"{name}.prt.json", canonical_json(manifest), "application/json")
    return dataclasses.replace(entry, files=dataclasses.replace(entry.files, prt=f"{name}.prt.json"))


def add_table_texture(store: BlobStore, npz: bytes, run: JobRun, files: dict[str, dict[str, Any]]) -> JobRun:
    """Store the viewer's files for one ``sh_table`` job (module docstring): ``npz`` is its ``P.npz``. Adds them to
    ``files`` and returns the run listing them too."""
    from relight.envmap.exr import to_half_safe
    from relight.worker.results import canonical_json

    stem = next(f for f in run.files if f.endswith(".npz"))[: -len(".npz")]
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        coefficients = np.asarray(z["coefficients"], dtype=np.float32)
        summary = json.loads(str(z["manifest"]))
    half, clamped = to_half_safe(coefficients)
    data = np.ascontiguousarray(np.transpose(half, (2, 0, 1, 3)), dtype="<f2")
    names = {k: f"{stem}.{k}" for k in ("table.bin", "table.json")}
    digest = _put(store, files, names["table.bin"], data.tobytes())
    manifest = {**summary, "format": "relight.scene-sh-table", "format_version": MANIFEST_VERSION, "job": run.id,
                "files": {"table.bin": {"name": names["table.bin"], "sha256": digest, "dtype": "float16",
                                        "byte_order": "little", "shape": list(data.shape),
                                        "order": "coefficient, row, column, channel", "float16_clamped": clamped}}}
    _put(store, files, names["table.json"], canonical_json(manifest), "application/json")
    return dataclasses.replace(run, files=[*run.files, *names.values()])


def add_matrix_texture(store: BlobStore, npz: bytes, mesh: Any, run: JobRun,
                       files: dict[str, dict[str, Any]]) -> JobRun:
    """Store the viewer's files for one ``shadow_matrix`` job (module docstring): ``npz`` is its ``P.npz``,
    ``mesh`` the plan's mesh it was computed for. Adds them to ``files`` and returns the run listing them too."""
    from relight.mesh import geometry
    from relight.vertex_texture import pack_float16
    from relight.worker.results import canonical_json

    stem = next(f for f in run.files if f.endswith(".npz"))[: -len(".npz")]
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        matrices = np.asarray(z["shadow_matrix"], dtype=np.float32)
        positions = np.asarray(z["positions"], dtype=np.float64)
        summary = json.loads(str(z["manifest"]))
    if matrices.shape[0] != mesh.n_vertices or not np.allclose(positions, mesh.positions, atol=1e-5, rtol=1e-6):
        raise ValueError(f"planned job {run.id}: its transfer matrices do not belong to the plan's mesh")
    blob, lay = geometry.to_bytes(mesh)
    names = {k: f"{stem}.{k}" for k in ("geometry.bin", "shadow_matrix.bin", "prt_matrix.json")}
    digest = _put(store, files, names["geometry.bin"], blob)
    tex, layout = pack_float16(matrices)
    data = np.ascontiguousarray(tex).astype("<f2", copy=False).tobytes()
    matrix_digest = _put(store, files, names["shadow_matrix.bin"], data)
    keep = ("kind", "order", "coefficients", "rays", "seed", "vertices", "basis", "monte_carlo_error_rms")
    manifest = {**{k: summary[k] for k in keep if k in summary}, "format": "relight.scene-prt-matrix",
                "format_version": MANIFEST_VERSION, "job": run.id,
                "geometry": {"sha256": digest, "name": names["geometry.bin"], **lay}, **_placement(mesh),
                "files": {"shadow_matrix.bin": {"name": names["shadow_matrix.bin"], "sha256": matrix_digest,
                                                "bytes": len(data), "dtype": "float16", "byte_order": "little",
                                                "texture": layout}}}
    _put(store, files, names["prt_matrix.json"], canonical_json(manifest), "application/json")
    return dataclasses.replace(run, files=[*run.files, *names.values()])
