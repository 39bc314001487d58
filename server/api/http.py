"""Responses for content-addressed data: strong ETags (the SHA-256), immutable caching, 304 on a match."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable
from pathlib import Path
from typing import TypeVar

from starlette.requests import Request
from starlette.responses import FileResponse, Response

T = TypeVar("T")

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


def file_or_bytes_response(request: Request, content: bytes | None, path: Path, digest: str,
                           media_type: str) -> Response:
    """Bytes held in memory as they are; a large file (``content`` None) streamed from its verified path."""
    if content is None:
        return blob_response(request, path, digest, media_type)
    return bytes_response(request, content, digest, media_type)


def bytes_response(request: Request, content: bytes, digest: str, media_type: str) -> Response:
    etag = etag_of(digest)
    if not_modified(request, etag):
        return Response(status_code=304, headers=cached_headers(etag))
    return Response(content, media_type=media_type, headers=cached_headers(etag))


async def until_disconnect(request: Request, work: Awaitable[T], poll_s: float = 0.25) -> T:
    """Await ``work`` unless the client goes away first: then it is cancelled (a plan's sandbox is killed) and the
    request ends with no answer, as nobody is there to read one."""
    task = asyncio.ensure_future(work)
    try:
        while True:
            done, _ = await asyncio.wait({task}, timeout=poll_s)
            if done:
                return task.result()
            if await request.is_disconnected():
                task.cancel()
                raise asyncio.CancelledError("the client disconnected")
    finally:
        if not task.done():
            task.cancel()
