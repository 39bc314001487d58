"""How a worker's threads are shared between jobs and interactive requests.

Jobs (SHRMs, tables, sweeps, scenes...) run for seconds to hours; interactive requests (an upload's decode, a
texture for the viewer, a reference image) take well under a second to a few seconds, and a user waits on them.
Were both in one queue, an upload made while every worker runs a long job would wait for a job to end (a 60 s
client timeout seen in the stateful API fuzz run). So every worker has one thread more than its job slots:

* each worker declares the Dask resource :data:`JOB_RESOURCE` = its job slots (``--nthreads``, default 1), and
  every job task asks for one unit of it, so at most that many jobs run on a worker at once;
* the extra thread is free of the resource: interactive tasks (submitted with :data:`INTERACTIVE_PRIORITY`, ahead
  of any queued job) always find a thread, at the cost of sharing the CPU with the running jobs while they last;
* the scheduler does not hold tasks back (:data:`SCHEDULER_CONFIG`): Dask's default queues a task of a large group
  with no dependencies (every upload decode is one of ``relight-analyze``) at the scheduler while every worker is
  "saturated", and it counts the jobs waiting on a worker for its job slot as saturation. With more jobs than
  slots an upload then waited, unscheduled, until jobs ended (seen in the stateful API fuzz run: an OBJ upload
  ``queued`` with no worker for over 60 s while both workers' threads for interactive tasks were idle).
"""

from __future__ import annotations

from typing import Any, Final

#: The Dask worker resource a job task holds while it runs.
JOB_RESOURCE: Final = "relight-job"
#: Dask priority of interactive tasks (jobs keep the default 0; higher runs first).
INTERACTIVE_PRIORITY: Final = 10
#: Dask configuration of the scheduler (embedded or ``relight scheduler``): no scheduler-side queuing.
SCHEDULER_CONFIG: Final = {"distributed.scheduler.worker-saturation": "inf"}


def worker_options(job_slots: int) -> dict[str, Any]:
    """The ``nthreads`` and ``resources`` of a worker that runs ``job_slots`` jobs at once plus interactive tasks."""
    if job_slots < 1:
        raise ValueError(f"a worker needs at least one job slot, not {job_slots}")
    return {"nthreads": job_slots + 1, "resources": {JOB_RESOURCE: job_slots}}


def task_options(*, job: bool) -> dict[str, Any]:
    """The ``Client.submit`` options of a job task (one job slot) or an interactive task (ahead of every job)."""
    return {"resources": {JOB_RESOURCE: 1}} if job else {"priority": INTERACTIVE_PRIORITY}


__all__ = ["INTERACTIVE_PRIORITY", "JOB_RESOURCE", "SCHEDULER_CONFIG", "task_options", "worker_options"]
