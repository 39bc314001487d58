"""The browser viewer (``web/``) served by the API server: ``mount_viewer(app)``.

Paths (none collides with an API route):

* ``/`` and ``/index.html`` — ``web/index.html``;
* ``/src/...``, ``/shaders/...`` — the viewer's modules, styles and GLSL (``web/src``, ``web/shaders``);
* ``/vendor/three/...`` — three.js from npm (``web/node_modules/three``, installed by ``npm ci --prefix web``),
  mapped to the bare specifiers ``three`` and ``three/addons/`` by the page's import map: no bundler, no CDN;
* ``/packages/relight-three/...`` — the three.js package (``web/packages/relight-three/src``), mapped to
  ``@relight/three`` by the import map (the side-by-side with three's PMREM uses it);
* ``/samples/meshes/...`` — the sample mesh files (``data/meshes``: bunny.obj, teapot.obj); ``/meshes`` is the
  API's (uploaded and preloaded meshes in canonical order, ``server/api/routes/meshes.py``).

Every folder is package data (``relight.web``, ``relight.data``; :mod:`relight.resources`), so a wheel install
serves the same files as a checkout: the wheel carries the three.js files the viewer imports (pyproject.toml).

Static files are public (the viewer asks for the API key, if the server needs one, and sends it with its API
calls).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Final

from fastapi import FastAPI
from starlette.responses import FileResponse, PlainTextResponse, Response
from starlette.staticfiles import StaticFiles

from relight import resources

log = logging.getLogger("relight.server")

WEB_DIR: Final = resources.package_dir(resources.WEB)
MESH_DIR: Final = resources.mesh_dir()
THREE_HINT: Final = "three.js is not installed: run `npm ci --prefix web` (make web) on the server"


class _Static(StaticFiles):
    """Static files that browsers revalidate (the viewer changes with the server)."""

    async def get_response(self, path: str, scope):  # type: ignore[no-untyped-def]
        response = await super().get_response(path, scope)
        response.headers.setdefault("Cache-Control", "no-cache")
        if path.endswith(".glsl"):
            response.headers["Content-Type"] = "text/plain; charset=utf-8"
        return response


def mount_viewer(app: FastAPI, *, web_dir: Path = WEB_DIR, mesh_dir: Path = MESH_DIR) -> None:
    """Serve the viewer at ``/`` (see the module docstring). Call once, after the API routers."""
    index = web_dir / "index.html"
    if not index.is_file():
        raise FileNotFoundError(f"the viewer's {index} is missing")

    async def viewer_index() -> Response:
        return FileResponse(index, media_type="text/html", headers={"Cache-Control": "no-cache"})

    app.add_api_route("/", viewer_index, methods=["GET"], include_in_schema=False)
    app.add_api_route("/index.html", viewer_index, methods=["GET"], include_in_schema=False)
    app.mount("/src", _Static(directory=web_dir / "src"), name="viewer-src")
    app.mount("/shaders", _Static(directory=web_dir / "shaders"), name="viewer-shaders")
    app.mount("/packages/relight-three", _Static(directory=web_dir / "packages" / "relight-three" / "src"),
              name="viewer-relight-three")
    app.mount("/samples/meshes", _Static(directory=mesh_dir), name="viewer-meshes")
    three = web_dir / "node_modules" / "three"
    if (three / "build" / "three.module.js").is_file():
        app.mount("/vendor/three", _Static(directory=three), name="viewer-three")
    else:
        log.warning(THREE_HINT)

        async def missing_three(path: str) -> Response:
            return PlainTextResponse(THREE_HINT, status_code=503)

        app.add_api_route("/vendor/three/{path:path}", missing_three, methods=["GET"], include_in_schema=False)
