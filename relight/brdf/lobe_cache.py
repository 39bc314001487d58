"""The in-process caches of per-lobe tabulations (BRDF coefficients, App. C's and the view bands' order searches,
view spectra): bounded LRU caches (``cachetools``) keyed by the lobe's canonical spec, and one :func:`clear` that
empties all of them.

A BRDF's tabulation depends on the lobe only, not on the lighting (seed 000 App. C: "not the dominant cost"), so
repeated prefilters of one material skip it. Timings that must include it (the cost model's calibration, the
accuracy–time sweep's points) call :func:`clear` first; every cache made by :func:`lobe_cache` is cleared, so no
search can keep a stale cache of its own.
"""

from __future__ import annotations

import json
from typing import Any, Final

from cachetools import LRUCache

from relight.brdf.base import Lobe

#: Entries per cache (a tabulation at F = 1024 is tens of MB; 32 lobes cover every material of a scene).
CACHE_SIZE: Final = 32
_caches: list[LRUCache[str, Any]] = []


def lobe_cache() -> LRUCache[str, Any]:
    """A new bounded cache, registered for :func:`clear`."""
    cache: LRUCache[str, Any] = LRUCache(maxsize=CACHE_SIZE)
    _caches.append(cache)
    return cache


def lobe_cache_key(lobe: Lobe, *parts: Any) -> str | None:
    """The cache key of a lobe and its parameters (the lobe's JSON spec); ``None`` for a lobe without a JSON spec,
    which is never cached."""
    try:
        return json.dumps([type(lobe).__qualname__, lobe.spec(), *parts], sort_keys=True)
    except (TypeError, ValueError):
        return None


def clear() -> None:
    """Forget everything every lobe cache holds (for timings that must include the tabulations)."""
    for cache in _caches:
        cache.clear()


__all__ = ["CACHE_SIZE", "clear", "lobe_cache", "lobe_cache_key"]
