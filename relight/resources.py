"""Package data (the shaders, the viewer, the sample meshes and maps) as directories, through ``importlib.resources``.

The top-level folders ``web/`` and ``data/`` install as the packages ``relight.web`` and ``relight.data``
(pyproject.toml ``[tool.setuptools] package-dir`` and ``package-data``), so the same names find the files in a
checkout (editable install) and in a wheel; nothing reads a path relative to the repository.

Folders are returned as :class:`pathlib.Path` because their readers need real directories (Starlette's
``StaticFiles``, the GLSL ``#include`` resolver): a package installed from a wheel is one, and a zip import
(which relight does not support) is refused with a clear error.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

#: The viewer (``web/``: index.html, src/, shaders/, three.js from node_modules/three).
WEB = "relight.web"
#: Sample data (``data/``: envmaps/*.exr, meshes/*.obj).
DATA = "relight.data"


def package_dir(package: str, *parts: str) -> Path:
    """The folder ``parts`` inside ``package``'s installed files (it need not exist)."""
    root = files(package)
    if not isinstance(root, Path):
        raise RuntimeError(f"{package} is not installed as plain files ({root!r}); install relight from a wheel or "
                           "a checkout, not a zip archive")
    return root.joinpath(*parts)


def shader_dir() -> Path:
    """``web/shaders``: the GLSL shared by the browser viewer and the moderngl renderer."""
    return package_dir(WEB, "shaders")


def mesh_dir() -> Path:
    """``data/meshes``: bunny.obj and teapot.obj."""
    return package_dir(DATA, "meshes")


def sample_envmaps() -> Path | None:
    """``data/envmaps``, the sample environment maps, or ``None`` when they are not installed."""
    path = package_dir(DATA, "envmaps")
    return path if path.is_dir() else None
