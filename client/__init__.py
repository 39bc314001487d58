"""Python client for the relight service: ``RelightClient`` (sync) and ``AsyncRelightClient`` (httpx).

The request and response models in :mod:`relight.client.models` are the ones the server uses, so both sides agree on
every field. Errors form one tree (:mod:`relight.client.errors`).
"""

from relight.client.errors import ApiError, JobFailed, RelightError, TransportError
from relight.client.sdk import AsyncRelightClient, RelightClient

__all__ = ["ApiError", "AsyncRelightClient", "JobFailed", "RelightClient", "RelightError", "TransportError"]
