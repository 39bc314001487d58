"""What the uploaded resources' services share (environment maps, :mod:`.envmaps`; meshes, :mod:`.meshes`): a row
per upload keyed by the SHA-256 of its bytes, its API model cached in memory (a bounded LRU, ``cachetools``), the
newest-first list, the insert that keeps the first of two concurrent uploads, and the decode task in a worker
process mapped to API problems (a time limit, bad input, a crashed worker).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any, Final, Generic, TypeVar

from cachetools import LRUCache
from distributed.scheduler import KilledWorker
from pydantic import BaseModel
from sqlalchemy import select

from relight.errors import InputError
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.db import Database, Envmap, Mesh
from relight.server.problems import NotFound, Unprocessable
from relight.server.services.base import in_thread
from relight.server.services.metrics import Metrics
from relight.worker.blobs import BlobStore, check_digest

#: The resource tables (same columns: id, name, bytes, info, created_at).
RowT = TypeVar("RowT", Envmap, Mesh)
PublicT = TypeVar("PublicT", bound=BaseModel)

#: API models kept in memory (a few kB each; rows never change once written).
CACHE_SIZE: Final = 4096


class ResourceService(Generic[RowT, PublicT]):
    """Rows of ``table`` shown as ``public(row)``; ``noun`` names the resource in errors ("environment map")."""

    table: type[RowT]
    noun: str

    def __init__(self, settings: Settings, db: Database, store: BlobStore, cluster: Cluster,
                 metrics: Metrics) -> None:
        self.settings = settings
        self.db = db
        self.store = store
        self.cluster = cluster
        self.metrics = metrics
        self._cache: LRUCache[str, PublicT] = LRUCache(maxsize=CACHE_SIZE)

    def _public(self, row: RowT) -> PublicT:
        raise NotImplementedError

    # ------------------------------------------------------------------------------------------------ reading
    def _get_row(self, resource_id: str) -> RowT | None:
        with self.db.session() as s:
            return s.get(self.table, resource_id)

    async def row(self, resource_id: str) -> RowT:
        """The resource's row (404 when there is none)."""
        row = await in_thread(self._get_row, resource_id)
        if row is None:
            raise NotFound(f"no {self.noun} with id {resource_id!r}")
        return row

    async def get(self, resource_id: str) -> PublicT:
        cached = self._cache.get(resource_id)
        if cached is not None:
            return cached
        pub = self._public(await self.row(resource_id))
        self._cache[resource_id] = pub
        return pub

    async def list(self, limit: int) -> list[PublicT]:
        def q() -> list[RowT]:
            with self.db.session() as s:
                return list(s.scalars(select(self.table).order_by(self.table.created_at.desc()).limit(limit)))

        return [self._public(r) for r in await in_thread(q)]

    def known_digest(self, resource_id: str) -> str:
        """``resource_id`` if it is a SHA-256 digest (404 naming the resource otherwise)."""
        try:
            return check_digest(resource_id)
        except ValueError:
            raise NotFound(f"no {self.noun} with id {resource_id!r}") from None

    # ------------------------------------------------------------------------------------------------ writing
    async def _insert(self, row: RowT) -> tuple[PublicT, bool]:
        """Record a decoded upload; the stored resource and whether this call created it (a concurrent upload of
        the same bytes may have been first)."""

        def insert() -> RowT:
            with self.db.session() as s:
                found = s.get(self.table, row.id)
                if found is not None:
                    return found
                s.add(row)
            return row

        stored = await in_thread(insert)
        self.metrics.inc("uploads_total")
        return self._public(stored), stored is row

    async def _decode(self, fut: Any, what: str, on_timeout: Callable[[], Awaitable[None]] | None = None
                      ) -> dict[str, Any]:
        """The result of a worker's decode task ``fut`` within ``decode_timeout_s``: 422 naming ``what`` when it
        overruns (the task cancelled, then ``on_timeout``), when the input is bad, or when the worker crashed."""
        limit = self.settings.decode_timeout_s
        try:
            info: dict[str, Any] = await asyncio.wait_for(fut, limit)
        except TimeoutError:
            await self.cluster.cancel(fut)
            if on_timeout is not None:
                await on_timeout()
            raise Unprocessable(f"decoding {what} took longer than {limit:g} s; it was stopped") from None
        except InputError as exc:
            raise Unprocessable(str(exc)) from None
        except KilledWorker:
            raise Unprocessable(f"decoding {what} crashed the worker process (corrupt data or over the memory "
                                "limit)") from None
        return info


__all__ = ["CACHE_SIZE", "ResourceService"]
