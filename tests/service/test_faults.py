"""Fault injection at the points that matter (issue 12, item 5): a job is held (``relight.worker.faults``, TEST ONLY)
inside its computation, after its result's blobs are written but before the ref naming them, and in the server
before the job row is updated; there the worker, the whole server, or the scheduler (of the deployment's form:
``relight scheduler`` and ``relight worker`` processes on mutual TLS) is killed with SIGKILL.

After each kill the job must finish once (one manifest, one ref, state succeeded), its result must equal the
library's bit for bit, and the blob store must hold exactly what it held before plus that result: no orphan blob,
no partial file in ``blobs/tmp``.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import psutil
import pytest

from relight.client.sdk import RelightClient
from relight.contract.models import JobPublic, JobState

from .postgres import Backend
from .support import (
    Proc,
    Server,
    base_env,
    exr_bytes,
    library_map,
    make_envmap,
    read_exr,
    start_server,
    wait_until,
)
from .test_resilience import worker_pid
from .test_scale_out import free_port, tls_init

pytestmark = pytest.mark.timeout(600)
SPEC = "phong:s=16"
EPSILON = 0.02
WORKER_POINTS = ("compute", "blobs_written")
POINTS = (*WORKER_POINTS, "before_commit")


# ------------------------------------------------------------------------------------------------ the hook
def arm(faults: Path, point: str) -> None:
    for p in faults.glob("*"):
        p.unlink()
    (faults / "armed").write_text(point)


def reached(faults: Path, point: str, timeout: float = 90) -> tuple[str, int]:
    marker = faults / f"{point}.reached"
    wait_until(marker.exists, timeout, f"a job to reach the fault point {point!r}")
    job_id, pid = marker.read_text().split()
    return job_id, int(pid)


def release(faults: Path, point: str) -> None:
    (faults / f"{point}.release").write_text("go")


# ------------------------------------------------------------------------------------------------ the checks
def blobs(data: Path) -> set[str]:
    return {p.name for p in (data / "blobs" / "sha256").rglob("*") if p.is_file()}


def manifests_for(data: Path, job_id: str) -> dict[str, dict[str, object]]:
    found = {}
    for p in (data / "blobs" / "sha256").rglob("*"):
        if p.is_file() and p.stat().st_size < 1 << 16:
            try:
                doc = json.loads(p.read_bytes())
            except (ValueError, UnicodeDecodeError):
                continue
            if isinstance(doc, dict) and doc.get("id") == job_id:
                found[p.name] = doc
    return found


def finished_once(c: RelightClient, data: Path, job_id: str, exr: bytes, before: set[str]) -> JobPublic:
    done = c.wait(job_id, timeout=180)
    assert done.state == JobState.succeeded, done
    got = read_exr(c.download(job_id))[""]
    expected = library_map(exr, SPEC, epsilon=EPSILON)
    assert np.array_equal(got.view(np.uint32), expected.view(np.uint32)), "result differs from the library's"
    manifests = manifests_for(data, job_id)
    assert len(manifests) == 1, f"expected one result, found {len(manifests)}"
    (digest, manifest), = manifests.items()
    files = manifest["files"]
    assert isinstance(files, dict)
    assert (data / "blobs" / "refs" / f"job-{job_id}").read_text().strip() == digest
    after = blobs(data)
    expected_blobs = before | {digest} | {str(f["sha256"]) for f in files.values()}
    assert after == expected_blobs, f"orphan blobs {after - expected_blobs}, missing {expected_blobs - after}"
    leftovers = list((data / "blobs" / "tmp").iterdir())
    assert leftovers == [], f"partial files left in blobs/tmp: {leftovers}"
    return done


# ------------------------------------------------------------------------------------------------ embedded
@pytest.fixture(scope="module")
def faulty(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, object]]:
    data = tmp_path_factory.mktemp("faulty")
    faults = tmp_path_factory.mktemp("faults")
    env = {"RELIGHT_TEST_FAULT_DIR": str(faults), "RELIGHT_MAX_UPLOAD_BYTES": str(4 << 20)}
    state: dict[str, object] = {"data": data, "faults": faults, "env": env, "database": database,
                                "server": start_server(data, env, database=database)}
    yield state
    srv = state["server"]
    assert isinstance(srv, Server)
    srv.stop()


def _parts(state: dict[str, object]) -> tuple[Server, Path, Path, dict[str, str]]:
    server, data, faults, env = state["server"], state["data"], state["faults"], state["env"]
    assert isinstance(server, Server) and isinstance(data, Path) and isinstance(faults, Path)
    assert isinstance(env, dict)
    return server, data, faults, env


@pytest.mark.parametrize("point", POINTS)
def test_worker_killed_at(point: str, faulty: dict[str, object], data_tmp: Path) -> None:
    server, data, faults, _ = _parts(faulty)
    with server.client() as c:
        exr = exr_bytes(make_envmap(32, seed=100 + POINTS.index(point)), data_tmp)
        env = c.upload_envmap(exr)
        before = blobs(data)
        arm(faults, point)
        job = c.submit(env.id, SPEC, epsilon=EPSILON)
        job_id, pid = reached(faults, point)
        assert job_id == job.id
        if point in WORKER_POINTS:
            victim = pid  # the worker process holding the job
        else:
            assert pid == server.pid  # the server holds the result; the worker that computed it goes
            victim = worker_pid(server, str(c.get_job(job.id).worker))
        os.kill(victim, signal.SIGKILL)
        release(faults, point)
        done = finished_once(c, data, job.id, exr, before)
        # a worker lost mid-computation is rescheduled by Dask (a second run); once the result is in the server's
        # hands the worker's death changes nothing
        assert done.runs == (2 if point in WORKER_POINTS else 1), done
        wait_until(lambda: c.health().workers == 2, 90, "the nanny to restart the killed worker")


@pytest.mark.parametrize("point", POINTS)
def test_server_killed_at(point: str, faulty: dict[str, object], data_tmp: Path) -> None:
    server, data, faults, env = _parts(faulty)
    with server.client() as c:
        exr = exr_bytes(make_envmap(32, seed=200 + POINTS.index(point)), data_tmp)
        envmap = c.upload_envmap(exr)
        before = blobs(data)
        arm(faults, point)
        job = c.submit(envmap.id, SPEC, epsilon=EPSILON)
        job_id, _ = reached(faults, point)
        assert job_id == job.id
    server.kill()  # SIGKILL to the process group: server, scheduler and workers at once
    release(faults, point)
    database = faulty["database"]
    assert isinstance(database, Backend)
    restarted = start_server(data, env, log_name=f"server-{point}.log", database=database)
    faulty["server"] = restarted
    with restarted.client() as c:
        done = finished_once(c, data, job.id, exr, before)
        assert done.submissions == 2  # once by each server process
        # held after its blobs were written, the restarted run finds them through the ref or writes the same bytes
        assert c.list_jobs(state="running") == [] and c.list_jobs(state="queued") == []


# ------------------------------------------------------------------------------------------------ cancel
#: The stated bounds: a cancelled job's worker stops computing within STOP_BOUND_S of the cancel and spends at most
#: STOP_CPU_S of CPU time meanwhile. The watch looks every 0.2 s (relight.worker.progress.CANCEL_POLL_S); the rest
#: is the C call in progress (one einsum or SH synthesis: milliseconds at these orders) and the cancel's way through
#: the scheduler. CPU time is the measure that does not depend on how loaded the shared test machine is (wall time
#: stretches with the load); the wall bound is generous for the same reason.
STOP_BOUND_S = 60.0
STOP_CPU_S = 1.0
#: An SHRM long enough to cancel in the middle: Torrance-Sparrow at F = 255, P = 16 (289 maps) on a 256 x 512 map
#: takes about 5 CPU seconds in a worker after its "prefiltering" stage starts (mostly the BRDF coefficients; 6.6 s
#: in all, measured), so cancelled 1 CPU second in, about 4 CPU seconds would be left.
LONG = {"brdf": "torrance-sparrow:alpha=0.2,fresnel=none", "order": 255, "p_order": 16, "size": 64}
#: A worker that computes uses a whole core's share; an idle one (heartbeats) well under 5 % of a core.
IDLE_CPU_PER_S = 0.05


def cpu_seconds(pid: int) -> float:
    t = psutil.Process(pid).cpu_times()
    return float(t.user + t.system)


def test_cancel_mid_computation_stops_the_worker(faulty: dict[str, object], data_tmp: Path) -> None:
    """Cancelled inside a long SHRM synthesis (no stage boundary for seconds), the worker stops computing within
    STOP_BOUND_S and writes nothing afterwards; the same worker then runs the next job."""
    server, data, faults, _ = _parts(faulty)
    arm(faults, "none")
    with server.client() as c:
        env = c.upload_envmap(exr_bytes(make_envmap(256, seed=400), data_tmp))
        job = c.submit(env.id, LONG["brdf"], order=LONG["order"], p_order=LONG["p_order"], size=LONG["size"])
        computing = wait_until(lambda: (j := c.get_job(job.id)).stage == "prefiltering" and j.worker and j, 120,
                               "the job to start prefiltering")
        pid = worker_pid(server, str(computing.worker))
        before = cpu_seconds(pid)
        wait_until(lambda: cpu_seconds(pid) - before > 1.0, 60, "the worker to compute for a second")
        blobs_at_cancel = blobs(data)
        t_cancel, cpu_cancel = time.monotonic(), cpu_seconds(pid)
        assert c.cancel_job(job.id).state == JobState.cancelled

        def idle() -> bool:
            t0 = cpu_seconds(pid)
            time.sleep(1.0)
            return cpu_seconds(pid) - t0 < IDLE_CPU_PER_S

        wait_until(idle, STOP_BOUND_S, "the cancelled worker to stop computing", interval=0.0)
        # the idle window itself is not computing time
        cpu_after = cpu_seconds(pid) - cpu_cancel - IDLE_CPU_PER_S
        assert cpu_after < STOP_CPU_S, f"the worker computed for {cpu_after:.2f} CPU seconds after the cancel"
        assert time.monotonic() - t_cancel < STOP_BOUND_S + 1.0
        time.sleep(2.0)
        assert blobs(data) == blobs_at_cancel, "a cancelled job wrote blobs"
        assert not (data / "blobs" / "refs" / f"job-{job.id}").exists()
        assert list((data / "blobs" / "tmp").iterdir()) == []
        assert c.get_job(job.id).state == JobState.cancelled
        assert psutil.pid_exists(pid)  # the worker was interrupted, not killed
        nxt = c.submit(env.id, SPEC, epsilon=EPSILON)
        assert c.wait(nxt.id, timeout=120).state == JobState.succeeded


# ------------------------------------------------------------------------------------------------ scheduler
@pytest.fixture(scope="module")
def external(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, object]]:
    """A separately started scheduler and two ``relight worker`` processes (what a deployment supervises and
    restarts), and a server pointed at them: the documented deployment, every connection mutual TLS with the
    certificate of ``relight tls init`` (``relight scheduler --tls-*``, the workers and the server from the
    ``RELIGHT_TLS_*`` environment), as in the compose file; the server's job table on ``database``."""
    tmp = tmp_path_factory.mktemp("faulty-external")
    faults = tmp_path_factory.mktemp("faults-external")
    port = free_port()
    address = f"tls://127.0.0.1:{port}"
    tls = tls_init(tmp / "certs")
    env = {"RELIGHT_TEST_FAULT_DIR": str(faults)}
    procs: dict[str, Proc] = {}
    log_no = iter(range(1000))

    def start_scheduler() -> Proc:
        log = tmp / f"scheduler{next(log_no)}.log"  # one log per start: the address line is this start's
        sched = Proc([sys.executable, "-m", "relight.cli", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                      "--tls-ca-file", tls["RELIGHT_TLS_CA_FILE"], "--tls-cert", tls["RELIGHT_TLS_CERT"],
                      "--tls-key", tls["RELIGHT_TLS_KEY"]], base_env(env), log).start()
        wait_until(lambda: f"relight: scheduler at {address}" in sched.output(), 60, "the scheduler to start")
        return sched

    def start_worker(i: int) -> Proc:
        return Proc([sys.executable, "-m", "relight.cli", "worker", "--scheduler", address, "--name",
                     f"relight-w{i}", "--host", "127.0.0.1", "--memory-limit", "2GiB"], base_env({**env, **tls}),
                    tmp / f"worker{i}.log").start()

    state: dict[str, object] = {"tmp": tmp, "faults": faults, "procs": procs, "start_scheduler": start_scheduler,
                                "start_worker": start_worker}
    try:
        procs["scheduler"] = start_scheduler()
        for i in range(2):
            procs[f"worker{i}"] = start_worker(i)
        server = start_server(tmp / "server", {**env, **tls, "RELIGHT_SCHEDULER": address}, database=database)
        procs["server"] = server
        with server.client() as c:
            wait_until(lambda: c.health().workers == 2, 90, "both workers to join the scheduler", interval=0.2)
        yield state
    finally:
        for p in reversed(list(procs.values())):
            p.stop()


@pytest.mark.parametrize("point", POINTS)
def test_scheduler_killed_at(point: str, external: dict[str, object], data_tmp: Path) -> None:
    procs, faults, tmp = external["procs"], external["faults"], external["tmp"]
    assert isinstance(procs, dict) and isinstance(faults, Path) and isinstance(tmp, Path)
    server = procs["server"]
    assert isinstance(server, Server)
    data = tmp / "server"
    start_scheduler, start_worker = external["start_scheduler"], external["start_worker"]
    assert callable(start_scheduler) and callable(start_worker)
    with server.client() as c:
        # both workers on this scheduler before it dies: the previous case restarted them, and its job may have
        # finished on one of them while the other was still starting (that one then joined the *next* scheduler
        # on the same address and never exited)
        wait_until(lambda: c.health().workers == 2, 90, "both workers to join the scheduler", interval=0.2)
        exr = exr_bytes(make_envmap(32, seed=300 + POINTS.index(point)), data_tmp)
        env = c.upload_envmap(exr)
        before = blobs(data)
        arm(faults, point)
        job = c.submit(env.id, SPEC, epsilon=EPSILON)
        assert reached(faults, point)[0] == job.id
        procs["scheduler"].kill()
        release(faults, point)
        # Dask workers (and their nannies) exit when their scheduler is lost; the supervisor (compose's restart
        # policy) brings the scheduler back on its address and restarts the workers
        procs["scheduler"] = start_scheduler()
        for i in range(2):
            wait_until(lambda i=i: not procs[f"worker{i}"].alive(), 90, f"worker {i} to exit", interval=0.2)
            procs[f"worker{i}"].stop()
            procs[f"worker{i}"] = start_worker(i)
        finished_once(c, data, job.id, exr, before)
        assert c.list_jobs(state="running") == [] and c.list_jobs(state="queued") == []


# ------------------------------------------------------------------------------------------------ SIGTERM
#: Seconds a SIGTERM'ed server may take to exit: uvicorn's graceful shutdown (5 s for open requests and event
#: streams, relight.server.run), then the job watchers, the Dask client and the embedded cluster (20 s at most).
SHUTDOWN_BOUND_S = 60.0


def test_sigterm_with_running_jobs_of_every_kind(tmp_path_factory: pytest.TempPathFactory, data_tmp: Path,
                                                 database: Backend) -> None:
    """SIGTERM while an SHRM, a tradeoff sweep and a scene are running or queued (and an event stream is open):
    the server exits cleanly (status 0, no traceback, no process of its group left, no tmp debris) within
    SHUTDOWN_BOUND_S; the next server resumes all three and each finishes once."""
    import httpx

    from .routes.test_jobs_kinds import KINDS, events, submit

    data = tmp_path_factory.mktemp("sigterm")
    # the jobs wait (TEST ONLY delay) far longer than the test takes to send SIGTERM: none can finish before it
    server = start_server(data, {"RELIGHT_TEST_JOB_DELAY_S": "60"}, database=database)
    with httpx.Client(base_url=server.url, timeout=60) as http:
        env = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=500), data_tmp)).json()["id"]
        ids = {kind: submit(http, kind, env, 7) for kind in KINDS}
        wait_until(lambda: sum(http.get(f"/jobs/{i}").json()["state"] == "running" for i in ids.values()) == 2,
                   90, "two jobs to run (two workers; the third queued)")
        stream = events(http, f"/jobs/{ids['shrm']}/events")
        next(stream)  # the stream is open
        group = {p.pid for p in psutil.Process(server.pid).children(recursive=True)}
        assert len(group) >= 2
        t0 = time.monotonic()
        assert server.proc is not None
        server.proc.send_signal(signal.SIGTERM)
        code = server.proc.wait(timeout=SHUTDOWN_BOUND_S)
        took = time.monotonic() - t0
        with contextlib.suppress(httpx.HTTPError):  # the open stream ends with the server, without "end"
            assert [e.event for e in stream if e.event == "end"] == []
    log = server.output()
    server.stop()
    # uvicorn raises the signal it caught again once it has shut down cleanly: "killed by SIGTERM" is the clean exit
    assert code in (0, -signal.SIGTERM), f"exit status {code}:\n{log[-3000:]}"
    assert "Traceback" not in log, log[-3000:]
    assert took < SHUTDOWN_BOUND_S
    wait_until(lambda: not any(psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE
                               for p in group), 30, "the server's worker processes to exit")
    assert list((data / "blobs" / "tmp").iterdir()) == []

    restarted = start_server(data, log_name="server2.log", database=database)
    try:
        with httpx.Client(base_url=restarted.url, timeout=60) as http:
            for kind, job_id in ids.items():
                final = json.loads([e for e in events(http, f"/jobs/{job_id}/events")][-1].data)
                assert final["state"] == "succeeded" and final["kind"] == kind, final
                assert final["submissions"] == 2, final  # once by each server process
            assert http.get(f"/tradeoffs/{ids['tradeoff']}").json()["points"]
            assert http.get(f"/scenes/{ids['scene']}").json()["files"]
            assert len(manifests_for(data, ids["shrm"])) == 1
    finally:
        restarted.stop()
