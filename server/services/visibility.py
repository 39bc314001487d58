"""Per-vertex visibility and transfer of a mesh as jobs (``POST /visibility``, the ``visibility`` job kind).

The request names a mesh (``POST /meshes``) and the computation (order F, rays per vertex, kind ``visibility`` /
``diffuse_transfer`` / ``shadow_matrix``, bounces, seed, block size); the canonical request adds the digest and
counts of the mesh's ``geometry.bin``, so the job's id (SHA-256 of the kind, algorithm version and request) names
exactly the vertices it computes for. It runs through the one job system (progress, SSE, cancel, the cap,
recovery) with the task :func:`relight.worker.visibility.compute_visibility`; its result is a manifest plus files in
the blob store (``relight.worker.visibility_results``), served verified, and recomputed when one is missing.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from relight.contract.models import JobPublic, JobState, Measurement, Prediction, VisibilityCreate
from relight.server.db import Job, utcnow
from relight.server.problems import Conflict, NotFound
from relight.server.services.base import aware, in_thread
from relight.server.services.jobs import JobService
from relight.server.services.kinds import JobKind, Submission, register
from relight.server.services.meshes import MeshService
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore
from relight.worker.results import job_ref, load_manifest
from relight.worker.visibility import compute_visibility, settings_of

if TYPE_CHECKING:
    from relight.server.state import Services

log = logging.getLogger("relight.server")


def _links(job_id: str, result: dict[str, Any] | None) -> dict[str, str]:
    links = {"result": f"/visibility/{job_id}"}
    for name in (result or {}).get("files") or {}:
        links[name] = f"/visibility/{job_id}/files/{name}"
    return links


def _store_result(row: Job, result: dict[str, Any]) -> None:
    submitted = aware(row.submitted_at) or utcnow()
    errors = result.get("monte_carlo_error_rms") or {}
    main = errors.get("transfer_error", errors.get("visibility_error"))
    row.measured = Measurement(seconds=(utcnow() - submitted).total_seconds(),
                               task_seconds=result.get("task_seconds"),
                               compute_seconds=result.get("compute_seconds"), rms_error=main,
                               reused=bool(result.get("reused")),
                               processes=result.get("block_processes")).model_dump(mode="json")
    row.result_sha256 = result["manifest_sha256"]
    row.result = {k: result[k] for k in ("manifest_sha256", "files", "monte_carlo_error_rms", "reused",
                                         "rays_cast", "mrays_per_second", "block_processes") if k in result}


async def _prepare(create: VisibilityCreate, services: Services) -> Submission:
    return await services.visibility.prepare(create)


VISIBILITY = register(JobKind("visibility", compute_visibility, request=VisibilityCreate, prepare=_prepare,
                              links=_links, store_result=_store_result))


class VisibilityService:
    def __init__(self, jobs: JobService, meshes: MeshService, store: BlobStore) -> None:
        self.jobs = jobs
        self.meshes = meshes
        self.store = store
        jobs.on_requeue.append(self._forget)

    async def _forget(self, job_id: str) -> None:
        await in_thread(self.store.delete_ref, job_ref(job_id))

    async def request(self, create: VisibilityCreate) -> dict[str, Any]:
        """The canonical request of ``create`` (404 for an unknown mesh)."""
        mesh = await self.meshes.get(create.mesh)
        geometry = {"sha256": mesh.geometry["sha256"], "vertices": mesh.vertices, "faces": mesh.faces}
        return {"mesh": mesh.id, "geometry": geometry, **create.model_dump(mode="json", exclude={"mesh"})}

    async def prepare(self, create: VisibilityCreate) -> Submission:
        """The canonical request, the prediction (``relight.visibility.predict``: rays, seconds, Monte Carlo error
        bound) and the integrity check of a stored result; 404 for an unknown mesh."""
        from relight.visibility import predict

        request = await self.request(create)
        await self.meshes.geometry(create.mesh)  # decoded again first if the stored geometry is gone
        pred = predict(settings_of(request), int(request["geometry"]["vertices"]))
        errors = pred["monte_carlo_error_bound"]
        predicted = Prediction(seconds=pred["seconds"],
                               rms_error=errors.get("transfer_error", errors["visibility_error"]),
                               representation=f"per-vertex {create.kind}, order {create.order}, {create.rays} rays"
                               ).model_dump(mode="json")
        return Submission(request, predicted=predicted, intact=self._intact)

    async def submit(self, create: VisibilityCreate) -> tuple[JobPublic, int]:
        sub = await self.prepare(create)
        row, status = await self.jobs.submit(VISIBILITY, sub.request, predicted=sub.predicted, intact=sub.intact)
        return self.jobs.public(row, cached=status == 200 and row.state == JobState.succeeded), status

    async def _intact(self, row: Job) -> bool:
        try:
            manifest = await in_thread(load_manifest, self.store, row.result_sha256 or "")
            for info in manifest["files"].values():
                await in_thread(self.store.verified_path, info["sha256"])
        except (BlobMissing, BlobCorrupt, KeyError, ValueError):
            return False
        return True

    async def manifest(self, job_id: str) -> tuple[str, dict[str, Any]]:
        row = await self.jobs.row(job_id, VISIBILITY.name)
        if row.state != JobState.succeeded or row.result_sha256 is None:
            raise Conflict(f"job {job_id} is {row.state}; it has no result yet", state=row.state)
        try:
            return row.result_sha256, await in_thread(load_manifest, self.store, row.result_sha256)
        except (BlobMissing, BlobCorrupt) as exc:
            await self._recompute(job_id, exc)
            raise AssertionError("unreachable") from exc

    async def file(self, job_id: str, name: str) -> tuple[bytes, str, str]:
        """(verified bytes, digest, media type) of one result file."""
        _, manifest = await self.manifest(job_id)
        info = manifest["files"].get(name)
        if info is None:
            raise NotFound(f"visibility result {job_id} has no file {name!r} (it has {', '.join(manifest['files'])})")
        digest = str(info["sha256"])
        data = self.store.cached_bytes(digest)
        if data is None:
            try:
                data = await in_thread(self.store.load, digest)
            except (BlobMissing, BlobCorrupt) as exc:
                await self._recompute(job_id, exc)
                raise AssertionError("unreachable") from exc
        return data, digest, str(info["media_type"])

    async def _recompute(self, job_id: str, exc: BaseException) -> None:
        await self.jobs.recompute(job_id, exc)  # queued again; 503


__all__ = ["VISIBILITY", "VisibilityService"]
