"""In-process fan-out of job updates to server-sent-event streams."""

from __future__ import annotations

import asyncio
from typing import Any

#: Updates a slow stream may lag behind before the oldest are dropped (the latest state always arrives).
QUEUE_SIZE = 64


class EventHub:
    def __init__(self) -> None:
        self._subscribers: dict[str, set[asyncio.Queue[dict[str, Any]]]] = {}

    def subscribe(self, job_id: str) -> asyncio.Queue[dict[str, Any]]:
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(QUEUE_SIZE)
        self._subscribers.setdefault(job_id, set()).add(q)
        return q

    def unsubscribe(self, job_id: str, q: asyncio.Queue[dict[str, Any]]) -> None:
        subs = self._subscribers.get(job_id)
        if subs is not None:
            subs.discard(q)
            if not subs:
                del self._subscribers[job_id]

    def publish(self, job_id: str, payload: dict[str, Any]) -> None:
        for q in self._subscribers.get(job_id, ()):
            if q.full():
                q.get_nowait()
            q.put_nowait(payload)

    def has_subscribers(self, job_id: str) -> bool:
        return job_id in self._subscribers
