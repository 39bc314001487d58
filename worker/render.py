"""Image tasks behind the viewer's endpoints that the server submits to Dask: thin wrappers over
:mod:`relight.gl.views` that find the uploaded map in the blob store (untrusted bytes are decoded only in a worker
process, docs/facts.md).

* :func:`reference_image` — the angular-domain brute force of the unit sphere for one distant view
  (``relight.gl.views.reference_sphere_image``, seed 000 eqs. 1-2).
* :func:`mesh_reference` — Mitsuba's image of an uploaded mesh under an uploaded map
  (``relight.gl.views.mesh_reference_image``).
* :func:`envmap_texture` — the map as float16 RGB lat-long texels for the viewer's background
  (``relight.gl.views.envmap_texture``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.worker.blobs import BlobStore


def reference_image(store_root: str, envmap_digest: str, brdf_spec: Any, view: list[float], size: int, *,
                    env_rows: int | None, max_pixels: int | None) -> NDArray[np.float32]:
    """(size, size, 3) brute-force image of the sphere lit by the uploaded map ``envmap_digest``."""
    from relight.gl.views import reference_sphere_image

    store = BlobStore(store_root)
    path = str(store.path(store.stored_envmap(envmap_digest)))
    return reference_sphere_image(path, brdf_spec, view, size, env_rows=env_rows, max_pixels=max_pixels)


def mesh_reference(store_root: str, envmap_digest: str, geometry_digest: str, vertices: int, faces: int,
                   view: list[float], size: int, **kw: Any) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Mitsuba's (image, luminance variance) of the mesh whose verified ``geometry.bin`` is ``geometry_digest``."""
    from relight.gl.views import mesh_reference_image

    store = BlobStore(store_root)
    geometry = store.verified_path(geometry_digest).read_bytes()
    envmap = str(store.path(store.stored_envmap(envmap_digest)))
    return mesh_reference_image(envmap, geometry, vertices, faces, view, size, **kw)


def envmap_texture(store_root: str, envmap_digest: str, rows: int, *,
                   max_pixels: int | None) -> tuple[bytes, int, int]:
    """The uploaded map ``envmap_digest`` as little-endian float16 RGB: (bytes, height, width)."""
    from relight.gl.views import envmap_texture as texture

    store = BlobStore(store_root)
    return texture(str(store.path(store.stored_envmap(envmap_digest))), rows, max_pixels=max_pixels)
