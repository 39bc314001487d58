"""The defects report of a welded mesh: counts, bounds, and what is wrong with it (reported, not refused).

Edges are unordered vertex pairs of the canonical faces. An edge used by one face is a *boundary* edge (the mesh
has a hole there), by more than two a *non-manifold* edge; two faces traversing a shared edge in the same
direction have *inconsistent orientation*. A face is *degenerate* when its area is below ``DEGENERATE_FRACTION``
x the squared bounding-box diagonal (corners that welded together were already dropped: ``collapsed_faces``).
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.intp]

#: Relative area below which a face counts as degenerate: the area of a triangle whose sides are ~1e-6 of the
#: mesh extent (far below any modelled detail, at the float32 resolution of the coordinates).
DEGENERATE_FRACTION: Final = 1e-12
#: At most this many offending items (faces or edges) are listed by index in the report.
LISTED: Final = 20


def edge_counts(faces: IndexArray) -> tuple[IndexArray, IndexArray, int]:
    """Unique undirected edges (E, 2), the number of faces using each, and the number of shared edges whose two
    faces traverse it in the same direction."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    n = int(faces.max()) + 1
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    keys, counts = np.unique(lo * n + hi, return_counts=True)  # 1-D keys: far faster than unique(axis=0)
    edges = np.stack([keys // n, keys % n], axis=1).astype(np.intp)
    # a directed edge appearing twice (same direction) means two faces disagree on orientation
    _, dcounts = np.unique(directed[:, 0] * n + directed[:, 1], return_counts=True)
    inconsistent = int(np.count_nonzero(dcounts > 1))
    return edges, np.asarray(counts, dtype=np.intp), inconsistent


def report(positions: FloatArray, faces: IndexArray, *, input_vertices: int, input_faces: int, merged: int,
           collapsed: int, unreferenced: int, without_normal: int) -> dict[str, Any]:
    """The defects report (module docstring), JSON-ready."""
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    area = 0.5 * np.linalg.norm(np.cross(positions[faces[:, 1]] - positions[faces[:, 0]],
                                         positions[faces[:, 2]] - positions[faces[:, 0]]), axis=1)
    degenerate = np.flatnonzero(area <= DEGENERATE_FRACTION * diag * diag)
    edges, counts, inconsistent = edge_counts(faces)
    boundary = edges[counts == 1]
    nonmanifold = edges[counts > 2]
    centre = 0.5 * (lo + hi)
    return {
        "vertices": int(positions.shape[0]),
        "faces": int(faces.shape[0]),
        "edges": int(edges.shape[0]),
        "input_vertices": int(input_vertices),
        "input_faces": int(input_faces),
        "merged_vertices": int(merged),
        "collapsed_faces": int(collapsed),
        "unreferenced_vertices": int(unreferenced),
        "degenerate_faces": int(degenerate.size),
        "degenerate_face_ids": degenerate[:LISTED].tolist(),
        "boundary_edges": int(boundary.shape[0]),
        "non_manifold_edges": int(nonmanifold.shape[0]),
        "non_manifold_edge_list": nonmanifold[:LISTED].tolist(),
        "inconsistently_oriented_edges": inconsistent,
        "vertices_without_normal": int(without_normal),
        "watertight": bool(boundary.shape[0] == 0 and nonmanifold.shape[0] == 0),
        "euler_characteristic": int(positions.shape[0] - edges.shape[0] + faces.shape[0]),
        "bounds": {"min": lo.tolist(), "max": hi.tolist()},
        "bounding_radius": float(np.linalg.norm(positions - centre, axis=1).max()),
        "surface_area": float(area.sum()),
    }
