"""The service side of ``relight export --server`` and ``relight bake --server`` (entry point ``relight.remote``,
name ``export``, so that the core's commands never import the client): upload the map (idempotent, its id is its
SHA-256) and read its export from ``GET /envmaps/{id}/ibl`` (:meth:`relight.client.sdk.RelightClient.ibl`).

The KTX2, GLB and SH files are byte-identical to a local export's (``relight.engine_export``); the manifest differs in
its ``source`` (the map's id instead of its path) and its ``seconds``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def remote_export(server: str, path: Path, *, fmt: str, target: str, size: int, levels: int | None,
                  epsilon: float, sun: str, pixel_format: str = "rgba16f", api_key: str | None = None,
                  timeout: float = 600.0, brdf: str | None = None) -> tuple[bytes, dict[str, Any]]:
    """(file bytes, manifest) of one export of the map at ``path`` computed by the service at ``server``."""
    from relight.client.sdk import RelightClient

    with RelightClient(server, api_key=api_key, timeout=timeout) as c:
        env = c.upload_envmap(path)
        out = c.ibl(env.id, target=target, format=fmt, size=size, levels=levels, epsilon=epsilon, sun=sun,
                    pixel_format=pixel_format, timeout=timeout, brdf=brdf)
    return out.data, out.manifest
