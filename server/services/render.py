"""The render service: one OpenGL context on one dedicated thread, the images the workers draw, and the caches of
both (the logic behind ``server/api/routes/render.py``).

* :meth:`RenderService.view` — a result drawn by ``relight.gl.render.Renderer`` on the GL thread. A GL context is
  bound to the thread that made it, so every GL call of the server runs on the service's single thread; the
  renderers of the most recent results are kept (their textures are uploaded once).
* :meth:`RenderService.reference` / :meth:`RenderService.mesh_reference` / :meth:`RenderService.texture` — the
  brute-force reference of an SHRM, Mitsuba's image of a mesh and the background texture, computed in a worker
  (:mod:`relight.worker.render`: they decode the uploaded map).

Images, references and environment textures are kept in a bounded LRU (``cachetools``) keyed by content: result
digest, canonical view, parameters. Created at start-up and closed at shutdown (:class:`relight.server.state
.Services`): closing releases the renderers and the context on their own thread, then stops it.
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
from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.server.problems import Unavailable, Unprocessable
from relight.server.services.base import content_id, in_thread
from relight.server.services.envmaps import EnvmapService
from relight.server.services.meshes import MeshService
from relight.server.services.shrms import ShrmService
from relight.worker import render as tasks
from relight.worker.blobs import BlobStore

#: Images, references and textures kept in memory (a 1024^2 float32 RGB image is 12 MiB; most are 256^2).
IMAGE_CACHE_ITEMS: Final = 64
#: Renderers (GL textures of one result each) kept on the GL thread.
RENDERER_ITEMS: Final = 4
REFERENCE_TIMEOUT_S: Final = 300.0
TEXTURE_TIMEOUT_S: Final = 120.0
#: Default resampling of the map for the reference: 4 (F_B + 1) rows keeps every band the result holds (a box
#: filter of that pixel size attenuates band F_B by under 3 %), at least 64, never above the map's own rows.
REFERENCE_ROWS_PER_BAND, REFERENCE_MIN_ROWS = 4, 64


class _Renderers(LRUCache[str, Any]):
    """Renderers by result digest; an evicted one releases its GL objects (on the GL thread, where it is evicted)."""

    def popitem(self) -> tuple[str, Any]:
        key, renderer = super().popitem()
        renderer.release()
        return key, renderer


class RenderService:
    def __init__(self, settings: Settings, store: BlobStore, cluster: Cluster, envmaps: EnvmapService,
                 shrms: ShrmService, meshes: MeshService) -> None:
        self.settings = settings
        self.store = store
        self.cluster = cluster
        self.envmaps = envmaps
        self.shrms = shrms
        self.meshes = meshes
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

    # ------------------------------------------------------------------------------------------------ endpoints
    async def view(self, shrm_id: str, view: list[float], **kw: Any) -> np.ndarray:
        """The result ``shrm_id`` drawn for the canonical ``view`` (``size``, ``obj``, ``mode``, ``env_rotation``:
        ``relight.gl.render.Renderer.render``); 503 without an OpenGL context."""
        digest, manifest = await self.shrms.manifest(shrm_id)
        key = ("render", digest, tuple(view), *sorted(kw.items()))
        image: np.ndarray | None = self.cached(key)
        if image is None:
            f = await self.shrms.result_file(shrm_id, "coefficients.bin")
            data = await in_thread(f.path.read_bytes)
            try:
                image = await self.render(digest, manifest, data, view=view, **kw)
            except RuntimeError as exc:
                raise Unavailable(f"no OpenGL context on this server: {exc}") from None
            except InputError as exc:
                raise Unprocessable(str(exc)) from None
            self.keep(key, image)
        return image

    async def reference(self, shrm_id: str, view: list[float], size: int,
                        env_rows: int | None) -> tuple[np.ndarray, int]:
        """The brute-force image of the sphere for the result's map and BRDF, and the map rows it was computed at
        (default: :data:`REFERENCE_ROWS_PER_BAND` (F_B + 1), at least :data:`REFERENCE_MIN_ROWS`)."""
        digest, manifest = await self.shrms.manifest(shrm_id)
        envmap_id = self.envmaps.known_digest(str(manifest.get("envmap", "")))
        if env_rows is None:
            f_b = int((manifest.get("orders") or {}).get("F_B") or 32)
            env_rows = max(REFERENCE_MIN_ROWS, REFERENCE_ROWS_PER_BAND * (f_b + 1))
        env_rows = min(env_rows, int((manifest.get("input") or {}).get("height") or env_rows))
        key = ("reference", digest, tuple(view), size, env_rows)
        image = self.cached(key)
        if image is None:
            await self.envmaps.input_ok(envmap_id)
            image = np.asarray(await self._in_worker(
                "brute-force reference", tasks.reference_image, str(self.store.root), envmap_id,
                manifest.get("brdf"), view, size, key=f"relight-reference-{content_id(list(key))}",
                env_rows=env_rows, max_pixels=self.settings.max_pixels))
            self.keep(key, image)
        return image, env_rows

    async def mesh_reference(self, mesh_id: str, envmap_id: str, view: list[float], size: int, *, spp: int,
                             albedo: float, max_depth: int, rotation: float,
                             env_rows: int) -> tuple[np.ndarray, np.ndarray]:
        """Mitsuba's image of the mesh under the map and its per-pixel luminance variance
        (``relight.gl.views.mesh_reference_image``), computed in a worker (it decodes the uploaded map)."""
        await self.envmaps.get(envmap_id)  # 404 for an unknown map
        mesh = await self.meshes.get(mesh_id)
        _, geometry = await self.meshes.geometry(mesh_id)
        key = ("mesh-reference", geometry, envmap_id, tuple(view), size, spp, albedo, max_depth, rotation, env_rows)
        cached: tuple[np.ndarray, np.ndarray] | None = self.cached(key)
        if cached is None:
            await self.envmaps.input_ok(envmap_id)
            rgb, var = await self._in_worker(
                "Mitsuba reference", tasks.mesh_reference, str(self.store.root), envmap_id, geometry, mesh.vertices,
                mesh.faces, view, size, key=f"relight-mesh-reference-{content_id(list(key))}", spp=spp,
                albedo=albedo, max_depth=max_depth, env_rotation=rotation, env_rows=env_rows,
                max_pixels=self.settings.max_pixels)
            cached = (np.asarray(rgb), np.asarray(var))
            self.keep(key, cached)
        return cached

    async def _in_worker(self, what: str, fn: Any, *args: Any, key: str, **kw: Any) -> Any:
        """``fn(*args, **kw)`` on the cluster: 422 for bad input, 503 past :data:`REFERENCE_TIMEOUT_S`, the task
        cancelled when the client goes away."""
        fut = self.cluster.submit(fn, *args, key=key, **kw)
        try:
            return await asyncio.wait_for(fut, REFERENCE_TIMEOUT_S)
        except (InputError, ValueError, KeyError, TypeError) as exc:
            raise Unprocessable(f"no {what} for this request: {exc}") from None
        except TimeoutError:
            await self.cluster.cancel(fut)
            raise Unavailable(f"the {what} took longer than {REFERENCE_TIMEOUT_S:.0f} s; ask for a smaller size",
                              headers={"Retry-After": "10"}) from None
        except asyncio.CancelledError:
            await self.cluster.cancel(fut)  # the client went away: free the worker
            raise

    async def texture(self, envmap_id: str, rows: int) -> tuple[bytes, int, int]:
        """The map as little-endian float16 RGB texels: (bytes, height, width)."""
        await self.envmaps.get(envmap_id)  # 404 for an unknown map
        key = ("texture", envmap_id, rows)
        cached = self.cached(key)
        if cached is None:
            await self.envmaps.input_ok(envmap_id)
            fut = self.cluster.submit(tasks.envmap_texture, str(self.store.root), envmap_id, rows,
                                      key=f"relight-texture-{envmap_id[:16]}-{rows}",
                                      max_pixels=self.settings.max_pixels)
            try:
                cached = await asyncio.wait_for(fut, TEXTURE_TIMEOUT_S)
            except InputError as exc:
                raise Unprocessable(str(exc)) from None
            self.keep(key, cached)
        data, h, w = cached
        return data, int(h), int(w)

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
