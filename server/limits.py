"""Request limits enforced before any route runs: header size (431), body size (413) and the API key (401) before
a byte of the body is read.

* :class:`BodyLimit` (pure ASGI middleware, outermost but for Starlette's error middleware): a request whose
  declared ``Content-Length`` exceeds the route's limit is answered 413 without reading its body; a request that
  carries a body (any method but GET/HEAD/OPTIONS) to a route behind the API key is answered 401 first when the key
  is missing or wrong; JSON bodies are read here up to ``max_json_bytes`` (413 beyond, whether a length was declared
  or the body is chunked) and replayed to the route; upload bodies (``UPLOAD_PATHS``) are streamed to the route
  with their bytes counted (413 the moment ``max_upload_bytes`` is passed). A URL whose path or query holds a NUL
  character (``%00``) is answered 422 (``validation-error``, as a parameter FastAPI refuses) before anything else:
  no id, name or parameter of the API contains one, and PostgreSQL cannot even compare a string holding one
  (psycopg refuses the query: a 500 on PostgreSQL where SQLite answered 404, found by the service suites'
  PostgreSQL legs).
* :class:`BoundedHttpToolsProtocol` (uvicorn's httptools protocol with a cap): the request line and headers
  together may take ``MAX_HEAD_BYTES``; beyond, the connection gets 431 and is closed. httptools buffers a header
  field whole before handing it on, so the count is kept on the raw bytes received while the head is open.

RFC 9110 §15.5.14 (413 Content Too Large), RFC 6585 §5 (431 Request Header Fields Too Large).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any, Final

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from relight.server.api.deps import key_problem
from relight.server.config import Settings
from relight.server.problems import PROBLEM_MEDIA_TYPE, TYPE_PREFIX, ContentTooLarge

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

#: Routes whose body is a file, streamed to the route (everything else is JSON, read whole here).
UPLOAD_PATHS: Final = frozenset({"/envmaps", "/brdfs/measured", "/meshes"})
#: Routes outside the API key (``relight.server.api.router``): health and metrics. No route with a body is.
PUBLIC_PATHS: Final = frozenset({"/health", "/metrics"})
#: Request line + headers; 64 KiB is four times nginx's default ``large_client_header_buffers`` (4 x 8 KiB) and
#: far above anything the SDK, a browser or curl sends.
MAX_HEAD_BYTES: Final = 64 * 1024
_BODYLESS: Final = frozenset({"GET", "HEAD", "OPTIONS"})


def _problem_bytes(status: int, slug: str, title: str, detail: str, path: str) -> bytes:
    return json.dumps({"type": TYPE_PREFIX + slug, "title": title, "status": status, "detail": detail,
                       "instance": path}).encode()


async def send_problem(send: Send, status: int, slug: str, title: str, detail: str, path: str,
                       headers: dict[str, str] | None = None) -> None:
    body = _problem_bytes(status, slug, title, detail, path)
    raw = [(b"content-type", PROBLEM_MEDIA_TYPE.encode()), (b"content-length", str(len(body)).encode()),
           (b"connection", b"close")]
    raw += [(k.lower().encode(), v.encode()) for k, v in (headers or {}).items()]
    await send({"type": "http.response.start", "status": status, "headers": raw})
    await send({"type": "http.response.body", "body": body})


class BodyLimit:
    """See the module docstring."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.settings = settings

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        method, path = scope["method"], scope["path"]
        if "\x00" in path or b"%00" in scope.get("query_string", b""):
            await send_problem(send, 422, "validation-error", "Unprocessable Content",
                               "the URL holds a NUL character (%00); no id, name or parameter may contain one",
                               path.replace("\x00", "%00"))
            return
        headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope["headers"]}
        upload = path.rstrip("/") in UPLOAD_PATHS
        limit = self.settings.max_upload_bytes if upload else self.settings.max_json_bytes
        has_body = method not in _BODYLESS
        if has_body and path not in PUBLIC_PATHS:
            problem = key_problem(self.settings, headers)
            if problem is not None:
                await send_problem(send, 401, "unauthorized", "Unauthorized", problem.detail, path, problem.headers)
                return
        declared = headers.get("content-length")
        if declared is not None:
            if not declared.isdigit():
                await send_problem(send, 400, "bad-request", "Bad Request",
                                   f"Content-Length must be an integer, got {declared[:40]!r}", path)
                return
            if int(declared) > limit:
                await send_problem(send, 413, "content-too-large", "Content Too Large",
                                   f"the body is {declared} bytes; the limit of this route is {limit} bytes", path)
                return
        if not has_body:
            await self.app(scope, receive, send)
            return
        if upload:
            await self.app(scope, _counting(receive, limit), send)
            return
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                await send_problem(send, 413, "content-too-large", "Content Too Large",
                                   f"the body exceeds the limit of this route, {limit} bytes", path)
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        await self.app(scope, _replay(b"".join(chunks), receive), send)


def _counting(receive: Receive, limit: int) -> Receive:
    seen = 0

    async def wrapped() -> Message:
        nonlocal seen
        message = await receive()
        if message["type"] == "http.request":
            seen += len(message.get("body", b""))
            if seen > limit:
                raise ContentTooLarge(f"the body exceeds the limit of this route, {limit} bytes")
        return message

    return wrapped


def _replay(body: bytes, receive: Receive) -> Receive:
    sent = False

    async def wrapped() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()  # after the body: wait for the disconnect, as the server would

    return wrapped


class BoundedHttpToolsProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol; a request head over :data:`MAX_HEAD_BYTES` gets 431 and the connection closes."""

    max_head_bytes = MAX_HEAD_BYTES

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._head_open = True
        self._head_bytes = 0
        self._head_too_large = False

    def data_received(self, data: bytes) -> None:
        if self._head_too_large:
            return
        if self._head_open:
            self._head_bytes += len(data)
        super().data_received(data)  # one read (<= 256 KiB) past the limit at most is buffered
        if self._head_open and self._head_bytes > self.max_head_bytes and not self._head_too_large:
            self._refuse()

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._head_open = True

    def on_headers_complete(self) -> None:
        self._head_open = False
        self._head_bytes = 0
        size = len(self.url) + sum(len(k) + len(v) + 4 for k, v in self.headers)
        if size > self.max_head_bytes:  # the whole head arrived in one read
            self._refuse()
            return
        super().on_headers_complete()

    def on_body(self, body: bytes) -> None:
        if not self._head_too_large:
            super().on_body(body)

    def on_message_complete(self) -> None:
        if not self._head_too_large:
            super().on_message_complete()

    def _refuse(self) -> None:
        self._head_too_large = True
        body = _problem_bytes(431, "header-fields-too-large", "Request Header Fields Too Large",
                              f"the request line and headers exceed {self.max_head_bytes} bytes", "")
        head = (b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-type: " + PROBLEM_MEDIA_TYPE.encode()
                + b"\r\ncontent-length: " + str(len(body)).encode() + b"\r\nconnection: close\r\n\r\n")
        self.transport.write(head + body)
        self.transport.close()
