"""Result files of a ``visibility`` job, written into the blob store, and the manifest that describes them.

* ``<array>.bin`` for ``ao``, ``visibility``, ``transfer`` (diffuse_transfer) and ``shadow_matrix``
  (shadow_matrix): float16 RGBA data textures indexed by vertex id (``relight.vertex_texture``: ``ceil(n / 4)``
  texels per vertex, row-major, ``width`` texels wide), uploaded with
  ``texImage2D(TEXTURE_2D, 0, RGBA16F, width, height, 0, RGBA, HALF_FLOAT, data)``; the layout of each is in the
  manifest (``files[name].texture``).
* ``visibility.npz``: every per-vertex array as float32 (with the ``*_error`` standard errors), for tools; written
  deterministically (``relight.npz``: sorted members, fixed zip timestamps) so that a recomputed result is
  byte-identical.
* ``manifest.json``: canonical JSON; its digest identifies the result, and the ref ``job-<job id>`` names it (a
  job re-run after a crash finds it instead of computing again, as SHRM results).
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from relight.npz import npz_bytes
from relight.worker.blobs import BlobStore
from relight.worker.results import canonical_json, job_ref

MANIFEST_FORMAT: Final = "relight.visibility-result"
MANIFEST_VERSION: Final = 1
NPZ_NAME: Final = "visibility.npz"
#: Arrays that get a float16 data texture (the rest is in the NPZ only).
TEXTURES: Final = ("ao", "visibility", "transfer", "shadow_matrix")


def write_visibility_result(store: BlobStore, job_id: str, request: dict[str, Any], arrays: dict[str, Any],
                            core: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """Store the textures, the NPZ and the manifest (module docstring); point the job's ref at the manifest.
    ``core`` is ``relight.visibility.run_manifest``. Returns ``(manifest digest, manifest)``."""
    import relight
    from relight.vertex_texture import pack_float16

    files: dict[str, Any] = {}
    for name in TEXTURES:
        if name not in arrays:
            continue
        tex, layout = pack_float16(np.asarray(arrays[name], dtype=np.float32))
        data = np.ascontiguousarray(tex).astype("<f2", copy=False).tobytes()
        files[f"{name}.bin"] = {
            "sha256": store.put_bytes(data), "bytes": len(data), "media_type": "application/octet-stream",
            "dtype": "float16", "byte_order": "little", "texture": layout,
            "webgl": {"target": "TEXTURE_2D", "internalformat": "RGBA16F", "format": "RGBA", "type": "HALF_FLOAT",
                      "width": layout["width"], "height": layout["height"]},
        }
    npz = npz_bytes({k: np.asarray(arrays[k], dtype=np.float32) for k in sorted(arrays)})
    files[NPZ_NAME] = {"sha256": store.put_bytes(npz), "bytes": len(npz), "media_type": "application/x-npz",
                       "dtype": "float32", "arrays": {k: list(np.shape(v)) for k, v in sorted(arrays.items())}}
    manifest: dict[str, Any] = {
        "format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "id": job_id,
        "mesh": request["mesh"], "geometry": request["geometry"],
        "algorithm_version": relight.ALGORITHM_VERSION, "relight_version": relight.__version__,
        **core, "files": files,
    }
    digest = store.put_bytes(canonical_json(manifest))
    store.set_ref(job_ref(job_id), digest)
    return digest, manifest
