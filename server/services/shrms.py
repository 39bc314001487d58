"""SHRM jobs (``POST /shrms``, the ``shrm`` job kind) and their results: manifests, files, views.

* **Submission.** The request is resolved and planned (:class:`relight.server.services.plans.PlanService`), its
  prediction stored on the job, and the job goes through the one job system
  (:class:`relight.server.services.jobs.JobService`). Its id is
  :func:`relight.server.services.plans.job_id_for` (input digests, canonical parameters, algorithm version).
* **Integrity.** Result files are verified by hash when served; a missing or corrupt one sends the job back to
  ``queued`` (recomputed, 503 meanwhile), never served. A finished job whose result is gone is recomputed when it
  is submitted again.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from cachetools import LRUCache

from relight.contract.models import JobPublic, JobState, Measurement, Orders, Prediction, ShrmCreate, parse_view
from relight.errors import InputError
from relight.server.cluster import Cluster
from relight.server.db import Job, Render, utcnow
from relight.server.problems import Conflict, Unprocessable
from relight.server.services.base import aware, content_id, in_thread
from relight.server.services.envmaps import EnvmapService
from relight.server.services.jobs import JobService
from relight.server.services.kinds import JobKind, Submission, register
from relight.server.services.plans import PlanService
from relight.worker import tasks
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore
from relight.worker.results import job_ref, load_manifest

if TYPE_CHECKING:
    from relight.server.state import Services

log = logging.getLogger("relight.server")

RENDER_TIMEOUT_S: Final = 300.0
#: Manifests kept in memory (each a few kB): one per recently served result.
MANIFEST_CACHE_ITEMS: Final = 1024


def _links(job_id: str, result: dict[str, Any] | None) -> dict[str, str]:
    return {"result": f"/shrms/{job_id}", "coefficients.exr": f"/shrms/{job_id}/coefficients.exr",
            "coefficients.bin": f"/shrms/{job_id}/coefficients.bin"}


def _store_result(row: Job, result: dict[str, Any]) -> None:
    """The manifest's digest is the result ref; the measurements go into ``measured``."""
    orders = (result.get("manifest") or {}).get("orders") or {}
    submitted = aware(row.submitted_at) or utcnow()
    row.measured = Measurement(
        seconds=(utcnow() - submitted).total_seconds(), task_seconds=result.get("task_seconds"),
        compute_seconds=result.get("compute_seconds"), stage_seconds=result.get("timings"),
        rms_error=orders.get("rms_min_of_errors"), rms_bound=orders.get("rms_appendix_b"),
        orders=Orders(F_L=orders.get("F_L"), F_rho=orders.get("F_rho"), F_B=orders.get("F_B", 0),
                      P_B=orders.get("P_B", 0)) if orders else None,
        reused=bool(result.get("reused")),
    ).model_dump(mode="json")
    row.result_sha256 = result["manifest_sha256"]
    row.result = {"manifest_sha256": result["manifest_sha256"], "reused": bool(result.get("reused"))}


async def _prepare(create: ShrmCreate, services: Services) -> Submission:
    return await services.shrms.prepare(create)


SHRM = register(JobKind("shrm", tasks.compute_shrm, request=ShrmCreate, prepare=_prepare, links=_links,
                        store_result=_store_result))


@dataclass(frozen=True)
class ResultFile:
    """A verified result file: its bytes (None for a file too large for the memory cache: served streamed from
    ``path``), digest, media type and where the store keeps it."""

    content: bytes | None
    sha256: str
    media_type: str
    path: Path


class ShrmService:
    def __init__(self, jobs: JobService, plans: PlanService, envmaps: EnvmapService, store: BlobStore,
                 cluster: Cluster) -> None:
        self.jobs = jobs
        self.plans = plans
        self.envmaps = envmaps
        self.store = store
        self.cluster = cluster
        self.db = jobs.db
        self._manifests: LRUCache[str, tuple[str, dict[str, Any]]] = LRUCache(MANIFEST_CACHE_ITEMS)
        jobs.on_requeue.append(self._forget)

    async def _forget(self, job_id: str) -> None:
        self._manifests.pop(job_id, None)
        await in_thread(self.store.delete_ref, job_ref(job_id))

    async def prepare(self, create: ShrmCreate) -> Submission:
        """The canonical request of ``create``, its id (input digests, canonical parameters, algorithm version) and,
        for a new job, the plan's prediction."""
        prep = await self.plans.prepare(create)
        await self.envmaps.input_ok(prep.envmap.id)
        request = {"envmap": prep.envmap.id, "brdf": prep.brdf.id, "brdf_spec": prep.brdf.spec,
                   "params": prep.params}
        predicted = None
        if await self.jobs.find(prep.job_id) is None:
            plan = await self.plans.plan_prepared(prep)
            predicted = Prediction(seconds=plan.predicted_seconds, rms_error=plan.predicted_error.rms_min_of_errors,
                                   orders=plan.orders, representation=plan.representation,
                                   by_view=plan.predicted_error.by_view).model_dump(mode="json")
        return Submission(request, job_id=prep.job_id, predicted=predicted, intact=self._result_intact)

    async def submit(self, create: ShrmCreate) -> tuple[JobPublic, int]:
        """Create (or find) the job for ``create``; returns the job and 202 (work pending) or 200 (finished)."""
        sub = await self.prepare(create)
        row, status = await self.jobs.submit(SHRM, sub.request, job_id=sub.job_id, predicted=sub.predicted,
                                             intact=sub.intact)
        return self.jobs.public(row, cached=status == 200 and row.state == JobState.succeeded), status

    async def _result_intact(self, row: Job) -> bool:
        if row.result_sha256 is None:
            return False
        try:
            manifest = await in_thread(load_manifest, self.store, row.result_sha256)
            for info in manifest["files"].values():
                await in_thread(self.store.verified_path, info["sha256"])
        except (BlobMissing, BlobCorrupt, KeyError, ValueError):
            return False
        self._manifests[row.id] = (row.result_sha256, manifest)
        return True

    async def manifest(self, job_id: str) -> tuple[str, dict[str, Any]]:
        cached = self._manifests.get(job_id)
        if cached is not None:
            return cached
        row = await self.jobs.row(job_id, "shrm")
        if row.state != JobState.succeeded or row.result_sha256 is None:
            raise Conflict(f"job {job_id} is {row.state}; it has no result yet", state=row.state)
        try:
            manifest = await in_thread(load_manifest, self.store, row.result_sha256)
        except (BlobMissing, BlobCorrupt) as exc:
            await self._recompute(job_id, exc)
            raise AssertionError("unreachable") from exc
        self._manifests[job_id] = (row.result_sha256, manifest)
        return row.result_sha256, manifest

    async def _recompute(self, job_id: str, exc: BaseException) -> None:
        self._manifests.pop(job_id, None)
        await self.jobs.recompute(job_id, exc)  # queued again; 503

    async def result_file(self, job_id: str, name: str) -> ResultFile:
        """A result file's verified bytes (held in memory after the first read: one ``stat`` per request)."""
        _, manifest = await self.manifest(job_id)
        info = manifest["files"][name]
        digest = info["sha256"]
        media_type = info.get("media_type", "application/octet-stream")
        data = self.store.cached_bytes(digest)
        if data is not None:
            return ResultFile(data, digest, media_type, self.store.path(digest))
        try:
            if int(info.get("bytes") or 0) > self.store.memory_bytes // 8 or not info.get("bytes"):
                # Large (or of unknown size): hashed once, then streamed from the file, never held whole.
                return ResultFile(None, digest, media_type, await in_thread(self.store.verified_path, digest))
            data = await in_thread(self.store.load, digest)
        except (BlobMissing, BlobCorrupt) as exc:
            await self._recompute(job_id, exc)
            raise AssertionError("unreachable") from exc
        return ResultFile(data, digest, media_type, self.store.path(digest))

    async def reflection(self, job_id: str, view_text: str) -> ResultFile:
        try:
            view = parse_view(view_text)
        except ValueError as exc:
            raise Unprocessable(str(exc)) from None
        manifest_digest, _ = await self.manifest(job_id)
        canon = [round(v, 9) + 0.0 for v in view]
        key = content_id({"manifest": manifest_digest, "view": canon})

        def lookup() -> str | None:
            with self.db.session() as s:
                r = s.get(Render, key)
                return r.sha256 if r else None

        digest = await in_thread(lookup)
        if digest is not None:
            try:
                return ResultFile(await in_thread(self.store.load, digest), digest, "image/x-exr",
                                  self.store.path(digest))
            except (BlobMissing, BlobCorrupt):
                digest = None
        fut = self.cluster.submit(tasks.render_reflection, str(self.store.root), manifest_digest, canon,
                                  key=f"relight-render-{key}")
        try:
            digest = str(await asyncio.wait_for(fut, RENDER_TIMEOUT_S))
        except InputError as exc:
            raise Unprocessable(str(exc)) from None

        def save() -> None:
            with self.db.session() as s:
                if s.get(Render, key) is None:
                    s.add(Render(key=key, job_id=job_id, view=",".join(f"{v:.9g}" for v in canon), sha256=digest))

        await self.jobs.write(save)
        return ResultFile(await in_thread(self.store.load, digest), digest, "image/x-exr", self.store.path(digest))


__all__ = ["SHRM", "ResultFile", "ShrmService"]
