"""Python client for the relight service: ``RelightClient`` (sync) and ``AsyncRelightClient`` (httpx).

The request and response models are the API contract's (:mod:`relight.contract.models`), the ones the server uses,
so both sides agree on every field. Errors form one tree (:mod:`relight.client.errors`).

The names below load on first use (PEP 562), so the ``relight`` CLI can register the client's commands
(``relight.client.cli``) without importing httpx and pydantic.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from relight.client.async_sdk import AsyncRelightClient
    from relight.client.errors import ApiError, JobFailed, RelightError, TransportError
    from relight.client.sdk import RelightClient

_WHERE = {
    "ApiError": "relight.client.errors",
    "JobFailed": "relight.client.errors",
    "RelightError": "relight.client.errors",
    "TransportError": "relight.client.errors",
    "AsyncRelightClient": "relight.client.async_sdk",
    "RelightClient": "relight.client.sdk",
}

__all__ = ["ApiError", "AsyncRelightClient", "JobFailed", "RelightClient", "RelightError", "TransportError"]


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
