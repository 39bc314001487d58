"""Lazy re-exports for packages split by object (PEP 562 module ``__getattr__``).

A package lists ``name -> submodule`` and gets a ``__getattr__`` that imports the submodule the first time one of its
names is used (then caches the value in the package), imports a submodule asked for by its own name, and a matching
``__dir__``. Importing one submodule (say
``relight.envmap.formats``) then does not load its siblings' heavy dependencies (OpenEXR, Pillow, ducc0).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def exports(package: str, names: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` re-exporting ``names`` (public name -> submodule name)."""

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            try:  # a submodule not imported yet (``package.<name>``)
                return importlib.import_module(f"{package}.{name}")
            except ModuleNotFoundError as exc:
                if exc.name != f"{package}.{name}":
                    raise
                raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
