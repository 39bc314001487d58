"""The installed layout: pyproject's explicit package list covers every package folder, and nothing installs a
generic top-level name (``server``, ``worker``, ``client``)."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _setuptools() -> dict[str, object]:
    table: dict[str, object] = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    return table


def test_every_package_folder_is_listed() -> None:
    conf = _setuptools()
    mapping = conf["package-dir"]
    assert isinstance(mapping, dict)
    found = set()
    for name, src in mapping.items():
        base = ROOT / src
        for init in base.rglob("__init__.py"):
            rel = init.parent.relative_to(base)
            found.add(".".join([name, *rel.parts]))
    listed = set(conf["packages"])  # type: ignore[call-overload]
    # A folder mapped by package-dir is also found under its parent's folder only when it lives there; the
    # mapped folders here are all top-level, so the two sets must agree exactly.
    assert found == listed, f"missing from pyproject: {sorted(found - listed)}; stale: {sorted(listed - found)}"


def test_no_generic_top_level_name() -> None:
    conf = _setuptools()
    tops = {name.split(".")[0] for name in conf["packages"]}  # type: ignore[union-attr]
    assert tops == {"relight"}
