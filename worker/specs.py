"""BRDF specs as the service stores them versus as the core reads them.

The core's parser (``relight.brdf.spec``) also accepts specs that name *files* (``merl:gold.binary``,
``measured:table.npz``, ``lobe1d:lobe.json``, any ``*.json`` string, ``{"kind": "lobe1d", "path": ...}``). A
client must never make the server or a worker open a path of its choosing, so:

* client strings naming a file kind or a JSON file are refused before the core sees them
  (:func:`check_client_string`); client objects are validated by the pydantic union, which has no path fields;
* a measured BRDF uploaded to the service is stored as ``{"kind": "merl", "sha256": <digest>}`` and turned into
  the core's ``{"kind": "merl", "path": <blob path>}`` only inside the service (:func:`to_core`), and back
  (:func:`from_core`) before anything is stored in a result, so no server path leaks into a response.
"""

from __future__ import annotations

import re
from typing import Any, Final

from relight.errors import InputError
from relight.worker.blobs import BlobStore

#: Core kinds whose parameters are file paths.
PATH_KINDS: Final = ("merl", "measured", "lobe1d")
_TERM_KIND = re.compile(r"^\s*([A-Za-z0-9_-]+)")


def check_client_string(spec: str) -> str:
    """Refuse a spec string that would make the core read a file; returns it unchanged otherwise."""
    if spec.strip().lower().endswith(".json"):
        raise InputError(f"brdf: JSON files are not accepted from clients ({spec!r}); send the spec object itself")
    for term in spec.split("+"):
        m = _TERM_KIND.match(term)
        kind = m.group(1).lower() if m else ""
        if kind in PATH_KINDS:
            raise InputError(f"brdf: {kind!r} specs name files and are not accepted as strings ({spec!r}); "
                             "upload measured BRDFs with POST /brdfs/measured, send lobe1d tables as objects")
    return spec


def to_core(spec: Any, store: BlobStore) -> Any:
    """The service spec with each uploaded measured BRDF (``sha256``) replaced by the core's ``path`` form."""
    if isinstance(spec, dict):
        if spec.get("kind") == "merl" and "sha256" in spec:
            out = {k: v for k, v in spec.items() if k != "sha256"}
            out["path"] = str(store.verified_path(str(spec["sha256"])))
            return out
        return {k: to_core(v, store) for k, v in spec.items()}
    if isinstance(spec, list):
        return [to_core(v, store) for v in spec]
    return spec


def from_core(obj: Any, store: BlobStore) -> Any:
    """Inverse of :func:`to_core` on any JSON structure (reports, manifests): blob paths become ``sha256``."""
    if isinstance(obj, dict):
        path = obj.get("path")
        if obj.get("kind") == "merl" and isinstance(path, str) and path.startswith(str(store.blob_dir)):
            return {**{k: v for k, v in obj.items() if k != "path"}, "sha256": path.rsplit("/", 1)[-1]}
        return {k: from_core(v, store) for k, v in obj.items()}
    if isinstance(obj, list):
        return [from_core(v, store) for v in obj]
    return obj
