"""``geometry.bin``: a welded mesh (``relight.mesh.model.TriangleMesh``) as one little-endian binary blob, the form
the service stores and serves (``GET /meshes/{id}/geometry.bin``) and the visibility jobs read, so that the viewer
draws exactly the vertices the per-vertex data refers to (``docs/conventions.md``, "Meshes").

Layout (:data:`SECTIONS`, in this order, each section starting at a multiple of 4 bytes, no header):
``positions`` float32 (V, 3), ``normals`` float32 (V, 3), ``tangents`` float32 (V, 4), ``indices`` uint32 (F, 3),
all in canonical order. :func:`layout` gives the byte offsets, which the mesh manifest repeats; a WebGL2 viewer
uploads each section as a buffer (``indices`` as the ``ELEMENT_ARRAY_BUFFER``), so ``gl_VertexID`` of an indexed
draw is the canonical vertex id that ``relight.vertex_texture`` indexes.

:func:`from_bytes` rebuilds the :class:`TriangleMesh` (float64 copies of the float32 values; the defects report is
not part of the blob).
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from relight.errors import InputError
from relight.mesh.model import TriangleMesh

#: (name, dtype, values per element), in file order.
SECTIONS: Final = (("positions", "<f4", 3), ("normals", "<f4", 3), ("tangents", "<f4", 4), ("indices", "<u4", 3))


def layout(vertices: int, faces: int) -> dict[str, Any]:
    """Byte offsets and shapes of every section (module docstring), and the total size."""
    offset = 0
    sections: dict[str, Any] = {}
    for name, dtype, width in SECTIONS:
        rows = faces if name == "indices" else vertices
        size = rows * width * 4
        sections[name] = {"offset": offset, "bytes": size, "dtype": "float32" if dtype == "<f4" else "uint32",
                          "shape": [rows, width]}
        offset += size
    return {"vertices": vertices, "faces": faces, "byte_order": "little", "sections": sections, "bytes": offset}


def to_bytes(mesh: TriangleMesh) -> tuple[bytes, dict[str, Any]]:
    """The blob and its :func:`layout`."""
    arrays = {"positions": mesh.positions, "normals": mesh.normals, "tangents": mesh.tangents,
              "indices": mesh.faces}
    parts = [np.ascontiguousarray(arrays[name], dtype=dtype).tobytes() for name, dtype, _ in SECTIONS]
    return b"".join(parts), layout(mesh.n_vertices, mesh.n_faces)


def from_bytes(data: bytes, vertices: int, faces: int, source: str = "geometry.bin") -> TriangleMesh:
    """The mesh a :func:`to_bytes` blob holds (InputError if its size does not match the counts)."""
    lay = layout(vertices, faces)
    if len(data) != lay["bytes"]:
        raise InputError(f"{source}: {len(data)} bytes, but {vertices} vertices and {faces} faces need "
                         f"{lay['bytes']}")
    arr: dict[str, Any] = {}
    for name, dtype, width in SECTIONS:
        sec = lay["sections"][name]
        arr[name] = np.frombuffer(data, dtype=dtype, count=sec["shape"][0] * width,
                                  offset=sec["offset"]).reshape(-1, width)
    idx = arr["indices"].astype(np.intp)
    if idx.size and int(idx.max()) >= vertices:
        raise InputError(f"{source}: vertex index {int(idx.max())} out of range for {vertices} vertices")
    return TriangleMesh(positions=arr["positions"].astype(np.float64), faces=idx,
                        normals=arr["normals"].astype(np.float64), tangents=arr["tangents"].astype(np.float64),
                        tangent_source="geometry.bin", source=source)
