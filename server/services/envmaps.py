"""Environment-map uploads: streamed, size-capped, sniffed, header-checked, then decoded in a worker process.

Order of checks (each rejects before the next costs anything):

1. ``Content-Length`` above the limit -> 413 before reading the body; bytes are counted while streaming too.
2. Magic bytes of the first chunk -> 415 for anything but OpenEXR, Radiance RGBE, PNG or JPEG.
3. Header only (``relight.envmap.probe``: pure Python, allocates nothing) -> 422 for a truncated header, more
   pixels than ``max_pixels`` (``max_stream_pixels`` for a lat-long EXR, which is streamed into a downsample
   within ``max_pixels``: issue 17, item 8) or an aspect that is neither lat-long (2:1) nor a cube-map layout.
4. Decoding (``relight.worker.tasks.analyze_envmap``) in a Dask worker process, under the worker's memory limit and a
   time limit (the worker is restarted if decoding overruns) -> 422 for corrupt data or NaN/Inf texels.

The id is the SHA-256 of the uploaded bytes: uploading the same file twice returns the same map.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from relight.contract.models import EnvmapPublic
from relight.envmap.formats import ACCEPTED, check_max_pixels, sniff
from relight.envmap.formats import SNIFF_BYTES as _SNIFF_BYTES
from relight.errors import InputError
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database, Envmap
from relight.server.problems import (
    NotFound,
    Unavailable,
    Unprocessable,
    UnsupportedMediaType,
)
from relight.server.services import uploads
from relight.server.services.base import in_thread, utc
from relight.server.services.metrics import Metrics
from relight.server.services.resources import ResourceService
from relight.worker import tasks
from relight.worker.blobs import BlobCorrupt, BlobMissing, BlobStore, BlobWriter

log = logging.getLogger("relight.server")



def check_header_size(width: int, height: int, max_pixels: int, max_stream_pixels: int | None = None) -> None:
    """Reject sizes from the header alone (no allocation): too many pixels, or not an environment-map aspect."""
    from relight.envmap import CUBE_LAYOUTS

    pixels = width * height
    if pixels > max_pixels:
        also = "" if max_stream_pixels is None or max_stream_pixels <= max_pixels else (
            f" (lat-long EXR files, width = 2 x height, are streamed up to {max_stream_pixels} pixels)")
        raise Unprocessable(f"image is {width} x {height} = {pixels} pixels; the limit is {max_pixels} pixels{also}",
                            width=width, height=height)
    cube = any(width * b == height * a and width % a == 0 for a, b in CUBE_LAYOUTS.values())
    if width != 2 * height and not cube:
        raise Unprocessable(f"image is {width} x {height}: an environment map must be a lat-long map with width = "
                            "2 x height, or a cube map (6:1 or 1:6 strip, 4:3 or 3:4 cross)")


class EnvmapService(ResourceService[Envmap, EnvmapPublic]):
    table = Envmap
    noun = "environment map"

    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster, metrics: Metrics) -> None:
        super().__init__(settings, db, store, cluster, metrics)
        #: worker address running the analysis of each digest (from its "started" event): restarted on timeout
        self.analysing_on: dict[str, str] = {}

    # ------------------------------------------------------------------------------------------------ reading
    def _public(self, row: Envmap) -> EnvmapPublic:
        return EnvmapPublic(
            id=row.id, name=row.name, bytes=row.bytes, created_at=utc(row.created_at), **row.info,
            links={"self": f"/envmaps/{row.id}", "preview": f"/envmaps/{row.id}/preview.png"},
        )

    async def preview(self, envmap_id: str) -> tuple[Path, str]:
        row = await self.row(envmap_id)
        digest = row.info.get("preview_sha256")
        if digest is None:
            raise NotFound(f"environment map {envmap_id} has no preview")
        try:
            return await in_thread(self.store.verified_path, digest), digest
        except (BlobMissing, BlobCorrupt):
            info = await self._analyze(envmap_id)  # the preview is derived data: make it again
            return await in_thread(self.store.verified_path, info["preview_sha256"]), info["preview_sha256"]

    async def input_ok(self, envmap_id: str) -> None:
        """Raise 503 if the uploaded bytes of a known map are gone or corrupt (they cannot be recomputed)."""
        try:
            await in_thread(self.store.verified_path, envmap_id)
        except (BlobMissing, BlobCorrupt) as exc:
            raise Unavailable(f"the stored bytes of environment map {envmap_id} are unusable ({exc}); upload the "
                              "file again") from exc

    # ------------------------------------------------------------------------------------------------ upload
    async def ingest_stream(self, chunks: AsyncIterator[bytes], content_length: str | None,
                            name: str | None) -> tuple[EnvmapPublic, bool]:
        """Store and analyse an upload (:func:`relight.server.services.uploads.receive`, its type sniffed from the
        first bytes); returns the map and whether it is new (201) or known (200)."""
        async with uploads.receive(self.store, chunks, content_length, cap=self.settings.max_upload_bytes,
                                   what="the image file", head_bytes=_SNIFF_BYTES, check_head=self._check_magic,
                                   metrics=self.metrics) as up:
            return await self._ingest_file(up.writer, up.digest, name)

    def _check_magic(self, head: bytes) -> None:
        if sniff(head) is None:
            raise UnsupportedMediaType(f"unrecognised file type (the body starts with {head[:8].hex(' ')}); "
                                       f"accepted formats are {ACCEPTED}")

    async def ingest_path(self, path: Path) -> tuple[EnvmapPublic, bool]:
        """Ingest a file from disk (preloading the sample maps)."""

        async def chunks() -> AsyncIterator[bytes]:
            with open(path, "rb") as fh:
                while chunk := fh.read(1 << 20):
                    yield chunk

        return await self.ingest_stream(chunks(), None, path.name)

    async def _ingest_file(self, writer: BlobWriter, digest: str, name: str | None) -> tuple[EnvmapPublic, bool]:
        from relight.envmap import probe

        try:
            header = await in_thread(probe, writer.tmp_path)
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        s = self.settings
        # a lat-long EXR above max_pixels is streamed into a downsample within max_pixels (tasks.analyze_envmap):
        # its cap is max_stream_pixels; anything else is decoded whole and capped by max_pixels
        streamed = header.format == "exr" and header.width == 2 * header.height and header.pixels > s.max_pixels
        limit = s.max_stream_pixels if streamed else s.max_pixels
        check_header_size(header.width, header.height, limit, s.max_stream_pixels)
        try:
            check_max_pixels(header, limit)  # every part and level the decoder would allocate
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        existing = await in_thread(self._get_row, digest)
        if existing is not None and self.store.has(digest):
            writer.abort()
            return self._public(existing), False
        await in_thread(self.store._install, writer.tmp_path, digest)
        try:
            info = await self._analyze(digest)
        except BaseException:
            if existing is None:
                self.store.delete(digest)
            raise
        if existing is not None:
            return self._public(existing), False
        return await self._insert(Envmap(id=digest, name=(name or None) and name[:255], bytes=writer.size, info=info))

    async def _analyze(self, digest: str) -> dict[str, Any]:
        s = self.settings
        fut = self.cluster.submit(
            tasks.analyze_envmap, str(self.store.root), digest, key=f"relight-analyze-{digest}-{uuid.uuid4().hex[:12]}",
            max_pixels=s.max_pixels, spectrum_lmax=s.spectrum_lmax, max_stream_pixels=s.max_stream_pixels,
        )

        async def restart() -> None:  # a decoder stuck in C code: restart its worker
            addr = self.analysing_on.pop(f"envmap-{digest}", None)
            if addr is not None:
                await self.cluster.restart_worker(addr)

        try:
            return await self._decode(fut, "the upload", on_timeout=restart)
        finally:
            self.analysing_on.pop(f"envmap-{digest}", None)
