"""Scrubbing the blob store (``relight store check DATA_DIR [--repair]``) and cleaning its temporary files.

* :func:`scrub` hashes every blob under ``sha256/`` and reads every ref under ``refs/``: a blob whose bytes do not
  hash to its name is corrupt, a ref naming an absent blob (or not naming a digest) dangles, a file in ``tmp/`` is
  left over from an interrupted write. With ``repair`` the corrupt blobs, dangling refs and left-over temporary
  files are removed, which is what the service needs to recompute: a job whose result ref or files are gone is
  recomputed when it is next read or submitted, a map whose uploaded bytes are gone answers 503 (upload it again).
* :func:`clean_tmp` removes the temporary files not written to for :data:`STALE_TMP_S` (the server calls it at
  start-up): a write in progress touches its file continually, and other processes (workers, a second server on
  the same store) may be writing now, so younger files are left alone; ``--repair`` uses the same rule.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path

from relight.worker.blobs import DIGEST_RE, BlobStore

_CHUNK = 1 << 20
#: Seconds without a write after which a temporary file is a left-over (an upload or a result write streams its
#: bytes with pauses of at most a network or compute step, far below this).
STALE_TMP_S = 600.0


@dataclass
class ScrubReport:
    blobs: int = 0
    refs: int = 0
    corrupt: list[str] = field(default_factory=list)
    dangling_refs: list[str] = field(default_factory=list)
    tmp_files: list[str] = field(default_factory=list)
    repaired: bool = False

    @property
    def clean(self) -> bool:
        return not (self.corrupt or self.dangling_refs or self.tmp_files)

    def lines(self) -> list[str]:
        out = [f"{self.blobs} blobs, {self.refs} refs checked"]
        out += [f"corrupt blob {d}" for d in self.corrupt]
        out += [f"dangling ref {r}" for r in self.dangling_refs]
        out += [f"left-over temporary file {t}" for t in self.tmp_files]
        if not self.clean:
            out.append("repaired: removed the above" if self.repaired else "run with --repair to remove them")
        return out


def _hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def scrub(store: BlobStore, *, repair: bool = False) -> ScrubReport:
    """Check every blob and ref of ``store`` (module docstring)."""
    report = ScrubReport(repaired=repair)
    present: set[str] = set()
    for path in sorted(store.blob_dir.rglob("*")):
        if not path.is_file():
            continue
        report.blobs += 1
        name = path.name
        if not DIGEST_RE.match(name) or path != store.path(name) or _hash(path) != name:
            report.corrupt.append(name)
            if repair:
                path.unlink(missing_ok=True)
        else:
            present.add(name)
    for ref in sorted(store.refs_dir.iterdir()):
        if not ref.is_file():
            continue
        report.refs += 1
        target = ref.read_text(errors="replace").strip()
        if target not in present:
            report.dangling_refs.append(ref.name)
            if repair:
                ref.unlink(missing_ok=True)
    cutoff = time.time() - STALE_TMP_S
    for tmp in sorted(store.tmp_dir.iterdir()):
        try:
            stale = tmp.is_file() and tmp.stat().st_mtime <= cutoff
        except FileNotFoundError:
            continue
        if stale:
            report.tmp_files.append(tmp.name)
            if repair:
                tmp.unlink(missing_ok=True)
    return report


def clean_tmp(store: BlobStore, *, older_than_s: float = STALE_TMP_S) -> int:
    """Remove files in ``tmp/`` last modified more than ``older_than_s`` seconds ago; returns how many."""
    cutoff = time.time() - older_than_s
    removed = 0
    for tmp in store.tmp_dir.iterdir():
        try:
            if tmp.is_file() and tmp.stat().st_mtime <= cutoff:
                tmp.unlink()
                removed += 1
        except FileNotFoundError:  # another process finished with it meanwhile
            continue
    return removed
