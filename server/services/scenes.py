"""Scenes as jobs (``POST /scenes``, the ``scene`` job kind of :mod:`relight.server.services.jobs`): store a scene,
plan it and run the plan in a worker (``relight.planning``).

The scene is validated twice before anything runs: by the pydantic model (shapes, ranges, exactly one of a
tolerance or a time budget) and by the core's own parser (``relight.planning.scene_from_dict``: distances beyond the
bounding radius, unique names, every material parsed). Materials are resolved like every BRDF reference of the API
(an id from ``POST /brdfs``, a spec object or a spec string) and stored by their canonical spec, so the scene's id
(the SHA-256 of its canonical form) does not depend on how a material was written. The run's files (one SHRM per
object, as EXR and as the viewer's float16 texture with its manifest; its view map; previews) go into the blob
store; ``GET /scenes/{id}/files/{name}`` serves them verified.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from relight.contract.models import SceneCreate, ScenePublic
from relight.errors import InputError
from relight.server.db import Job
from relight.server.problems import Unprocessable
from relight.server.services import submissions
from relight.server.services.base import aware, in_thread, utc
from relight.server.services.brdfs import BrdfService
from relight.server.services.envmaps import EnvmapService
from relight.server.services.jobs import JobService
from relight.server.services.kinds import JobKind, register
from relight.server.services.meshes import MeshService
from relight.worker.analysis import run_scene
from relight.worker.blobs import DIGEST_RE
from relight.worker.specs import to_core

if TYPE_CHECKING:
    from relight.server.state import Services


def _links(job_id: str, result: dict[str, Any] | None) -> dict[str, str]:
    links = {"result": f"/scenes/{job_id}"}
    for name in ((result or {}).get("files") or {}):
        links[name] = f"/scenes/{job_id}/files/{name}"
    return links


async def _prepare(create: SceneCreate, services: Services) -> dict[str, Any]:
    return await services.scenes.canonical(create)


SCENE = register(JobKind(
    "scene", run_scene, request=SceneCreate, prepare=_prepare,
    result_version=2,  # 2: per-object float16 textures for the viewer ({name}.coefficients.bin, .texture.json)
    links=_links,
))


def _frame_spec(spec: str) -> dict[str, Any]:
    """The canonical spec of a material the BRDF registry refuses because it is anisotropic (a tangent-frame BRDF,
    seed 003): strings only, never one that would make the core open a file."""
    from relight.brdf.spec import parse_frame_brdf
    from relight.worker.specs import check_client_string

    check_client_string(spec)
    out: dict[str, Any] = parse_frame_brdf(spec).spec()
    return out


class SceneService:
    def __init__(self, jobs: JobService, envmaps: EnvmapService, brdfs: BrdfService,
                 meshes: MeshService | None = None) -> None:
        self.jobs = jobs
        self.envmaps = envmaps
        self.brdfs = brdfs
        self.meshes = meshes
        self.store = jobs.store

    def public(self, row: Job) -> ScenePublic:
        result = row.result or {}
        job = self.jobs.public(row)
        links = {"self": f"/scenes/{row.id}", "job": f"/jobs/{row.id}", "events": f"/jobs/{row.id}/events"}
        for name in (result.get("files") or {}):
            links[name] = f"/scenes/{row.id}/files/{name}"
        return ScenePublic(
            id=row.id, state=job.state, stage=job.stage, progress=job.progress, failure_reason=row.failure_reason,
            scene=row.request["scene"], plan=result.get("plan"), result=result.get("result"),
            files=result.get("files"), created_at=utc(row.created_at), finished_at=aware(row.finished_at),
            links=links,
        )

    async def canonical(self, create: SceneCreate) -> dict[str, Any]:
        """The canonical request of ``create``: materials by canonical spec, validated by the core's parser."""
        env = await self.envmaps.get(create.environment)
        await self.envmaps.input_ok(env.id)
        objects = []
        geometry: dict[str, dict[str, Any]] = {}
        for k, obj in enumerate(create.objects):
            try:
                material = (await self.brdfs.resolve(obj.material)).spec
            except Unprocessable as problem:
                if not isinstance(obj.material, str) or DIGEST_RE.match(obj.material):
                    raise
                try:  # anisotropic materials are not registry BRDFs (SHRMs cannot represent them)
                    material = await in_thread(_frame_spec, obj.material)
                except InputError:
                    raise problem from None  # not anisotropic either: the registry's problem names the error
            item: dict[str, Any] = {"name": obj.name or f"object{k}", "size": obj.size, "distance": obj.distance,
                                    "material": material, "shadows": obj.shadows,
                                    "interreflections": obj.interreflections}
            if obj.mesh is not None:
                if self.meshes is None:
                    raise Unprocessable("this server has no mesh service")
                mesh = await self.meshes.get(obj.mesh)  # 404 for an unknown mesh
                await self.meshes.geometry(obj.mesh)  # decoded again first if the stored geometry is gone
                item["mesh"] = mesh.id
                geometry[mesh.id] = {"sha256": mesh.geometry["sha256"], "vertices": mesh.vertices,
                                     "faces": mesh.faces}
            else:
                item["shape"] = obj.shape or "sphere"
            if obj.view is not None:
                item["view"] = obj.view
            if obj.tangent is not None:
                item["tangent"] = obj.tangent.model_dump(mode="json", exclude_none=True)
            objects.append(item)
        scene = {"name": create.name, "environment": env.id, "objects": objects, "epsilon": create.epsilon,
                 "time_budget_s": create.time_budget_s, "size": create.size, "lighting": create.lighting,
                 "material_edits": create.material_edits, "frame_budget_ms": create.frame_budget_ms}

        def check() -> None:  # the core's validation is the authority (distances, names, materials)
            from relight.planning import scene_from_dict

            core = {**scene, "objects": [{**o, "material": to_core(o["material"], self.store)} for o in objects]}
            scene_from_dict(core)

        try:
            await in_thread(check)
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        out: dict[str, Any] = {"scene": scene, "preview_size": create.preview_size}
        if geometry:  # the vertices each uploaded mesh's transfer is computed for (the job id names them)
            out["meshes"] = geometry
        return out

    async def submit(self, create: SceneCreate) -> tuple[ScenePublic, int]:
        row, status = await self.jobs.submit(SCENE, await self.canonical(create))
        return self.public(row), status

    async def get(self, scene_id: str) -> ScenePublic:
        return self.public(await self.jobs.row(scene_id, SCENE.name))

    async def file(self, scene_id: str, name: str) -> tuple[Path, str, str]:
        """(verified path, digest, media type) of one output file of a finished scene."""
        return await submissions.file(self.jobs, scene_id, name, SCENE.name)
