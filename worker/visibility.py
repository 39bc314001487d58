"""The ``visibility`` job kind's task: per-vertex SH visibility, diffuse transfer or shadow matrix of a stored mesh
(``relight.visibility``), fanned out over the Dask workers by vertex blocks.

:func:`compute_visibility` (run by :func:`relight.worker.progress.run_job`) reads the mesh's canonical
``geometry.bin`` (``relight.mesh.geometry``: the vertices the viewer draws), splits the vertices into blocks of
``block`` and, on a Dask worker, submits one :func:`visibility_block` task per block through
``distributed.worker_client`` (the job's own thread secedes while it waits, so a one-thread worker can run blocks
too); elsewhere (a direct call) it runs the blocks in turn. Every block uses the same seeded directions, so the
result does not depend on how the blocks were spread (tested against a serial ``compute_transfer``). Each worker
process keeps the last meshes and their Embree scenes (:func:`_mesh`), so a block costs its rays, not a BVH build.
Progress is reported per finished block; a cancelled job stops there and cancels its remaining blocks.

The result (``relight.worker.visibility_results``) is content-addressed: float16 per-vertex data textures and a
float32 NPZ, described by a manifest with the Monte Carlo errors.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.worker.blobs import BlobStore
from relight.worker.progress import JobContext, Reporter
from relight.worker.results import existing_result

#: Meshes (with their ray casters) each worker process keeps.
MESH_CACHE = 4


@functools.lru_cache(maxsize=MESH_CACHE)
def _mesh(store_root: str, digest: str, vertices: int, faces: int) -> tuple[Any, Any]:
    from relight.mesh import geometry
    from relight.raycast import RayCaster

    mesh = geometry.from_bytes(BlobStore(store_root).read(digest), vertices, faces, source=f"geometry {digest}")
    return mesh, RayCaster(mesh.positions, mesh.faces)


def settings_of(request: dict[str, Any]) -> Any:
    from relight.visibility import TransferSettings

    return TransferSettings(order=int(request["order"]), rays=int(request["rays"]), kind=request["kind"],
                            bounces=int(request.get("bounces", 0)), albedo=float(request.get("albedo", 0.8)),
                            seed=int(request.get("seed", 0)), block=int(request.get("block", 1024)))


def visibility_block(store_root: str, geometry: dict[str, Any], request: dict[str, Any], start: int, stop: int,
                     previous: NDArray[np.float64] | None = None) -> tuple[dict[str, NDArray[np.float64]], str]:
    """One block of vertices ``start:stop`` (``relight.visibility.transfer_block``; with ``previous`` one bounce)
    and the process that computed it (``host:pid``)."""
    import os
    import socket

    from relight.visibility import transfer_block

    mesh, caster = _mesh(store_root, geometry["sha256"], int(geometry["vertices"]), int(geometry["faces"]))
    arrays = transfer_block(mesh, start, stop, settings_of(request), caster=caster, previous=previous).arrays
    return arrays, f"{socket.gethostname()}:{os.getpid()}"


def _run_blocks(store_root: str, geometry: dict[str, Any], request: dict[str, Any], ranges: list[tuple[int, int]],
                report: Reporter, stage: str, span: tuple[float, float], processes: set[str],
                previous: NDArray[np.float64] | None = None) -> list[Any]:
    """Every block's arrays as ``relight.visibility.Block`` objects, fanned out when running on a Dask worker;
    ``processes`` collects the processes that computed them."""
    from relight.visibility import Block

    lo, hi = span
    done: dict[int, dict[str, NDArray[np.float64]]] = {}
    fanned = False
    if len(ranges) > 1:
        try:
            from distributed import get_worker, worker_client

            get_worker()
            fanned = True
        except (ImportError, ValueError):
            fanned = False
    if fanned:
        import distributed

        as_completed: Any = distributed.as_completed  # untyped

        with worker_client() as client:
            prev = client.scatter(previous, broadcast=True) if previous is not None else None
            prefix = f"relight-visibility-block-{report.job_id}-{report.submission}-{stage}"
            futures = {client.submit(visibility_block, store_root, geometry, request, a, b, prev, pure=False,
                                     key=f"{prefix}-{a}"): k for k, (a, b) in enumerate(ranges)}
            try:
                for fut in as_completed(list(futures)):
                    done[futures[fut]], proc = fut.result()
                    processes.add(proc)
                    report(stage, lo + (hi - lo) * len(done) / len(ranges))
            finally:
                client.cancel([f for f in futures if not f.done()])
    else:
        for k, (a, b) in enumerate(ranges):
            done[k], proc = visibility_block(store_root, geometry, request, a, b, previous)
            processes.add(proc)
            report(stage, lo + (hi - lo) * (k + 1) / len(ranges))
    return [Block(a, b, done[k]) for k, (a, b) in enumerate(ranges)]


def compute_visibility(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    """The ``visibility`` job kind (module docstring). ``request`` (canonical,
    :mod:`relight.server.services.visibility`): ``mesh`` (id), ``geometry`` (its ``geometry.bin`` digest,
    ``vertices``, ``faces``), ``order``, ``rays``, ``kind``, ``bounces``, ``albedo``, ``seed``, ``block``."""
    from relight.visibility import block_ranges, combine, run_manifest
    from relight.worker.visibility_results import write_visibility_result

    t0 = time.perf_counter()
    store, report = ctx.store, ctx.report
    found = existing_result(store, ctx.job_id)
    if found is not None:
        digest, manifest = found
        return {"manifest_sha256": digest, "files": _file_links(manifest), "reused": True,
                "monte_carlo_error_rms": manifest["monte_carlo_error_rms"],
                "task_seconds": time.perf_counter() - t0, "compute_seconds": 0.0}
    settings = settings_of(request)
    geometry = request["geometry"]
    root = str(store.root)
    n_vertices = int(geometry["vertices"])
    ranges = block_ranges(n_vertices, settings.block)
    report("loading", 0.02)
    mesh, _ = _mesh(root, geometry["sha256"], n_vertices, int(geometry["faces"]))
    t_compute = time.perf_counter()
    passes = 1 + settings.bounces
    processes: set[str] = set()
    arrays = combine(_run_blocks(root, geometry, request, ranges, report, "tracing", (0.05, 0.05 + 0.9 / passes),
                                 processes), n_vertices)
    if settings.bounces:
        arrays["direct_transfer"] = arrays["transfer"].copy()
        previous = arrays["transfer"]
        for b in range(settings.bounces):
            span = (0.05 + 0.9 * (b + 1) / passes, 0.05 + 0.9 * (b + 2) / passes)
            bounce = combine(_run_blocks(root, geometry, request, ranges, report, f"bounce {b + 1}", span,
                                         processes, previous), n_vertices)["transfer"]
            arrays["transfer"] = arrays["transfer"] + bounce
            previous = bounce
    compute_seconds = time.perf_counter() - t_compute
    report.check_cancelled()
    report("writing", 0.96)
    manifest_core = run_manifest(mesh, settings, arrays, len(ranges), passes)
    digest, manifest = write_visibility_result(store, ctx.job_id, request, arrays, manifest_core)
    rays = n_vertices * settings.rays * passes
    return {"manifest_sha256": digest, "files": _file_links(manifest), "reused": False,
            "monte_carlo_error_rms": manifest["monte_carlo_error_rms"],
            "task_seconds": time.perf_counter() - t0, "compute_seconds": compute_seconds,
            "rays_cast": rays, "mrays_per_second": rays / compute_seconds / 1e6 if compute_seconds > 0 else None,
            "block_processes": len(processes)}


def _file_links(manifest: dict[str, Any]) -> dict[str, dict[str, str]]:
    return {name: {"sha256": info["sha256"], "media_type": info["media_type"]}
            for name, info in manifest["files"].items()}
