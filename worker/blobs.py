"""Content-addressed blob store on a local (or shared) directory.

Layout under ``root``::

    sha256/ab/cd/abcd...   one file per blob, named by the SHA-256 of its bytes
    refs/<name>            small text files naming a blob digest (job results, rendered views)
    tmp/                   files being written; renamed into place when complete

Writes are atomic (temporary file in ``tmp/``, then ``os.replace``), so a reader never sees a partial blob. They
are not fsync'ed: after a power cut a blob may be torn, which verification detects like any other corruption.
Reads are verified: the bytes are hashed and compared with the name. A mismatch raises :class:`BlobCorrupt`
and the caller recomputes; a corrupt blob is never returned. Hashing a large blob on every read would cap the
throughput of cached downloads, so a process remembers which files it has verified, keyed by the file's
inode, size, modification time and inode-change time (ctime: every write moves it and no call can set it back):
a file that changes on disk after verification is hashed again, even when size and mtime are restored.
"""

from __future__ import annotations

import hashlib
import os
import re
import threading
import uuid
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Final

DIGEST_RE: Final = re.compile(r"^[0-9a-f]{64}$")
REF_RE: Final = re.compile(r"^[A-Za-z0-9_.-]{1,200}$")
_CHUNK: Final = 1 << 20


class BlobError(Exception):
    """Base class of blob-store errors."""


class BlobMissing(BlobError, KeyError):
    """No blob (or ref) with that name."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable
        return str(self.args[0]) if self.args else "blob missing"


class BlobCorrupt(BlobError):
    """The stored bytes do not hash to the blob's name; the file has been removed."""


def sha256_hex(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def check_digest(digest: str) -> str:
    """Return ``digest`` if it is 64 lowercase hex characters, else raise ``ValueError`` quoting it."""
    if not isinstance(digest, str) or not DIGEST_RE.match(digest):
        raise ValueError(f"not a SHA-256 hex digest: {digest!r}")
    return digest


class BlobWriter:
    """Streams bytes into a temporary file while hashing; :meth:`commit` moves it into the store."""

    def __init__(self, store: BlobStore) -> None:
        self._store = store
        self.tmp_path = store.tmp_dir / f"{uuid.uuid4().hex}.part"
        self._fh: IO[bytes] | None = open(self.tmp_path, "wb")  # noqa: SIM115 - closed in commit/abort
        self._hash = hashlib.sha256()
        self.size = 0

    def write(self, chunk: bytes) -> None:
        if self._fh is None:
            raise BlobError("write to a closed blob writer")
        self._fh.write(chunk)
        self._hash.update(chunk)
        self.size += len(chunk)

    def _close(self) -> None:
        if self._fh is not None:
            self._fh.close()  # no fsync: a blob torn by a power cut fails verification and is recomputed
            self._fh = None

    def finish(self) -> str:
        """Close the temporary file (still at :attr:`tmp_path`) and return the digest of what was written."""
        self._close()
        return self._hash.hexdigest()

    def commit(self) -> str:
        """Move the written bytes into the store; returns their digest."""
        digest = self.finish()
        self._store._install(self.tmp_path, digest)
        return digest

    def abort(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
        self.tmp_path.unlink(missing_ok=True)


def stored_envmap_ref(digest: str) -> str:
    """Ref naming the stored downsample of a streamed upload (:meth:`BlobStore.stored_envmap`)."""
    return f"envmap-stored-{check_digest(digest)}"


class BlobStore:
    """See the module docstring."""

    def __init__(self, root: str | os.PathLike[str], *, memory_bytes: int = 0) -> None:
        self.root = Path(root).resolve()
        self.memory_bytes = memory_bytes
        self._memory: OrderedDict[str, tuple[tuple[int, int, int, int], bytes]] = OrderedDict()
        self._memory_size = 0
        self.tmp_dir = self.root / "tmp"
        self.refs_dir = self.root / "refs"
        self.blob_dir = self.root / "sha256"
        for d in (self.tmp_dir, self.refs_dir, self.blob_dir):
            d.mkdir(parents=True, exist_ok=True)
        self._verified: dict[str, tuple[int, int, int, int]] = {}
        self._lock = threading.Lock()

    # -- paths -----------------------------------------------------------------------------------------------
    def path(self, digest: str) -> Path:
        check_digest(digest)
        return self.blob_dir / digest[:2] / digest[2:4] / digest

    def has(self, digest: str) -> bool:
        return self.path(digest).is_file()

    # -- writing ---------------------------------------------------------------------------------------------
    def writer(self) -> BlobWriter:
        return BlobWriter(self)

    def _install(self, tmp: Path, digest: str) -> None:
        final = self.path(digest)
        final.parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp, final)  # atomic; an existing copy (same bytes by construction) is replaced
        self._forget(digest)

    def put_bytes(self, data: bytes) -> str:
        w = self.writer()
        try:
            w.write(data)
            return w.commit()
        except BaseException:
            w.abort()
            raise

    def put_file(self, path: str | os.PathLike[str]) -> str:
        """Copy a file into the store (hashing it on the way); the source is left in place."""
        w = self.writer()
        try:
            with open(path, "rb") as fh:
                while chunk := fh.read(_CHUNK):
                    w.write(chunk)
            return w.commit()
        except BaseException:
            w.abort()
            raise

    @contextmanager
    def new_file(self, suffix: str = "") -> Iterator[Path]:
        """A temporary path inside the store for a library that writes files itself; removed afterwards."""
        p = self.tmp_dir / f"{uuid.uuid4().hex}{suffix}"
        try:
            yield p
        finally:
            p.unlink(missing_ok=True)

    def delete(self, digest: str) -> None:
        self.path(digest).unlink(missing_ok=True)
        self._forget(digest)

    # -- reading ---------------------------------------------------------------------------------------------
    def _stat_key(self, p: Path) -> tuple[int, int, int, int]:
        """What a verification is valid for. The inode change time is in it: any write to the file (or ``utime``
        putting its mtime back) moves ctime, which no user-space call can set, so a content change cannot keep an
        old verification (size and mtime alone can be kept by whoever overwrites the file in place)."""
        st = p.stat()
        return (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)

    def verified_fast(self, digest: str) -> Path | None:
        """The blob's path if this process verified it and it is unchanged since (one ``stat``), else None."""
        p = self.path(digest)
        try:
            key = self._stat_key(p)
        except FileNotFoundError:
            return None
        with self._lock:
            return p if self._verified.get(digest) == key else None

    def verified_path(self, digest: str) -> Path:
        """Path of a blob whose bytes hash to ``digest`` (hashing it unless already verified unchanged).

        Raises :class:`BlobMissing` or :class:`BlobCorrupt` (the corrupt file is removed).
        """
        p = self.path(digest)
        try:
            key = self._stat_key(p)
        except FileNotFoundError:
            raise BlobMissing(f"blob {digest} is not in the store") from None
        with self._lock:
            if self._verified.get(digest) == key:
                return p
        h = hashlib.sha256()
        try:
            with open(p, "rb") as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
        except FileNotFoundError:
            raise BlobMissing(f"blob {digest} is not in the store") from None
        if h.hexdigest() != digest:
            p.unlink(missing_ok=True)
            self._forget(digest)
            raise BlobCorrupt(f"blob {digest} is corrupt (its bytes hash to {h.hexdigest()}); removed")
        with self._lock:
            self._verified[digest] = key
        return p

    def cached_bytes(self, digest: str) -> bytes | None:
        """Bytes held in memory for a blob verified by this process, if the file is unchanged since (one
        ``stat``); None otherwise (the caller then verifies again through :meth:`load`)."""
        with self._lock:
            entry = self._memory.get(digest)
        if entry is None:
            return None
        try:
            key = self._stat_key(self.path(digest))
        except FileNotFoundError:
            key = None
        if key != entry[0]:
            self._forget(digest)
            return None
        with self._lock:
            if digest in self._memory:
                self._memory.move_to_end(digest)
        return entry[1]

    def load(self, digest: str) -> bytes:
        """Read and verify a blob and keep its bytes in memory (LRU, up to ``memory_bytes`` in all) so that
        repeated reads cost one ``stat``. Raises :class:`BlobMissing` or :class:`BlobCorrupt`."""
        p = self.path(digest)
        try:
            key = self._stat_key(p)
        except FileNotFoundError:
            raise BlobMissing(f"blob {digest} is not in the store") from None
        data = self.read(digest)
        with self._lock:
            self._verified[digest] = key
            if len(data) <= self.memory_bytes // 8:
                old = self._memory.pop(digest, None)
                if old is not None:
                    self._memory_size -= len(old[1])
                self._memory[digest] = (key, data)
                self._memory_size += len(data)
                while self._memory_size > self.memory_bytes and self._memory:
                    _, (_, evicted) = self._memory.popitem(last=False)
                    self._memory_size -= len(evicted)
        return data

    def _forget(self, digest: str) -> None:
        with self._lock:
            old = self._memory.pop(digest, None)
            if old is not None:
                self._memory_size -= len(old[1])
            self._verified.pop(digest, None)

    def read(self, digest: str) -> bytes:
        """The blob's bytes, verified against ``digest`` (see :meth:`verified_path`)."""
        p = self.path(digest)
        try:
            data = p.read_bytes()
        except FileNotFoundError:
            raise BlobMissing(f"blob {digest} is not in the store") from None
        actual = sha256_hex(data)
        if actual != digest:
            p.unlink(missing_ok=True)
            self._forget(digest)
            raise BlobCorrupt(f"blob {digest} is corrupt (its bytes hash to {actual}); removed")
        return data

    def stored_envmap(self, digest: str) -> str:
        """The blob that jobs decode for the uploaded map ``digest``: the area-exact downsample the upload's
        analysis stored when the file was too large to decode whole (issue 17, item 8), else the upload itself."""
        stored = self.get_ref(stored_envmap_ref(digest))
        return stored if stored is not None and self.has(stored) else digest

    # -- refs ------------------------------------------------------------------------------------------------
    def _ref_path(self, name: str) -> Path:
        if not REF_RE.match(name):
            raise ValueError(f"bad ref name {name!r}")
        return self.refs_dir / name

    def set_ref(self, name: str, digest: str) -> None:
        check_digest(digest)
        tmp = self.tmp_dir / f"{uuid.uuid4().hex}.ref"
        tmp.write_text(digest)  # a torn ref does not parse as a digest and reads as absent (recompute)
        os.replace(tmp, self._ref_path(name))

    def get_ref(self, name: str) -> str | None:
        try:
            text = self._ref_path(name).read_text().strip()
        except FileNotFoundError:
            return None
        return text if DIGEST_RE.match(text) else None

    def delete_ref(self, name: str) -> None:
        self._ref_path(name).unlink(missing_ok=True)
