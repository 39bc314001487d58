"""Issue 17, item 8, through a real server: a lat-long EXR above ``max_pixels`` (8192 x 4096 here, Poly Haven's
"8k") is accepted, streamed from the stored file in a worker into its area-exact downsample within ``max_pixels``,
and the downsample is what jobs use; the worker's peak memory stays under ``stream_memory_bound``; a big file
that is not lat-long, or a lat-long one above ``max_stream_pixels``, is still a 422 from the header."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import psutil
import pytest

from relight.envmap import read_envmap, write_exr
from relight.sh9 import all_conventions
from relight.worker.blobs import BlobStore
from relight.worker.tasks import stored_rows, stream_memory_bound

from .postgres import Backend
from .support import Server, assert_healthy, assert_problem, start_server, wait_until

pytestmark = pytest.mark.timeout(600)

WIDTH, HEIGHT = 8192, 4096
MAX_PIXELS = 1024 * 512  # the test servers' decode cap: the stored map has 512 rows
SPECTRUM_LMAX = 256


@pytest.fixture(scope="module")
def big(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp("bigmaps"), {
        "RELIGHT_MAX_PIXELS": str(MAX_PIXELS), "RELIGHT_MAX_STREAM_PIXELS": str(WIDTH * HEIGHT),
        "RELIGHT_MAX_UPLOAD_BYTES": str(96 << 20), "RELIGHT_DECODE_TIMEOUT_S": "500",
        "RELIGHT_SPECTRUM_LMAX": str(SPECTRUM_LMAX)}, database=database)
    wait_until(lambda: len(psutil.Process(srv.pid).children()) >= 2, 60, "the Dask workers to start")
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def bh(big: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=big.url, timeout=600.0) as c:
        yield c


def smooth_exr(path: Path) -> Path:
    """An 8192 x 4096 smooth sky (l <= 2 in each channel), half floats, ZIP: neighbouring texels repeat, so the
    file stays a few MB while the decoder still produces 32 M texels."""
    theta = ((np.arange(HEIGHT) + 0.5) * np.pi / HEIGHT).astype(np.float32)[:, None]
    phi = ((np.arange(WIDTH) + 0.5) * 2 * np.pi / WIDTH).astype(np.float32)[None, :]
    img = np.empty((HEIGHT, WIDTH, 3), dtype=np.float32)
    for c, (a, b) in enumerate([(0.5, 0.2), (0.4, 0.3), (0.3, 0.25)]):
        img[..., c] = 1.0 + a * np.cos(theta) + b * np.sin(theta) * np.cos(phi)
    write_exr(path, img, half=True)
    return path


def worker_procs(server: Server) -> list[psutil.Process]:
    return [p for p in psutil.Process(server.pid).children()
            if "resource_tracker" not in " ".join(p.cmdline())]


def peak_rss(pid: int) -> int:
    """VmHWM: the process's peak resident memory since it started, bytes."""
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmHWM")


def test_a_big_latlong_exr_is_streamed_downsampled_and_used_by_jobs(big: Server, bh: httpx.Client,
                                                                      tmp_path: Path) -> None:
    path = smooth_exr(tmp_path / "big.exr")
    size = path.stat().st_size
    assert size < 96 << 20
    procs = worker_procs(big)
    before = {p.pid: p.memory_info().rss for p in procs}
    with open(path, "rb") as fh:
        r = bh.post("/envmaps", content=iter(lambda: fh.read(1 << 20), b""), params={"name": "big.exr"})
    assert r.status_code == 201, r.text
    body = r.json()
    rows = stored_rows(HEIGHT, MAX_PIXELS)
    assert rows == 512
    assert (body["source_width"], body["source_height"]) == (WIDTH, HEIGHT)
    assert (body["width"], body["height"]) == (2 * rows, rows)
    assert body["bytes"] == size and body["stored_sha256"] != body["id"]
    # Memory: growth of each worker's peak over its resident size before the upload, against the stated bound
    # (streaming buffers + the stored map's copies). Decoding the file whole would take 32 M texels x 12 bytes =
    # 0.4 GB for the float32 planes alone, above the bound (about 0.25 GB at 8192 -> 512 rows).
    bound = stream_memory_bound(WIDTH, rows, SPECTRUM_LMAX)
    grown = max(peak_rss(p.pid) - before[p.pid] for p in procs)
    assert grown <= bound, (grown, bound)
    assert bound < WIDTH * HEIGHT * 12
    assert max(peak_rss(p.pid) for p in procs) < 2 << 30  # the bound for a 16k map holds at 8k too
    # the stored map is exactly the core's streamed downsample of the same file (same code, float32 EXR round trip)
    stored_digest = body["stored_sha256"]
    blobs = BlobStore(big.log.parent / "blobs")  # the server's data directory holds its log and its blob store
    stored = read_envmap(blobs.read(stored_digest))
    expected = read_envmap(path, max_rows=rows)
    assert stored.pixels.shape == (rows, 2 * rows, 3)
    assert np.array_equal(stored.pixels, expected.pixels)
    assert blobs.stored_envmap(body["id"]) == stored_digest
    # a job decodes the stored map (the 8k upload itself is above the jobs' max_pixels: without the stored map
    # the job would fail with "the limit is 524288 pixels")
    deadline = time.monotonic() + 500
    while True:
        g = bh.get(f"/envmaps/{body['id']}/ibl", params={"target": "three", "format": "sh"})
        if g.status_code != 202 or time.monotonic() > deadline:
            break
        time.sleep(1.0)
    assert g.status_code == 200, g.text
    doc = g.json()
    assert (doc["source"]["height"], doc["source"]["width"]) == (rows, 2 * rows)
    # the job's SH9 is the stored map's (to float64 summation order: 1e-9 relative of the largest coefficient)
    ref = np.array(all_conventions(expected.pixels)["raw"]["coefficients"])
    np.testing.assert_allclose(np.array(doc["sh9"]["raw"]["coefficients"]), ref, rtol=0, atol=1e-9 * abs(ref).max())
    # the same file again: the same map, nothing recomputed
    with open(path, "rb") as fh:
        again = bh.post("/envmaps", content=fh.read())
    assert again.status_code == 200 and again.json()["stored_sha256"] == stored_digest
    assert_healthy(bh)


@pytest.mark.parametrize(("width", "height", "fragments"), [
    (6 * 2048, 2048, ("12288 x 2048", "the limit is 524288 pixels", "streamed up to")),  # a big cube strip
    (2 * 4608, 4608, ("9216 x 4608", f"the limit is {WIDTH * HEIGHT} pixels")),  # lat-long above the stream cap
])
def test_big_maps_that_cannot_be_streamed_are_refused_from_the_header(bh: httpx.Client, width: int, height: int,
                                                                       fragments: tuple[str, ...]) -> None:
    from .test_envmaps import exr_header_only

    n = len(bh.get("/envmaps").json()["items"])
    assert_problem(bh.post("/envmaps", content=exr_header_only(width, height)), 422, *fragments)
    assert len(bh.get("/envmaps").json()["items"]) == n  # nothing stored
    assert_healthy(bh)
