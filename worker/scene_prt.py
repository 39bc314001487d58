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
"""

from __future__ import annotations

import dataclasses
import io
import json
from typing import Any, Final

import numpy as np

from relight.planning.report import ObjectResult
from relight.worker.blobs import BlobStore

MANIFEST_FORMAT: Final = "relight.scene-prt"
MANIFEST_VERSION: Final = 1
OCTET: Final = "application/octet-stream"


def _put(store: BlobStore, files: dict[str, dict[str, Any]], name: str, data: bytes, media_type: str = OCTET) -> str:
    digest = store.put_bytes(data)
    files[name] = {"sha256": digest, "bytes": len(data), "media_type": media_type}
    return digest


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
    lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
    manifest = {
        "format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "object": name, "order": int(run["order"]),
        "rays": int(run["rays"]), "monte_carlo_error_rms": run.get("monte_carlo_error_rms"),
        "geometry": {"sha256": geometry_digest, "name": f"{name}.geometry.bin", **lay},
        "bounds": {"min": [float(x) for x in lo], "max": [float(x) for x in hi]},
        "bounding_radius": float(mesh.radius),
        "files": {"transfer.bin": {"sha256": transfer_digest, "name": f"{name}.transfer.bin", "bytes": len(data),
                                   "dtype": "float16", "byte_order": "little", "texture": layout}},
    }
    _put(store, files, f"{name}.prt.json", canonical_json(manifest), "application/json")
    return dataclasses.replace(entry, files=dataclasses.replace(entry.files, prt=f"{name}.prt.json"))
