"""Python client for the relight service: ``RelightClient`` (sync) and ``AsyncRelightClient`` (httpx).

The request and response models in :mod:`client.models` are the ones the server uses, so both sides agree on
every field. Errors form one tree (:mod:`client.errors`).
"""

from client.errors import ApiError, JobFailed, RelightError, TransportError
from client.sdk import AsyncRelightClient, RelightClient

__all__ = ["ApiError", "AsyncRelightClient", "JobFailed", "RelightClient", "RelightError", "TransportError"]
