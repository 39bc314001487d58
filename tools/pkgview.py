"""Build the installed package layout as a tree of symlinks, for tools that read the file system.

pyproject.toml maps the top-level folders into one namespace (``server/`` installs as ``relight.server``, see
``[tool.setuptools] package-dir``). Python finds them through setuptools' editable finder, but mypy and
import-linter resolve modules from directories, so ``make lint`` points them at ``build/pkgview``: ``relight/``'s
own entries linked one by one, plus one link per mapped folder. Run: ``python tools/pkgview.py [OUT]``.
"""

from __future__ import annotations

import shutil
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def build(out: Path) -> Path:
    mapping: dict[str, str] = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    if out.exists():
        shutil.rmtree(out)
    top = out / "relight"
    top.mkdir(parents=True)
    nested = {name.split(".", 1)[1]: src for name, src in mapping.items() if name.startswith("relight.")}
    for entry in (ROOT / mapping["relight"]).iterdir():
        if entry.name != "__pycache__" and entry.name not in nested:
            (top / entry.name).symlink_to(entry)
    for sub, src in nested.items():
        if "." in sub:
            raise ValueError(f"package-dir maps a nested package {sub!r}; pkgview links one level only")
        (top / sub).symlink_to(ROOT / src, target_is_directory=True)
    return out


if __name__ == "__main__":
    print(build(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "build" / "pkgview"))
