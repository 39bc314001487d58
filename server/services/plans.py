"""Resolving a job request (map, BRDF, canonical parameters, job id) and planning it without computing (with the
machine's cost-model calibration, :mod:`relight.server.services.calibration`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sqlalchemy import select

import relight
from relight.contract.models import (
    BrdfPublic,
    EnvmapPublic,
    JobCreate,
    Orders,
    OutputShape,
    PlanPublic,
    PredictedError,
    SunPlan,
)
from relight.errors import InputError
from relight.server.config import Settings
from relight.server.db import Database, Job
from relight.server.problems import Unavailable, Unprocessable
from relight.server.services.base import content_id, in_thread
from relight.server.services.brdfs import BrdfService
from relight.server.services.calibration import CalibrationService
from relight.server.services.envmaps import EnvmapService
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore
from relight.worker.sandbox import SandboxMemoryError, SandboxPool, SandboxTimeout, busy_then
from relight.worker.specs import to_core


@dataclass(frozen=True)
class Prepared:
    envmap: EnvmapPublic
    brdf: BrdfPublic
    params: dict[str, Any]
    job_id: str


def job_id_for(envmap_id: str, brdf_id: str, params: dict[str, Any]) -> str:
    """SHA-256 of (input digests, canonical parameters, algorithm version): the job's identity."""
    return content_id({
        "task": "prefilter", "algorithm_version": relight.ALGORITHM_VERSION, "envmap": envmap_id, "brdf": brdf_id,
        "params": params,
    })


class PlanService:
    def __init__(self, settings: Settings, db: Database, store: BlobStore, envmaps: EnvmapService,
                 brdfs: BrdfService, calibration: CalibrationService, pool: SandboxPool) -> None:
        self.settings = settings
        self.calibration = calibration
        self.pool = pool
        self.store = store
        self.db = db
        self.envmaps = envmaps
        self.brdfs = brdfs

    def canonical_params(self, create: JobCreate) -> dict[str, Any]:
        """Explicit defaults (epsilon = the core's default when no order is given) and the configured limits."""
        from relight.prefilter import DEFAULT_EPSILON

        s = self.settings
        if create.order is not None and create.order > s.max_order:
            raise Unprocessable(f"order: {create.order} is above this server's limit of {s.max_order}")
        if create.p_order is not None and create.p_order > s.max_p_order:
            raise Unprocessable(f"p_order: {create.p_order} is above this server's limit of {s.max_p_order}")
        if create.size is not None and create.size > s.max_size:
            raise Unprocessable(f"size: {create.size} is above this server's limit of {s.max_size}")
        if create.p_order is not None and create.order is None:
            raise Unprocessable(f"p_order ({create.p_order}) needs an explicit order as well")
        epsilon = create.epsilon
        if epsilon is None and create.order is None:
            epsilon = DEFAULT_EPSILON
        params: dict[str, Any] = {"epsilon": epsilon, "order": create.order, "p_order": create.p_order,
                                  "size": create.size}
        sun = getattr(create, "sun", "keep")  # SHRM jobs only; absent when keep, so earlier job ids stay valid
        if sun != "keep":
            from relight.sun import parse_sun

            try:
                parse_sun(sun)
            except InputError as exc:
                raise Unprocessable(f"sun: {exc}") from None
            params["sun"] = sun
        return params

    async def prepare(self, create: JobCreate) -> Prepared:
        env = await self.envmaps.get(create.envmap)
        brdf = await self.brdfs.resolve(create.brdf)
        params = self.canonical_params(create)
        return Prepared(env, brdf, params, job_id_for(env.id, brdf.id, params))

    async def plan_prepared(self, prep: Prepared, *, sun_orders: bool = False) -> PlanPublic:
        """The plan; ``sun_orders`` (``POST /plan``): with ``sun=extract`` and a tolerance also the order each lobe
        needs with and without the sun (``relight.planning.sun_orders``: the stored map decoded and its sun
        extracted, about a second at 1024 x 512)."""
        from relight.planning import JobPlan, plan_job
        from relight.planning.sun_orders import plan_job_with_sun

        info = prep.envmap.model_dump(mode="json")
        try:
            spec = await in_thread(to_core, prep.brdf.spec, self.store)
            if sun_orders and prep.params.get("sun") == "extract" and prep.params.get("epsilon") is not None:
                path = str(self.store.path(self.store.stored_envmap(prep.envmap.id)))
                raw: JobPlan = await self.pool.run(busy_then, self.settings.plan_test_busy_s, plan_job_with_sun,
                                                   info, spec, prep.params, path,
                                                   timeout=self.settings.plan_timeout_s)
            else:
                raw = await self.pool.run(busy_then, self.settings.plan_test_busy_s, plan_job, info, spec,
                                          prep.params, timeout=self.settings.plan_timeout_s)
        except (InputError, ValueError) as exc:
            raise Unprocessable(str(exc)) from None
        except (BlobMissing, BlobCorrupt) as exc:
            raise Unavailable(f"the measured BRDF file of {prep.brdf.id} is unusable ({exc}); upload it again") \
                from None
        except (SandboxMemoryError, SandboxTimeout) as exc:
            raise Unprocessable(f"planning this request was stopped: {exc}; give explicit orders or a larger "
                                "epsilon") from None
        if not raw.cost_model.calibrated:
            self.calibration.ensure()
        s = self.settings
        f_b, p_b = raw.orders.F_B, raw.orders.P_B
        if f_b > s.max_order:
            raise Unprocessable(f"the tolerance epsilon={prep.params['epsilon']} needs order F = {f_b}, above this "
                                f"server's limit of {s.max_order}; give a larger epsilon or an explicit order")
        if p_b > s.max_p_order:
            raise Unprocessable(f"the tolerance needs view order P = {p_b}, above this server's limit of "
                                f"{s.max_p_order}")
        if raw.size > s.max_size:
            raise Unprocessable(f"the output would have S = {raw.size} rows, above this server's limit of "
                                f"{s.max_size}; give an explicit smaller size")

        out = raw.to_json()["output"]
        out_bytes = max(int(out["height"]) * int(out["width"]) * int(out["layers"]) * 3 * 4,
                        int(out["exr_bytes_estimate"]))  # float32 RGB per layer: what the worker holds and writes
        if out_bytes > s.max_output_bytes:
            raise Unprocessable(f"the output would be {out['layers']} layers of {out['height']} x {out['width']} "
                                f"texels = {out_bytes} bytes, above this server's limit of {s.max_output_bytes} "
                                "bytes; give a smaller size, order or p_order", output_bytes=out_bytes)

        def finished() -> bool:
            with self.db.session() as sess:
                return sess.scalar(select(Job.state).where(Job.id == prep.job_id)) == "succeeded"

        d = raw.to_json()
        return PlanPublic(
            job_id=prep.job_id, cached=await in_thread(finished), representation=raw.representation,
            reason=raw.reason, orders=Orders(**d["orders"]), predicted_error=PredictedError(**d["predicted_error"]),
            predicted_seconds=raw.predicted_seconds, output=OutputShape(**d["output"]), cost_model=d["cost_model"],
            sun=SunPlan(**d["sun"]) if d.get("sun") else None,
        )

    async def plan(self, create: JobCreate) -> PlanPublic:
        return await self.plan_prepared(await self.prepare(create), sun_orders=True)
