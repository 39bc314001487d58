"""Issue 12, item 4 (storage integrity), against a real server on loopback.

* A result blob corrupted in place with its size and mtime put back was served with the old ETag (and 304s): the
  verification record now includes the inode change time, which the overwrite moves and nobody can set back.
* Left-over temporary files are removed at start-up (younger ones, maybe being written by another process, stay).
* ``relight store check`` finds corrupt blobs, dangling refs and left-overs; ``--repair`` removes them.
* ``/health`` says degraded when the blob store's disk is below the free-space threshold.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from .postgres import Backend
from .support import REPO, Server, base_env, exr_bytes, make_envmap, start_server, wait_done, wait_until

pytestmark = pytest.mark.timeout(240)

STALE_AGE_S = 2 * 3600  # older than relight.worker.store_check.STALE_TMP_S (600 s)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Path:
    """A data directory whose blob store already holds a stale and a fresh temporary file."""
    d = tmp_path_factory.mktemp(f"storage-{database.name}")
    tmp = d / "blobs" / "tmp"
    tmp.mkdir(parents=True)
    (tmp / "stale.part").write_bytes(b"x" * 1000)
    old = time.time() - STALE_AGE_S
    os.utime(tmp / "stale.part", (old, old))
    (tmp / "fresh.part").write_bytes(b"y" * 1000)
    return d


@pytest.fixture(scope="module")
def store_server(data_dir: Path, database: Backend) -> Iterator[Server]:
    srv = start_server(data_dir, {"RELIGHT_MIN_FREE_BYTES": str(1 << 60),  # no disk has an exbibyte free
                                  "RELIGHT_BLOB_CACHE_BYTES": str(64 << 10)},  # results over 8 KiB are streamed
                       database=database)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def sh(store_server: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=store_server.url, timeout=60.0) as c:
        yield c


def blob_path(data_dir: Path, digest: str) -> Path:
    return data_dir / "blobs" / "sha256" / digest[:2] / digest[2:4] / digest


def store_check(data_dir: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", "store", "check", str(data_dir), *extra],
                          capture_output=True, text=True, env=base_env(), cwd=REPO, timeout=120)


def test_left_over_temporary_files_are_removed_at_start_up(store_server: Server, data_dir: Path) -> None:
    tmp = data_dir / "blobs" / "tmp"
    assert not (tmp / "stale.part").exists()
    assert (tmp / "fresh.part").exists()  # maybe another process's write in progress: left alone
    (tmp / "fresh.part").unlink()


def test_health_reports_a_full_disk(sh: httpx.Client) -> None:
    h = sh.get("/health").json()
    assert h["status"] == "degraded"
    assert any(p.startswith("disk:") for p in h["problems"]), h
    assert h["workers"] == 2


def test_corruption_keeping_size_and_mtime_is_never_served(sh: httpx.Client, data_dir: Path, tmp_path: Path
                                                           ) -> None:
    env = sh.post("/envmaps", content=exr_bytes(make_envmap(32, seed=11), tmp_path)).json()["id"]
    r = sh.post("/shrms", json={"envmap": env, "brdf": "phong:s=16", "order": 6, "size": 8})
    assert r.status_code in (200, 202), r.text
    job = wait_done(sh, f"/jobs/{r.json()['id']}")
    assert job["state"] == "succeeded", job
    url = f"/shrms/{job['id']}/coefficients.exr"
    first = sh.get(url)
    assert first.status_code == 200
    etag = first.headers["etag"]
    digest = etag.strip('"')
    assert hashlib.sha256(first.content).hexdigest() == digest
    assert sh.get(url, headers={"If-None-Match": etag}).status_code == 304  # verified and unchanged: 304

    path = blob_path(data_dir, digest)
    st = path.stat()
    with open(path, "r+b") as fh:  # in place: same inode, same size
        fh.seek(st.st_size // 2)
        flipped = bytes(b ^ 0xFF for b in fh.read(16))
        fh.seek(st.st_size // 2)
        fh.write(flipped)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))  # and the old mtime back
    after = path.stat()
    assert (after.st_ino, after.st_size, after.st_mtime_ns) == (st.st_ino, st.st_size, st.st_mtime_ns)
    assert hashlib.sha256(path.read_bytes()).hexdigest() != digest

    again = sh.get(url, headers={"If-None-Match": etag})
    assert again.status_code == 503, (again.status_code, again.headers.get("etag"))  # never 304, never the bytes
    assert "retry-after" in {k.lower() for k in again.headers}

    def served() -> httpx.Response | None:
        resp = sh.get(url)
        return resp if resp.status_code == 200 else None

    back = wait_until(served, 120, "the result to be recomputed", interval=0.25)
    assert hashlib.sha256(back.content).hexdigest() == back.headers["etag"].strip('"') == digest  # bit-identical


def test_results_are_streamed_not_held_whole(store_server: Server, sh: httpx.Client, tmp_path: Path) -> None:
    """16 concurrent GETs of a result of several MB: the server's resident memory, sampled every 5 ms while they
    run, grows by less than four copies of it (held whole, as before, it would be sixteen)."""
    import threading

    import psutil

    env = sh.post("/envmaps", content=exr_bytes(make_envmap(64, seed=13), tmp_path)).json()["id"]
    r = sh.post("/shrms", json={"envmap": env, "brdf": "phong:s=8", "order": 4, "size": 768})
    job = wait_done(sh, f"/jobs/{r.json()['id']}")
    assert job["state"] == "succeeded", job
    url = f"/shrms/{job['id']}/coefficients.bin"  # float16, incompressible layout: 768 x 1536 x 3 x 2 bytes
    first = sh.get(url)
    size = len(first.content)
    assert size == 768 * 1536 * 3 * 2
    proc = psutil.Process(store_server.pid)
    base = proc.memory_info().rss
    peak = [base]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], proc.memory_info().rss)
            time.sleep(0.005)

    sampler = threading.Thread(target=sample)
    sampler.start()
    try:
        with ThreadPoolExecutor(16) as pool:
            bodies = list(pool.map(lambda _: httpx.get(f"{store_server.url}{url}", timeout=60).content, range(16)))
    finally:
        stop.set()
        sampler.join()
    assert all(b == first.content for b in bodies)
    assert peak[0] - base < 4 * size, (peak[0] - base) / size


def test_store_check_finds_and_repairs(sh: httpx.Client, data_dir: Path, tmp_path: Path) -> None:
    env = sh.post("/envmaps", content=exr_bytes(make_envmap(16, seed=12), tmp_path)).json()
    clean = store_check(data_dir)
    assert clean.returncode == 0, clean.stdout + clean.stderr
    target = blob_path(data_dir, env["id"])
    target.write_bytes(b"corrupted")
    stale = data_dir / "blobs" / "tmp" / "left.part"
    stale.write_bytes(b"z")
    old = time.time() - STALE_AGE_S
    os.utime(stale, (old, old))
    found = store_check(data_dir)
    assert found.returncode == 1, found.stdout
    assert f"corrupt blob {target.name}" in found.stdout and "left-over temporary file left.part" in found.stdout
    fixed = store_check(data_dir, "--repair")
    assert fixed.returncode == 0 and "repaired" in fixed.stdout, fixed.stdout
    assert not target.exists() and not stale.exists()
    assert store_check(data_dir).returncode == 0
