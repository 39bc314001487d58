"""Shared helpers for services: database work off the event loop, timestamps, canonical hashing."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any, TypeVar

import anyio.to_thread

from relight.worker.results import canonical_json

T = TypeVar("T")


async def in_thread(fn: Callable[..., T], *args: Any) -> T:
    """Run blocking work (database, file system) in the thread pool."""
    return await anyio.to_thread.run_sync(fn, *args)


def aware(dt: datetime | None) -> datetime | None:
    """SQLite returns naive datetimes; every stored time is UTC."""
    if dt is None or dt.tzinfo is not None:
        return dt
    return dt.replace(tzinfo=UTC)


def utc(dt: datetime) -> datetime:
    """A stored (non-null) time as an aware UTC datetime."""
    return dt if dt.tzinfo is not None else dt.replace(tzinfo=UTC)


def content_id(obj: Any) -> str:
    """SHA-256 of the canonical JSON of ``obj``."""
    return hashlib.sha256(canonical_json(obj)).hexdigest()
