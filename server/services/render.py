"""The render service: one OpenGL context on one dedicated thread and the caches of what it and the workers drew.

A GL context is bound to the thread that made it, so every GL call of the server runs on the service's single
thread; the renderers of the most recent results are kept (their textures are uploaded once). Images, references
and environment textures are kept in a bounded LRU (``cachetools``) keyed by content: result digest, canonical view,
parameters. Created at start-up and closed at shutdown (:class:`relight.server.state.Services`): closing releases the
renderers and the context on their own thread, then stops it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
from collections.abc import Hashable
from typing import Any, Final

import numpy as np
from cachetools import LRUCache

from relight.errors import InputError

#: Images, references and textures kept in memory (a 1024^2 float32 RGB image is 12 MiB; most are 256^2).
IMAGE_CACHE_ITEMS: Final = 64
#: Renderers (GL textures of one result each) kept on the GL thread.
RENDERER_ITEMS: Final = 4


class _Renderers(LRUCache[str, Any]):
    """Renderers by result digest; an evicted one releases its GL objects (on the GL thread, where it is evicted)."""

    def popitem(self) -> tuple[str, Any]:
        key, renderer = super().popitem()
        renderer.release()
        return key, renderer


class RenderService:
    def __init__(self) -> None:
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="relight-gl")
        self._ctx: Any = None
        self._renderers = _Renderers(RENDERER_ITEMS)  # touched on the GL thread only
        self._images: LRUCache[Hashable, Any] = LRUCache(IMAGE_CACHE_ITEMS)
        self._lock = threading.Lock()  # the image cache is read and written from the event loop and threads

    # ------------------------------------------------------------------------------------------------ cache
    def cached(self, key: Hashable) -> Any:
        with self._lock:
            return self._images.get(key)

    def keep(self, key: Hashable, value: Any) -> None:
        with self._lock:
            self._images[key] = value

    # ------------------------------------------------------------------------------------------------ GL
    def _render(self, digest: str, manifest: dict[str, Any], data: bytes, **kw: Any) -> np.ndarray:
        from relight.gl import layout, render

        if self._ctx is None:
            self._ctx = render.create_context()
        r = self._renderers.get(digest)
        if r is None:
            lay = layout.from_manifest(manifest)
            arr = np.frombuffer(data, dtype="<f2")
            if arr.size != lay.num_layers * lay.height * lay.width * 3:
                raise InputError(f"coefficients.bin holds {arr.size} values; the manifest describes "
                                 f"{lay.num_layers} x {lay.height} x {lay.width} x 3")
            r = render.Renderer(lay, arr.reshape(lay.num_layers, lay.height, lay.width, 3), ctx=self._ctx)
            self._renderers[digest] = r
        return np.asarray(r.render(**kw))

    async def render(self, digest: str, manifest: dict[str, Any], data: bytes, **kw: Any) -> np.ndarray:
        """The result ``digest`` drawn by ``relight.gl.render.Renderer.render(**kw)`` on the GL thread."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._pool, lambda: self._render(digest, manifest, data, **kw))

    def _release(self) -> None:
        while self._renderers:
            self._renderers.popitem()
        if self._ctx is not None:
            self._ctx.release()
            self._ctx = None

    async def close(self) -> None:
        await asyncio.get_running_loop().run_in_executor(self._pool, self._release)
        self._pool.shutdown(wait=True)
        with self._lock:
            self._images.clear()
