"""Mesh tasks the server submits to Dask workers: decoding an upload (untrusted bytes: only ever in a worker process)
and producing the sample meshes as uploads.

* :func:`analyze_mesh` decodes the uploaded file ``digest`` under the caps (``relight.mesh.model.Caps``: byte,
  vertex and face counts checked before any array is built), welds it into relight's canonical order, computes
  normals, tangents and the defects report, stores ``geometry.bin`` (``relight.mesh.geometry``) and returns the
  mesh's metadata. ``relight.errors.InputError`` for anything malformed (the server answers 422).
* :func:`sample_upload` puts a sample mesh (``relight.mesh.sample_file``: bunny, teapot, the generated bunny-100k)
  into the blob store as the file an upload of it would be.
"""

from __future__ import annotations

import struct
import time
from typing import Any

from relight.errors import InputError
from relight.worker.blobs import BlobStore


def analyze_mesh(store_root: str, digest: str, *, name: str, max_bytes: int, max_vertices: int,
                 max_faces: int) -> dict[str, Any]:
    """Decode, weld and describe the uploaded mesh ``digest`` (module docstring); returns its metadata, with the
    digest and layout of ``geometry.bin``."""
    from relight.mesh import Caps, build, decode, sniff
    from relight.mesh import geometry as geometry_mod

    t0 = time.perf_counter()
    store = BlobStore(store_root)
    data = store.read(digest)
    caps = Caps(max_bytes=max_bytes, max_vertices=max_vertices, max_faces=max_faces)
    fmt = sniff(data[:4096])
    try:
        mesh = build(decode(data, name, caps))
    except InputError:
        raise
    except (ValueError, KeyError, IndexError, TypeError, AttributeError, OverflowError, RecursionError,
            MemoryError, struct.error) as exc:  # a decoder path without its own check: still the file's fault
        raise InputError(f"{name}: malformed mesh file ({type(exc).__name__}: {exc})") from None
    blob, lay = geometry_mod.to_bytes(mesh)
    geometry_digest = store.put_bytes(blob)
    defects = dict(mesh.defects)
    return {
        "format": fmt,
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "bounds": defects.pop("bounds"),
        "bounding_radius": defects.pop("bounding_radius"),
        "surface_area": defects.pop("surface_area"),
        "watertight": defects.pop("watertight"),
        "tangent_source": defects.pop("tangent_source"),
        "normal_weighting": defects.pop("normal_weighting"),
        "defects": {k: v for k, v in defects.items() if k not in ("vertices", "faces")},
        "geometry": {"sha256": geometry_digest, **lay},
        "decode_seconds": time.perf_counter() - t0,
    }


def sample_upload(store_root: str, name: str) -> tuple[str, str, int]:
    """Store the sample mesh ``name`` as an upload: ``(file name, digest, bytes)``."""
    from relight.mesh import sample_file

    filename, data = sample_file(name)
    return filename, BlobStore(store_root).put_bytes(data), len(data)
