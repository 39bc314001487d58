"""The service objects of one server process, all created at start-up and closed at shutdown (the app's lifespan,
:func:`relight.server.main.create_app`). Jobs of every kind left queued or running are resumed at start-up."""

from __future__ import annotations

import asyncio
import importlib
import logging
from dataclasses import dataclass, field
from pathlib import Path

from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database
from relight.server.services.base import in_thread
from relight.server.services.brdfs import BrdfService
from relight.server.services.calibration import CalibrationService
from relight.server.services.envmaps import EnvmapService
from relight.server.services.events import EventHub
from relight.server.services.health import HealthMonitor
from relight.server.services.jobs import JobService
from relight.server.services.meshes import MeshService
from relight.server.services.metrics import Metrics
from relight.server.services.plans import PlanService
from relight.server.services.render import RenderService
from relight.server.services.scenes import SceneService
from relight.server.services.shrms import ShrmService
from relight.server.services.tradeoffs import TradeoffService
from relight.server.services.visibility import VisibilityService
from relight.worker.blobs import BlobStore
from relight.worker.progress import TOPIC
from relight.worker.sandbox import SandboxPool
from relight.worker.store_check import clean_tmp

log = logging.getLogger("relight.server")

PRELOAD_SUFFIXES = (".exr", ".hdr", ".png", ".jpg", ".jpeg")
#: Modules that only register job kinds (no service of their own): imported at start-up, before recovery. The
#: kinds with a service (shrm, tradeoff, scene) register when their service's module is imported above.
KIND_MODULES: tuple[str, ...] = ("relight.server.services.sh_tables", "relight.server.services.gaussian",
                                 "relight.server.services.ibl", "relight.server.services.factorizations",
                                 "relight.server.services.inout", "relight.server.services.sh_transfers")


@dataclass
class Services:
    settings: Settings
    db: Database
    store: BlobStore
    cluster: Cluster
    hub: EventHub
    metrics: Metrics
    envmaps: EnvmapService
    brdfs: BrdfService
    plans: PlanService
    jobs: JobService
    shrms: ShrmService
    tradeoffs: TradeoffService
    scenes: SceneService
    render: RenderService
    meshes: MeshService
    visibility: VisibilityService
    calibration: CalibrationService
    health: HealthMonitor
    background: list[asyncio.Task[None]] = field(default_factory=list)

    @classmethod
    async def start(cls, settings: Settings) -> Services:
        for module in (*KIND_MODULES, *settings.job_kind_modules):
            importlib.import_module(module)  # registers its kinds (relight.server.services.kinds.register)
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        db = Database(settings.resolved_database_url)
        migrated = await in_thread(db.create_all)
        if migrated:
            log.warning("moved %d jobs of the previous schema into the job table", migrated)
        store = BlobStore(settings.resolved_blob_dir, memory_bytes=settings.blob_cache_bytes)
        removed = await in_thread(clean_tmp, store)  # left-overs of interrupted writes
        if removed:
            log.warning("removed %d left-over temporary files from the blob store", removed)
        cluster = Cluster(settings)
        await cluster.start()
        hub, metrics = EventHub(), Metrics()
        envmaps = EnvmapService(settings, db, store, cluster, metrics)
        brdfs = BrdfService(settings, db, store)
        calibration = CalibrationService(cluster)
        pool = SandboxPool(settings.plan_workers, settings.plan_memory_bytes)
        plans = PlanService(settings, db, store, envmaps, brdfs, calibration, pool)
        jobs = JobService(settings, db, store, cluster, hub, metrics, envmaps)
        meshes = MeshService(settings, db, store, cluster, metrics)
        shrms = ShrmService(jobs, plans, envmaps, store, cluster)
        self = cls(settings, db, store, cluster, hub, metrics, envmaps, brdfs, plans, jobs, shrms=shrms,
                   tradeoffs=TradeoffService(jobs, envmaps, brdfs), scenes=SceneService(jobs, envmaps, brdfs, meshes),
                   render=RenderService(settings, store, cluster, envmaps, shrms, meshes), meshes=meshes,
                   visibility=VisibilityService(jobs, meshes, store), calibration=calibration,
                   health=HealthMonitor(settings, db, store, cluster))
        await self.health.start()
        jobs.start()
        cluster.subscribe(TOPIC, jobs.on_event)
        await jobs.resume()  # every kind: the kinds registered themselves when their services were imported
        if settings.preload_dir is not None:
            self.background.append(asyncio.create_task(self._preload(settings.preload_dir), name="relight-preload"))
        if settings.preload_meshes:
            self.background.append(asyncio.create_task(self._preload_meshes(settings.preload_meshes),
                                                       name="relight-preload-meshes"))
        return self

    async def _preload(self, directory: Path) -> None:
        from relight.server.problems import ProblemError

        for path in sorted(directory.glob("*")):
            if path.suffix.lower() not in PRELOAD_SUFFIXES or not path.is_file():
                continue
            try:
                env, created = await self.envmaps.ingest_path(path)
                log.info("preloaded %s as %s%s", path.name, env.id, "" if created else " (known)")
            except ProblemError as exc:
                log.warning("preloading %s: %s", path, exc.detail)

    async def _preload_meshes(self, names: list[str]) -> None:
        from relight.server.problems import ProblemError

        for name in names:
            try:
                mesh, created = await self.meshes.ingest_sample(name)
                log.info("preloaded mesh %s as %s%s", name, mesh.id, "" if created else " (known)")
            except ProblemError as exc:
                log.warning("preloading mesh %s: %s", name, exc.detail)

    async def stop(self) -> None:
        for t in self.background:
            t.cancel()
        await asyncio.gather(*self.background, return_exceptions=True)
        await self.health.close()
        await self.jobs.close()
        await self.render.close()
        await self.calibration.close()
        await self.cluster.close()
        self.plans.pool.close()
        self.metrics.gc.stop()
        self.db.dispose()
