"""Responses for content-addressed data: strong ETags (the SHA-256), immutable caching, 304 on a match."""

from __future__ import annotations

from pathlib import Path

from starlette.requests import Request
from starlette.responses import FileResponse, Response

IMMUTABLE = "public, max-age=31536000, immutable"


def etag_of(digest: str) -> str:
    return f'"{digest}"'


def not_modified(request: Request, etag: str) -> bool:
    """If-None-Match (RFC 9110 §13.1.2: weak comparison, ``*`` matches any current representation)."""
    header = request.headers.get("if-none-match")
    if not header:
        return False
    for tag in header.split(","):
        tag = tag.strip()
        if tag == "*" or tag.removeprefix("W/") == etag:
            return True
    return False


def cached_headers(etag: str) -> dict[str, str]:
    return {"ETag": etag, "Cache-Control": IMMUTABLE}


def blob_response(request: Request, path: Path, digest: str, media_type: str,
                  filename: str | None = None) -> Response:
    etag = etag_of(digest)
    if not_modified(request, etag):
        return Response(status_code=304, headers=cached_headers(etag))
    headers = cached_headers(etag)
    if filename:
        headers["Content-Disposition"] = f'attachment; filename="{filename}"'
    return FileResponse(path, media_type=media_type, headers=headers)


def bytes_response(request: Request, content: bytes, digest: str, media_type: str) -> Response:
    etag = etag_of(digest)
    if not_modified(request, etag):
        return Response(status_code=304, headers=cached_headers(etag))
    return Response(content, media_type=media_type, headers=cached_headers(etag))
