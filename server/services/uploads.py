"""The one bounded streaming path of every upload: environment maps (``POST /envmaps``), measured BRDFs
(``POST /brdfs/measured``) and meshes (``POST /meshes``).

:func:`receive` streams the request body into the blob store's temporary file (:class:`relight.worker.blobs
.BlobWriter`) and never holds more than one chunk in memory:

* a declared ``Content-Length`` above the cap is refused before a byte is read (413), one that is not an integer
  is a 400; a body that grows past the cap is refused at the chunk that crosses it (413), whatever it declared;
* the first ``head_bytes`` are kept and handed to the caller's ``check_head`` as soon as they are in (so a file of
  the wrong type is refused (415) before the rest is read) or at the end for a shorter body; an empty body is a 422;
* on any error, here or in the caller's block, the temporary file is deleted and nothing is stored; uploads
  refused for their content (413, 415, 422) are counted in ``uploads_rejected_total``.

Inside the ``async with`` block the bytes are written and hashed (:attr:`Upload.digest`); the caller installs them
into the store (``store._install(upload.writer.tmp_path, digest)``) once it has checked what only it knows.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass

from relight.server.problems import BadRequest, ContentTooLarge, Unprocessable, UnsupportedMediaType
from relight.server.services.base import in_thread
from relight.server.services.metrics import Metrics
from relight.worker.blobs import BlobStore, BlobWriter

#: What a refusal for the upload's content is (counted as a rejected upload).
REJECTIONS = (ContentTooLarge, UnsupportedMediaType, Unprocessable)


@dataclass(frozen=True)
class Upload:
    """A received body: its temporary file (still to install), digest, size and first bytes."""

    writer: BlobWriter
    digest: str
    size: int
    head: bytes


def declared_length(content_length: str | None) -> int | None:
    """The request's ``Content-Length`` as an integer (400 naming the value when it is not one)."""
    if content_length is None:
        return None
    try:
        return int(content_length)
    except ValueError:
        raise BadRequest(f"Content-Length must be an integer, got {content_length!r}") from None


@asynccontextmanager
async def receive(store: BlobStore, chunks: AsyncIterator[bytes], content_length: str | None, *, cap: int,
                  what: str, head_bytes: int, check_head: Callable[[bytes], None], limit: str | None = None,
                  metrics: Metrics | None = None) -> AsyncIterator[Upload]:
    """Stream ``chunks`` into the store's temporary file under ``cap`` bytes (module docstring).

    ``what`` names the expected file in the empty-body message ("the image file"); ``limit`` describes the cap in
    the 413 messages (default "the limit of {cap} bytes"); ``check_head(head)`` raises a problem for a body whose
    first ``head_bytes`` bytes (fewer for a shorter body) are not what the route accepts.
    """
    limit = limit or f"the limit of {cap} bytes"
    writer = store.writer()
    try:
        declared = declared_length(content_length)
        if declared is not None and declared > cap:
            raise ContentTooLarge(f"the body is {declared} bytes, over {limit}")
        head = b""
        checked = False
        async for chunk in chunks:
            if not chunk:
                continue
            if writer.size + len(chunk) > cap:
                raise ContentTooLarge(f"the body exceeds {limit}")
            if not checked:
                head += chunk[: head_bytes - len(head)]
                if len(head) >= head_bytes:
                    check_head(head)
                    checked = True
            writer.write(chunk)
        if writer.size == 0:
            raise Unprocessable(f"the request body is empty: send {what} as the body")
        if not checked:
            check_head(head)
        digest = await in_thread(writer.finish)
        yield Upload(writer, digest, writer.size, head)
    except BaseException as exc:
        if metrics is not None and isinstance(exc, REJECTIONS):
            metrics.inc("uploads_rejected_total")
        writer.abort()
        raise
