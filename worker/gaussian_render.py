"""The image task behind ``GET /gaussian/render.{png,exr}`` (seed 002: Green, Kautz & Durand 2007, §5, eqs. 5, 7).

:func:`gaussian_image` draws a ``gaussian_fit`` result lit by a ``gaussian_chain`` result on the CPU
(``relight.sg_render``: the reference the GPU shader is tested against): the unit sphere, or -- with a
``visibility`` job's per-vertex SH -- that job's mesh with eq. 7's glossy shadows (``relight.sg_shadow``). It runs
in a worker process because it reads the chain's float16 levels and the mesh from the blob store and casts rays.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from relight.worker.blobs import BlobStore

if TYPE_CHECKING:
    from relight.sg_render import GaussianRenderReport


def chain_from_result(store: BlobStore, result: dict[str, Any]) -> Any:
    """The ``GaussianChain`` of a ``gaussian_chain`` job's result (its float16 level files, as the viewer reads)."""
    from relight.gaussian_chain import ChainLevel, GaussianChain

    levels = []
    for entry in result["levels"]:
        raw = store.read(result["files"][entry["file"]]["sha256"])
        h, w = int(entry["height"]), int(entry["width"])
        half = np.frombuffer(raw, dtype="<f2").reshape(h, w, 3)
        levels.append(ChainLevel(sigma=float(entry["sigma"]), map=half.astype(np.float32), orders=entry["orders"]))
    return GaussianChain(sigma0=float(result["sigma0"]), ratio=float(result["ratio"]), levels=levels)


def gaussian_image(store_root: str, material_spec: dict[str, Any], chain_result: dict[str, Any], view: list[float],
                   size: int, *, geometry: dict[str, Any] | None = None, visibility_npz: str | None = None,
                   mode: str = "none", supersample: int = 2) -> tuple[NDArray[np.float32], GaussianRenderReport]:
    """(size, size, 3) float32 image and its report (mode, unclamped visibility range, vertices)."""
    import io

    from relight.brdf.spec import parse_brdf
    from relight.mesh import geometry as geom
    from relight.sg_render import GaussianRenderReport, render_mesh_gaussian, render_sphere_gaussian

    store = BlobStore(store_root)
    material = parse_brdf(material_spec)
    chain = chain_from_result(store, chain_result)
    v = np.asarray(view, dtype=np.float64)
    if geometry is None:
        image = render_sphere_gaussian(material, chain, v, size, supersample=supersample)  # type: ignore[arg-type]
        return np.asarray(image, dtype=np.float32), GaussianRenderReport(object="sphere")
    mesh = geom.from_bytes(store.read(geometry["sha256"]), int(geometry["vertices"]), int(geometry["faces"]),
                           source=f"geometry {geometry['sha256']}").normalised()
    vis = None
    if mode != "none":
        if visibility_npz is None:
            raise ValueError(f"visibility mode {mode!r} needs a visibility job")
        with np.load(io.BytesIO(store.read(visibility_npz))) as npz:
            vis = np.asarray(npz["visibility"], dtype=np.float64)
    image, report = render_mesh_gaussian(material, chain, mesh, v, size,  # type: ignore[arg-type]
                                         supersample=supersample, visibility=vis, mode=mode)
    return np.asarray(image, dtype=np.float32), dataclasses.replace(report, vertices=mesh.n_vertices)
