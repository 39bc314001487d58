"""``relight.server.services.uploads.receive``: the one bounded streaming path of every upload (maps, MERL files,
meshes), on a real blob store. The body is an async generator that records how far it was read, so "refused
before the rest is read" is observed, not assumed."""

from __future__ import annotations

import asyncio
import hashlib
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from relight.server.problems import BadRequest, ContentTooLarge, ProblemError, Unprocessable, UnsupportedMediaType
from relight.server.services.metrics import Metrics
from relight.server.services.uploads import receive
from relight.worker.blobs import BlobStore

HEAD = b"GOOD"


class Body:
    """Chunks handed out one at a time; ``read`` counts those taken."""

    def __init__(self, *chunks: bytes) -> None:
        self.chunks = chunks
        self.read = 0

    async def __call__(self) -> AsyncIterator[bytes]:
        for c in self.chunks:
            self.read += 1
            yield c


def check(head: bytes) -> None:
    if not head.startswith(HEAD[: len(head)]) or len(head) < len(HEAD):
        raise UnsupportedMediaType(f"not a GOOD file (starts with {head[:4]!r})")


def run(store: BlobStore, body: Body, length: str | None = None, cap: int = 100,
        metrics: Metrics | None = None) -> tuple[str, int, bytes, bool]:
    async def go() -> tuple[str, int, bytes, bool]:
        async with receive(store, body(), length, cap=cap, what="the GOOD file", head_bytes=len(HEAD),
                           check_head=check, metrics=metrics) as up:
            present = up.writer.tmp_path.is_file()
            store._install(up.writer.tmp_path, up.digest)
            return up.digest, up.size, up.head, present

    return asyncio.run(go())


def leftovers(store: BlobStore) -> list[Path]:
    return list(store.tmp_dir.iterdir())


@pytest.fixture
def store(tmp_path: Path) -> BlobStore:
    return BlobStore(tmp_path / "blobs")


def test_a_body_in_chunks_is_hashed_and_installed_by_the_caller(store: BlobStore) -> None:
    body = Body(b"GO", b"OD and", b"", b" more")
    digest, size, head, present = run(store, body, length="15")
    data = b"GOOD and more"
    assert digest == hashlib.sha256(data).hexdigest() and size == len(data) and head == HEAD and present
    assert store.read(digest) == data and leftovers(store) == []


def test_a_declared_length_over_the_cap_is_refused_unread(store: BlobStore) -> None:
    body = Body(HEAD)
    metrics = Metrics()
    with pytest.raises(ContentTooLarge, match="the body is 101 bytes, over the limit of 100 bytes"):
        run(store, body, length="101", metrics=metrics)
    assert body.read == 0 and leftovers(store) == [] and metrics.counters["uploads_rejected_total"] == 1


def test_a_body_growing_past_the_cap_stops_at_that_chunk(store: BlobStore) -> None:
    body = Body(HEAD + b"x" * 60, b"y" * 40, b"never read")  # declares nothing; 104 > 100 at the second chunk
    with pytest.raises(ContentTooLarge, match="exceeds the limit of 100 bytes"):
        run(store, body)
    assert body.read == 2 and leftovers(store) == []
    assert run(store, Body(HEAD + b"x" * 96))[1] == 100  # exactly the cap is accepted


def test_a_wrong_head_is_refused_before_the_rest(store: BlobStore) -> None:
    body = Body(b"BADD", b"x" * 10, b"y" * 10)
    with pytest.raises(UnsupportedMediaType, match="not a GOOD file"):
        run(store, body)
    assert body.read == 1 and leftovers(store) == []


def test_a_short_body_is_checked_at_its_end(store: BlobStore) -> None:
    with pytest.raises(UnsupportedMediaType, match=r"starts with b'GO'"):
        run(store, Body(b"G", b"O"))


def test_empty_and_malformed_bodies_name_the_problem(store: BlobStore) -> None:
    with pytest.raises(Unprocessable, match="the request body is empty: send the GOOD file as the body"):
        run(store, Body(b"", b""))
    with pytest.raises(BadRequest, match="Content-Length must be an integer, got 'ten'"):
        run(store, Body(HEAD), length="ten")
    assert leftovers(store) == []


def test_an_error_in_the_callers_block_leaves_nothing(store: BlobStore) -> None:
    metrics = Metrics()

    async def go() -> None:
        async with receive(store, Body(HEAD, b"payload")(), None, cap=100, what="x", head_bytes=4, check_head=check,
                           metrics=metrics):
            raise Unprocessable("the caller's own check failed")

    with pytest.raises(ProblemError, match="the caller's own check"):
        asyncio.run(go())
    assert leftovers(store) == [] and metrics.counters["uploads_rejected_total"] == 1
    assert not any(p.is_file() for p in store.root.rglob("*"))
