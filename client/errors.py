"""The client's one exception tree, and the single place where httpx errors are mapped onto it.

    RelightError                 (the ``relight`` CLI's service commands report it on one line, exit status 2)
    ├── ApiError                 the server answered with an error status (RFC 9457 problem details)
    ├── JobFailed                a job ended failed or cancelled
    └── TransportError           no usable answer: connection refused, timeout, broken stream
"""

from __future__ import annotations

import json
from typing import Any

import httpx


class RelightError(Exception):
    """Base class of every error the client raises."""


class ApiError(RelightError):
    """An HTTP error status with its problem-details body (``type``, ``title``, ``status``, ``detail``)."""

    def __init__(self, status: int, title: str, detail: str | None = None, *, type: str = "about:blank",
                 body: dict[str, Any] | None = None, method: str = "", url: str = "") -> None:
        self.status = status
        self.title = title
        self.detail = detail
        self.type = type
        self.body = body or {}
        self.method = method
        self.url = url
        where = f" ({method} {url})" if method else ""
        super().__init__(f"{status} {title}{': ' + detail if detail else ''}{where}")


class JobFailed(RelightError):
    """A job that ended ``failed`` or ``cancelled``; ``job`` is its last state."""

    def __init__(self, job: Any) -> None:
        self.job = job
        reason = getattr(job, "failure_reason", None) or getattr(job, "state", "failed")
        super().__init__(f"job {getattr(job, 'id', '?')} {getattr(job, 'state', 'failed')}: {reason}")


class TransportError(RelightError):
    """The request did not produce an HTTP response (connection, timeout, protocol error)."""


def from_httpx(exc: httpx.HTTPError) -> TransportError:
    """Map any httpx transport-level exception to :class:`TransportError` (the one mapping point)."""
    req = getattr(exc, "_request", None)
    where = f"{req.method} {req.url}: " if isinstance(req, httpx.Request) else ""
    kind = type(exc).__name__
    return TransportError(f"{where}{kind}: {exc}" if str(exc) else f"{where}{kind}")


def from_response(resp: httpx.Response) -> ApiError:
    """Build an :class:`ApiError` from an error response (problem details, or plain text from a proxy)."""
    body: dict[str, Any] = {}
    try:
        parsed = json.loads(resp.content) if resp.content else {}
        if isinstance(parsed, dict):
            body = parsed
    except ValueError:
        body = {"detail": resp.text[:500]}
    title = str(body.get("title") or resp.reason_phrase or "error")
    detail = body.get("detail")
    return ApiError(resp.status_code, title, str(detail) if detail is not None else None,
                    type=str(body.get("type", "about:blank")), body=body, method=resp.request.method,
                    url=str(resp.request.url))
