"""Failure and cancellation: a worker or the whole server killed mid-job, and cancelled jobs.

The server here runs with ``RELIGHT_TEST_JOB_DELAY_S`` (TEST ONLY): each job waits that long, reporting
progress, before computing, so "mid-job" is a state the test can observe rather than a race.
"""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlparse

import httpx
import psutil
import pytest

from relight.client.sdk import RelightClient
from relight.contract.models import JobPublic, JobState

from .postgres import Backend
from .support import (
    Server,
    assert_healthy,
    assert_problem,
    exr_bytes,
    make_envmap,
    start_server,
    wait_until,
)

pytestmark = pytest.mark.timeout(240)
DELAY_S = "3"


@pytest.fixture(scope="module")
def slow(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, object]]:
    data = tmp_path_factory.mktemp("slow")
    state: dict[str, object] = {"data": data, "database": database,
                                "server": start_server(data, {"RELIGHT_TEST_JOB_DELAY_S": DELAY_S}, database=database)}
    yield state
    srv = state["server"]
    assert isinstance(srv, Server)
    srv.stop()


def running(c: RelightClient, job_id: str) -> JobPublic | None:
    job = c.get_job(job_id)
    return job if job.state == JobState.running and job.worker else None


def worker_pid(server: Server, address: str) -> int:
    """The pid of the worker process listening on ``address`` (a child of the server process)."""
    port = urlparse(address).port
    for proc in psutil.Process(server.pid).children(recursive=True):
        try:
            if any(c.laddr.port == port and c.status == psutil.CONN_LISTEN for c in proc.net_connections("tcp")):
                return int(proc.pid)
        except psutil.Error:
            continue
    raise AssertionError(f"no child process listens on {address}")


def manifests_for(data: Path, job_id: str) -> list[Path]:
    found = []
    for p in (data / "blobs" / "sha256").rglob("*"):
        if p.is_file() and p.stat().st_size < 1 << 16:
            try:
                doc = json.loads(p.read_bytes())
            except (ValueError, UnicodeDecodeError):
                continue
            if isinstance(doc, dict) and doc.get("id") == job_id:
                found.append(p)
    return found


def test_worker_killed_mid_job(slow: dict[str, object], data_tmp: Path) -> None:
    server = slow["server"]
    assert isinstance(server, Server)
    with server.client() as c:
        env = c.upload_envmap(exr_bytes(make_envmap(32, seed=21), data_tmp))
        job = c.submit(env.id, "phong:s=16", epsilon=0.02)
        mid = wait_until(lambda: running(c, job.id), 30, "the job to run on a worker")
        assert mid.stage == "test_delay"
        os.kill(worker_pid(server, str(mid.worker)), signal.SIGKILL)
        done = c.wait(job.id, timeout=90)
        assert done.state == JobState.succeeded
        assert done.runs == 2, f"expected a rescheduled second run, got runs={done.runs}"
        assert done.submissions == 1  # Dask rescheduled it; the server did not resubmit
        assert c.download(job.id)
        wait_until(lambda: c.health().workers == 2, 60, "the nanny to restart the killed worker")


def test_server_killed_mid_job_then_restarted(slow: dict[str, object], data_tmp: Path) -> None:
    server = slow["server"]
    data = slow["data"]
    assert isinstance(server, Server) and isinstance(data, Path)
    exr = exr_bytes(make_envmap(32, seed=22), data_tmp)
    with server.client() as c:
        env = c.upload_envmap(exr)
        job = c.submit(env.id, "phong:s=24", epsilon=0.02)
        wait_until(lambda: running(c, job.id), 30, "the job to run")
    server.kill()  # SIGKILL: server, scheduler and workers die at once, nothing is cleaned up

    database = slow["database"]
    assert isinstance(database, Backend)
    restarted = start_server(data, {"RELIGHT_TEST_JOB_DELAY_S": DELAY_S}, log_name="server2.log", database=database)
    slow["server"] = restarted
    with restarted.client() as c:
        done = c.wait(job.id, timeout=90)
        assert done.state == JobState.succeeded
        assert done.runs == 2 and done.submissions == 2  # started once by each server process
        assert c.list_jobs(state="running") == [] and c.list_jobs(state="queued") == []
        assert c.get_shrm(job.id).id == job.id
        again = c.submit(env.id, "phong:s=24", epsilon=0.02)
        assert again.cached and again.state == JobState.succeeded
    assert len(manifests_for(data, job.id)) == 1, "a restarted job must not leave two results"
    refs = [p.name for p in (data / "blobs" / "refs").iterdir() if job.id in p.name]
    assert refs == [f"job-{job.id}"]


def test_cancel(slow: dict[str, object], data_tmp: Path) -> None:
    server = slow["server"]
    assert isinstance(server, Server)
    with server.client() as c, httpx.Client(base_url=server.url, timeout=60) as http:
        env = c.upload_envmap(exr_bytes(make_envmap(32, seed=23), data_tmp))
        job = c.submit(env.id, "phong:s=12", epsilon=0.02)
        cancelled = c.cancel_job(job.id)
        assert cancelled.state == JobState.cancelled and cancelled.failure_reason
        assert c.cancel_job(job.id).state == JobState.cancelled  # idempotent
        events = http.get(f"/jobs/{job.id}/events").text
        assert "event: end" in events and '"cancelled"' in events
        assert_problem(http.get(f"/shrms/{job.id}"), 409, "cancelled")
        from relight.client.errors import JobFailed

        with pytest.raises(JobFailed, match="cancelled"):
            c.wait(job.id, timeout=10)
        assert_healthy(http)
        # the same request again starts the job afresh
        resubmitted = c.submit(env.id, "phong:s=12", epsilon=0.02)
        assert resubmitted.id == job.id and resubmitted.state == JobState.queued
        assert c.wait(job.id, timeout=60).state == JobState.succeeded
