"""Worker code (``relight.worker``) run directly on real Dask worker processes, without the server: a job through
``run_job`` (its ``started`` / ``progress`` / ``done`` events on the progress topic, the submission number, the
result), a cancelled job stopped inside its computation by ``CancelWatch``, and ``analyze_envmap`` on an uploaded
map checked against a closed form.

The task functions below are shipped to the worker by value (``cloudpickle.register_pickle_by_value``): the worker
processes do not import the test tree.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import pytest
from distributed import Client, LocalCluster

from relight.envmap import write_exr
from relight.worker.blobs import BlobStore
from relight.worker.progress import TOPIC, JobCancelled, JobContext, run_job
from relight.worker.tasks import analyze_envmap

cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def client() -> Iterator[Client]:
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as c:
        yield c


def staged_task(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    for i in range(request["stages"]):
        ctx.report(f"stage{i}", (i + 1) / (request["stages"] + 1))
    return {"pid": os.getpid(), "sum": sum(request["values"]), "job": ctx.job_id}


def counting_task(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    """Pure computation with no progress reports (no stage boundary to stop at): only CancelWatch can stop it."""
    path = Path(request["counter"])
    n = 0
    while True:
        n += 1
        if n % 200_000 == 0:
            path.write_text(str(n))


def test_run_job_on_a_worker_process_reports_and_returns(client: Client) -> None:
    events: list[dict[str, Any]] = []
    client.subscribe_topic(TOPIC, lambda ev: events.append(ev[1]))
    job = {"job_id": "j" * 64, "submission": 3, "request": {"stages": 2, "values": [1, 2, 3.5]}}
    result = client.submit(run_job, staged_task, "/nonexistent-store", job, pure=False).result(timeout=60)
    assert result["sum"] == 6.5 and result["job"] == "j" * 64
    assert result["pid"] != os.getpid()  # it ran in the worker process
    deadline = time.monotonic() + 30
    while not any(e.get("stage") == "done" for e in events) and time.monotonic() < deadline:
        time.sleep(0.05)
    mine = [e for e in events if e["job"] == "j" * 64]
    assert all(e["submission"] == 3 for e in mine)
    assert mine[0]["event"] == "started" and mine[0]["worker"] in client.scheduler_info()["workers"]
    stages = [(e["stage"], e["fraction"]) for e in mine if e["event"] == "progress"]
    assert stages == [("stage0", 1 / 3), ("stage1", 2 / 3), ("done", 1.0)]


def test_a_cancelled_job_stops_inside_its_computation(client: Client, tmp_path: Path) -> None:
    counter = tmp_path / "counter"
    job = {"job_id": "c" * 64, "submission": 1, "request": {"counter": str(counter)}}
    fut = client.submit(run_job, counting_task, str(tmp_path), job, pure=False)
    deadline = time.monotonic() + 60
    while not counter.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert counter.exists(), "the task never started counting"
    fut.cancel()
    # CancelWatch looks every CANCEL_POLL_S (0.2 s): well within 5 s the count must stop moving for good
    time.sleep(5.0)
    stopped = counter.read_text()
    time.sleep(1.0)
    assert counter.read_text() == stopped, "the cancelled task is still computing"
    # the worker is free again: a new job runs to the end
    job2 = {"job_id": "d" * 64, "submission": 1, "request": {"stages": 0, "values": [1]}}
    assert client.submit(run_job, staged_task, str(tmp_path), job2, pure=False).result(timeout=60)["sum"] == 1


def test_analyze_envmap_on_a_worker_matches_the_closed_form(client: Client, tmp_path: Path) -> None:
    """A constant map c: its luminance L = 0.2126 c_r + 0.7152 c_g + 0.0722 c_b has all its SH energy in l = 0,
    E_0 = 4 pi L^2 (the squared norm of a constant over the sphere), and the spectrum's bands above 0 vanish to
    quadrature rounding."""
    c = np.array([0.5, 1.0, 2.0])
    store = BlobStore(tmp_path / "store")
    path = tmp_path / "const.exr"
    write_exr(path, np.broadcast_to(c, (16, 32, 3)).astype(np.float32))
    digest = store.put_bytes(path.read_bytes())
    info = client.submit(analyze_envmap, str(store.root), digest, max_pixels=10**6, spectrum_lmax=8,
                         pure=False).result(timeout=120)
    lum = float(np.dot([0.2126, 0.7152, 0.0722], c))
    assert (info["width"], info["height"], info["layout"], info["format"]) == (32, 16, "latlong", "exr")
    assert info["mean"] == pytest.approx(c.tolist(), rel=1e-6)
    spectrum = info["sh_power_spectrum"]
    assert len(spectrum) == 9 and spectrum[0] == pytest.approx(4 * math.pi * lum**2, rel=1e-6)
    assert max(spectrum[1:]) < 1e-10 * spectrum[0]
    assert store.has(info["preview_sha256"])  # the preview went into the store the server reads


def test_a_task_error_reaches_the_caller_unchanged(client: Client) -> None:
    job = {"job_id": "e" * 64, "submission": 1, "request": {"stages": 0, "values": ["x"]}}
    with pytest.raises(TypeError):
        client.submit(run_job, staged_task, "/nonexistent-store", job, pure=False).result(timeout=60)
    assert JobCancelled.__module__ == "relight.worker.progress"
