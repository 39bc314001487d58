"""RFC 9457 problem details: the exceptions services raise and the handlers that render them.

Every error response is ``application/problem+json`` with ``type``, ``title``, ``status`` and ``detail``;
validation errors add ``errors`` (one entry per offending field, with its location and value).
"""

from __future__ import annotations

import errno
import logging
import math
import secrets
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import JSONResponse

from relight.errors import InputError

log = logging.getLogger("relight.server")

PROBLEM_MEDIA_TYPE = "application/problem+json"
TYPE_PREFIX = "urn:relight:problem:"

_TITLES = {400: "Bad Request", 401: "Unauthorized", 403: "Forbidden", 404: "Not Found", 405: "Method Not Allowed",
           406: "Not Acceptable", 409: "Conflict", 413: "Content Too Large", 415: "Unsupported Media Type",
           422: "Unprocessable Content", 429: "Too Many Requests", 500: "Internal Server Error",
           503: "Service Unavailable", 504: "Gateway Timeout", 507: "Insufficient Storage"}


class ProblemError(Exception):
    """An error with an HTTP status; ``slug`` makes the problem ``type`` (``urn:relight:problem:<slug>``)."""

    status = 500
    slug = "internal-error"

    def __init__(self, detail: str, *, headers: dict[str, str] | None = None, **extra: Any) -> None:
        super().__init__(detail)
        self.detail = detail
        self.headers = headers or {}
        self.extra = extra


class BadRequest(ProblemError):
    status, slug = 400, "bad-request"


class Unauthorized(ProblemError):
    status, slug = 401, "unauthorized"


class NotFound(ProblemError):
    status, slug = 404, "not-found"


class Conflict(ProblemError):
    status, slug = 409, "conflict"


class ContentTooLarge(ProblemError):
    status, slug = 413, "content-too-large"


class UnsupportedMediaType(ProblemError):
    status, slug = 415, "unsupported-media-type"


class Unprocessable(ProblemError):
    status, slug = 422, "invalid-input"


class TooManyJobs(ProblemError):
    status, slug = 429, "too-many-jobs"


class Unavailable(ProblemError):
    status, slug = 503, "unavailable"


def problem_response(status: int, slug: str, detail: str | None, *, instance: str | None = None,
                     headers: dict[str, str] | None = None, **extra: Any) -> JSONResponse:
    body: dict[str, Any] = {"type": TYPE_PREFIX + slug, "title": _TITLES.get(status, "Error"), "status": status}
    if detail is not None:
        body["detail"] = detail
    if instance is not None:
        body["instance"] = instance
    body.update(extra)
    return JSONResponse(jsonable_encoder(body), status_code=status, headers=headers,
                        media_type=PROBLEM_MEDIA_TYPE)


def _field(loc: tuple[Any, ...] | list[Any]) -> str:
    """``("body", "phong", "s")`` -> ``phong.s``: the request part (body, query, path, header) is dropped."""
    parts = [str(p) for p in loc]
    if len(parts) > 1 and parts[0] in ("body", "query", "path", "header", "cookie"):
        parts = parts[1:]
    return ".".join(parts)


def _safe_input(value: Any) -> Any:
    """The offending value, JSON-safe: short scalars as they are, anything else (and NaN/Inf) as its repr."""
    text = repr(value)
    if isinstance(value, float) and not math.isfinite(value):
        return text
    return value if len(text) <= 200 and isinstance(value, str | int | float | bool | None) else text[:200]


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into problem details."""

    @app.exception_handler(ProblemError)
    async def _problem(request: Request, exc: ProblemError) -> JSONResponse:
        return problem_response(exc.status, exc.slug, exc.detail, instance=request.url.path, headers=exc.headers,
                                **exc.extra)

    @app.exception_handler(InputError)
    async def _input(request: Request, exc: InputError) -> JSONResponse:
        return problem_response(422, "invalid-input", str(exc), instance=request.url.path)

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = []
        for e in exc.errors():
            field = _field(e.get("loc", ()))
            item = {"field": field, "message": e.get("msg", "invalid"), "type": e.get("type")}
            if "input" in e and e.get("type") != "missing":
                item["value"] = _safe_input(e["input"])
            errors.append(item)
        detail = "; ".join(
            f"{x['field']}: {x['message']}" + (f" (got {x['value']!r})" if "value" in x else "") for x in errors
        )
        return problem_response(422, "validation-error", detail or "invalid request", instance=request.url.path,
                                errors=errors)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        slug = {404: "not-found", 405: "method-not-allowed"}.get(exc.status_code, "http-error")
        detail = exc.detail if isinstance(exc.detail, str) else None
        if exc.status_code == 404 and detail == "Not Found":
            detail = f"no route for {request.method} {request.url.path}"
        return problem_response(exc.status_code, slug, detail, instance=request.url.path,
                                headers=dict(exc.headers or {}))

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        """Nothing of the exception reaches the client (its text may hold server paths, SQL, addresses): a
        reference to the log line instead. A full disk is 507, with the same reticence."""
        incident = secrets.token_hex(6)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            log.error("storage full on %s %s [%s]: %s", request.method, request.url.path, incident, exc)
            return problem_response(507, "insufficient-storage", f"the server's storage is full; nothing was stored "
                                    f"(incident {incident})", instance=request.url.path, incident=incident)
        log.exception("unhandled error on %s %s [%s]", request.method, request.url.path, incident)
        return problem_response(500, "internal-error", f"internal error (incident {incident}: the server's log has "
                                "the details)", instance=request.url.path, incident=incident)


#: ``responses=`` for route decorators: documents problem bodies in the OpenAPI schema.
def problem_responses(*codes: int) -> dict[int | str, dict[str, Any]]:
    from relight.contract.models import Problem

    return {
        code: {
            "description": _TITLES.get(code, "Error"),
            "content": {PROBLEM_MEDIA_TYPE: {"schema": Problem.model_json_schema()}},
        }
        for code in codes
    }
