"""In-process fan-out of job updates to server-sent-event streams.

When the server is asked to stop (SIGTERM), :meth:`EventHub.close` hands every stream :data:`CLOSED`, so open
streams end at once instead of holding uvicorn's graceful shutdown for its whole timeout (and being cancelled with
a traceback); a client reconnects to the next server.
"""

from __future__ import annotations

import asyncio
from typing import Any

#: Updates a slow stream may lag behind before the oldest are dropped (the latest state always arrives).
QUEUE_SIZE = 64
#: The last item of every stream's queue once the hub is closed (compared by identity).
CLOSED: dict[str, Any] = {"closed": True}


class EventHub:
    def __init__(self) -> None:
        self._subscribers: dict[str, set[asyncio.Queue[dict[str, Any]]]] = {}
        self.closed = False

    def subscribe(self, job_id: str) -> asyncio.Queue[dict[str, Any]]:
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(QUEUE_SIZE)
        self._subscribers.setdefault(job_id, set()).add(q)
        if self.closed:
            q.put_nowait(CLOSED)
        return q

    def close(self) -> None:
        """End every stream, present and future (module docstring)."""
        self.closed = True
        for subs in self._subscribers.values():
            for q in subs:
                if q.full():
                    q.get_nowait()
                q.put_nowait(CLOSED)

    def unsubscribe(self, job_id: str, q: asyncio.Queue[dict[str, Any]]) -> None:
        subs = self._subscribers.get(job_id)
        if subs is not None:
            subs.discard(q)
            if not subs:
                del self._subscribers[job_id]

    def publish(self, job_id: str, payload: dict[str, Any]) -> None:
        if self.closed:
            return
        for q in self._subscribers.get(job_id, ()):
            if q.full():
                q.get_nowait()
            q.put_nowait(payload)

    def has_subscribers(self, job_id: str) -> bool:
        return job_id in self._subscribers
