"""A really full disk (issue 12, item 4): the blob store on a small tmpfs mount (the tests run as root, as CI does),
filled by another file. Uploads answer 507 with a clean problem (no path, no OS error text) and leave nothing
behind, ``/health`` says degraded, a job whose result does not fit fails with a retryable reason, and once space
is freed the same request succeeds."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from .postgres import Backend
from .support import Server, assert_problem, exr_bytes, fresh_health, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(300)
#: The mount: room for a small map and its analysis, not for the big upload or the job's result below.
MOUNT_BYTES = 8 << 20
#: Free bytes left once the filler is written (the big upload and the result each need several times this).
LEFT_BYTES = 96 << 10
MIN_FREE = 1 << 20


@pytest.fixture(scope="module")
def full(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[tuple[Server, Path]]:
    assert os.geteuid() == 0, "this test mounts a tmpfs: it runs as root (CI does)"
    root = tmp_path_factory.mktemp("disk")
    mount = root / "blobs"
    mount.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={MOUNT_BYTES}", "tmpfs", str(mount)], check=True,
                   capture_output=True)
    server = None
    try:
        server = start_server(root / "data", {"RELIGHT_BLOB_DIR": str(mount),
                                              "RELIGHT_MIN_FREE_BYTES": str(MIN_FREE)}, database=database)
        yield server, mount
    finally:
        if server is not None:
            server.stop()
        subprocess.run(["umount", "-l", str(mount)], check=True, capture_output=True)


def fill(mount: Path, leave: int) -> Path:
    filler = mount / "filler"
    free = os.statvfs(mount).f_bavail * os.statvfs(mount).f_frsize
    with open(filler, "wb") as fh:
        fh.write(b"\0" * max(0, free - leave))
    return filler


def clean_problem(resp: httpx.Response, mount: Path) -> None:
    body = assert_problem(resp, 507, "storage is full")
    text = resp.text
    assert str(mount) not in text and "Errno" not in text and "No space" not in text, text
    assert body.get("incident")


def test_a_full_disk_is_507_degraded_and_failed_jobs_recover(full: tuple[Server, Path], tmp_path: Path) -> None:
    server, mount = full
    with httpx.Client(base_url=server.url, timeout=120) as http:
        assert http.get("/health").json()["status"] == "ok"
        small = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=900), tmp_path))
        assert small.status_code == 201, small.text
        env = small.json()["id"]
        listed = {e["id"] for e in http.get("/envmaps").json()["items"]}

        filler = fill(mount, LEFT_BYTES)
        health = fresh_health(http)  # the probes run in the background: a round after the disk filled
        assert health["status"] == "degraded" and any(p.startswith("disk:") for p in health["problems"]), health

        big = exr_bytes(make_envmap(160, seed=901), tmp_path)  # noisy floats: ~600 KB even compressed
        assert len(big) > 4 * LEFT_BYTES
        with httpx.Client(base_url=server.url, timeout=120) as once:  # answered before the body was read: the
            clean_problem(once.post("/envmaps", content=big), mount)  # server closes that connection
        assert {e["id"] for e in http.get("/envmaps").json()["items"]} == listed  # no row
        assert list((mount / "tmp").iterdir()) == []  # no partial file

        # a job whose result (9 layers of 64 x 128 float32 RGB, ~900 KB) does not fit
        req = {"envmap": env, "brdf": {"kind": "microfacet", "sigma": 0.3}, "order": 6, "p_order": 2, "size": 64}
        job = http.post("/shrms", json=req)
        assert job.status_code == 202, job.text
        job_id = job.json()["id"]
        failed = wait_until(lambda: (j := http.get(f"/jobs/{job_id}").json())["state"] in ("failed", "succeeded")
                            and j, 180, "the job to end")
        assert failed["state"] == "failed" and "full" in failed["failure_reason"], failed
        assert str(mount) not in failed["failure_reason"]
        assert list((mount / "tmp").iterdir()) == []

        filler.unlink()
        wait_until(lambda: http.get("/health").json()["status"] == "ok", 30, "health to recover")
        again = http.post("/shrms", json=req)  # the failure was retryable: the same request runs again
        assert again.status_code == 202 and again.json()["id"] == job_id, again.text
        done = wait_until(lambda: (j := http.get(f"/jobs/{job_id}").json())["state"] in ("failed", "succeeded")
                          and j, 180, "the resubmitted job")
        assert done["state"] == "succeeded", done
        assert http.post("/envmaps", content=big).status_code == 201
