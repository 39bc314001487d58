"""The embedded cluster's job slots against Dask's scheduler-side queuing (``relight.worker.slots``), on a real
``LocalCluster`` as the server makes it (:class:`relight.server.cluster.Cluster`).

Six jobs (two running, four waiting for a job slot on their workers) saturate both workers by Dask's count; then
fourteen interactive tasks of one group run one after the other, each held (as a cached result would be). With
Dask's default ``worker-saturation`` 1.1 the ninth (the group now larger than twice the cluster's threads: "root-ish")
is queued at the scheduler with no worker until a job ends (measured: ``queued`` after 8 s, jobs of 60 s); with
``SCHEDULER_CONFIG`` every one runs on a worker's thread kept free of jobs while the jobs still run.
"""

from __future__ import annotations

import asyncio
import time
import uuid
from pathlib import Path

import pytest

from relight.server.cluster import Cluster
from relight.server.config import Settings
from relight.worker.slots import JOB_RESOURCE, task_options
from relight.worker.tasks import warmup

pytestmark = pytest.mark.timeout(300)
JOB_S = 600.0  # longer than the test: no job can end and free a slot while it runs
WAIT_S = 60.0  # a bound on one interactive task of ~1 ms: only a task held back by the scheduler comes near it


def test_interactive_tasks_run_while_waiting_jobs_saturate_the_workers(tmp_path: Path) -> None:
    async def scenario() -> None:
        cluster = Cluster(Settings(data_dir=tmp_path, n_workers=2, threads_per_worker=1))
        await cluster.start()
        try:
            client = cluster.client
            jobs = [client.submit(time.sleep, JOB_S, key=f"slot-job-{i}", pure=False, **task_options(job=True))
                    for i in range(6)]
            sched = cluster.local.scheduler
            for _ in range(600):
                if sum(ws.used_resources.get(JOB_RESOURCE, 0) > 0 for ws in sched.workers.values()) == 2:
                    break
                await asyncio.sleep(0.1)
            assert all(len(ws.processing) >= 3 for ws in sched.workers.values()), "the jobs saturate no worker"
            held = []
            for i in range(14):
                fut = cluster.submit(warmup, key=f"relight-analyze-{uuid.uuid4().hex}")
                try:
                    await asyncio.wait_for(asyncio.shield(fut), WAIT_S)
                except TimeoutError:
                    raise AssertionError(f"interactive task {i} is {sched.tasks[fut.key].state!r} after {WAIT_S} s "
                                         "while six jobs hold or wait for the job slots") from None
                held.append(fut)
            assert not any(j.done() for j in jobs)
            await client.cancel(jobs, force=True)
        finally:
            await cluster.close()

    asyncio.run(scenario())
