"""Mesh uploads (``POST /meshes``): streamed and size-capped, sniffed, then decoded in a worker process under the
vertex and face caps; the canonical geometry served back (``GET /meshes/{id}``, ``geometry.bin``).

Order of checks (each rejects before the next costs anything; nothing is stored after a rejection):

1. ``Content-Length`` above ``min(max_upload_bytes, max_mesh_bytes)`` -> 413 before reading the body; bytes are
   counted while streaming too.
2. The first bytes (``relight.mesh.sniff``) -> 415 unless GLB, glTF JSON or OBJ text.
3. Decoding (``relight.worker.meshes.analyze_mesh``) in a Dask worker process, under the worker's memory limit and
   ``decode_timeout_s``: the declared vertex and face counts against ``max_mesh_vertices`` / ``max_mesh_faces``
   before any array is built (an OBJ's records counted on the raw bytes, a glTF's accessor counts, a GLB's header
   length against the file), then parsing, welding, normals -> 422 naming what is wrong (a truncated record, an
   index out of range, a NaN coordinate, a lying GLB header, 10^8 declared faces ...).

The id is the SHA-256 of the uploaded bytes. The sample meshes (``Settings.preload_meshes``) are ingested the same
way at start-up from the files ``relight.mesh.sample_file`` gives (the generated bunny-100k as a GLB).
"""

from __future__ import annotations

import uuid
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from relight.contract.models import MeshPublic
from relight.errors import InputError
from relight.mesh.load import SNIFF_BYTES, sniff
from relight.server.db import Mesh
from relight.server.problems import Unprocessable, UnsupportedMediaType
from relight.server.services import uploads
from relight.server.services.base import in_thread, utc
from relight.server.services.resources import ResourceService
from relight.worker import meshes as mesh_tasks
from relight.worker.blobs import BlobCorrupt, BlobMissing

ACCEPTED = "Wavefront OBJ, glTF 2.0 (.gltf with embedded buffers) or GLB"


def _check_mesh_head(head: bytes) -> None:
    if sniff(head) is None:
        raise UnsupportedMediaType(f"unrecognised mesh file (the body starts with {head[:8].hex(' ')}); "
                                   f"accepted formats are {ACCEPTED}")


class MeshService(ResourceService[Mesh, MeshPublic]):
    table = Mesh
    noun = "mesh"

    @property
    def max_bytes(self) -> int:
        return min(self.settings.max_upload_bytes, self.settings.max_mesh_bytes)

    # ------------------------------------------------------------------------------------------------ reading
    def _public(self, row: Mesh) -> MeshPublic:
        links = {"self": f"/meshes/{row.id}", "geometry.bin": f"/meshes/{row.id}/geometry.bin"}
        return MeshPublic(id=row.id, name=row.name, bytes=row.bytes, created_at=utc(row.created_at),
                          links=links, **{k: v for k, v in row.info.items() if k != "decode_seconds"})

    async def geometry(self, mesh_id: str) -> tuple[Path, str]:
        """The verified ``geometry.bin`` of a mesh (derived data: decoded again if it is gone or corrupt)."""
        pub = await self.get(mesh_id)
        digest = str(pub.geometry["sha256"])
        try:
            return await in_thread(self.store.verified_path, digest), digest
        except (BlobMissing, BlobCorrupt):
            await self._analyze(pub.id, pub.name or "mesh")
            return await in_thread(self.store.verified_path, digest), digest

    # ------------------------------------------------------------------------------------------------ upload
    async def ingest_stream(self, chunks: AsyncIterator[bytes], content_length: str | None,
                            name: str | None) -> tuple[MeshPublic, bool]:
        """Store and decode an upload (:func:`relight.server.services.uploads.receive`); the mesh and whether it is
        new (201) or known (200)."""
        async with uploads.receive(self.store, chunks, content_length, cap=self.max_bytes, what="the mesh file",
                                   head_bytes=SNIFF_BYTES, check_head=_check_mesh_head,
                                   limit=f"the mesh size limit of {self.max_bytes} bytes", metrics=self.metrics) as up:
            existing = await in_thread(self._get_row, up.digest)
            if existing is not None and self.store.has(up.digest):
                up.writer.abort()
                return self._public(existing), False
            await in_thread(self.store._install, up.writer.tmp_path, up.digest)
        return await self._ingest_blob(up.digest, up.size, name, known=existing is not None)

    async def _ingest_blob(self, digest: str, size: int, name: str | None, *, known: bool) -> tuple[MeshPublic, bool]:
        """Decode the stored upload ``digest`` and record it; an upload that fails to decode is deleted."""
        try:
            info = await self._analyze(digest, name or "mesh")
        except BaseException:
            if not known:
                await in_thread(self.store.delete, digest)
                self.metrics.inc("uploads_rejected_total")
            raise
        return await self._insert(Mesh(id=digest, name=(name or None) and name[:255], bytes=size, info=info))

    async def ingest_sample(self, sample: str) -> tuple[MeshPublic, bool]:
        """Ingest a sample mesh (``relight.mesh.SAMPLES``) as an upload of its file."""
        fut = self.cluster.submit(mesh_tasks.sample_upload, str(self.store.root), sample,
                                  key=f"relight-mesh-sample-{sample}")
        try:
            filename, digest, size = await fut
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        existing = await in_thread(self._get_row, digest)
        if existing is not None:
            return self._public(existing), False
        return await self._ingest_blob(digest, size, sample, known=False)

    async def _analyze(self, digest: str, name: str) -> dict[str, Any]:
        s = self.settings
        fut = self.cluster.submit(mesh_tasks.analyze_mesh, str(self.store.root), digest, name=name,
                                  max_bytes=self.max_bytes, max_vertices=s.max_mesh_vertices,
                                  max_faces=s.max_mesh_faces, key=f"relight-mesh-{digest}-{uuid.uuid4().hex[:12]}")
        return await self._decode(fut, "the mesh")
