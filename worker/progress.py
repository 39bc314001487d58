"""Progress and cancellation for task functions running on a Dask worker.

A task reports ``(stage, fraction)`` through a :class:`Reporter`. On a Dask worker each report becomes a Dask
event (``Worker.log_event`` on topic :data:`TOPIC`); the server subscribes to the topic
(``Client.subscribe_topic``) and stores and streams what it receives. Outside a worker (a direct call, a unit
test) reports go to an optional callback.

Reports are throttled here (at most one per ``min_interval`` seconds unless the stage changes) so a chatty loop
cannot flood the scheduler. Every message carries the job id and the submission number, so the server can drop
reports from a superseded submission.

Every kind of job runs through :func:`run_job`, the one Dask entry point of jobs: it reports ``started``, runs the
test-only delay (``RELIGHT_TEST_JOB_DELAY_S``), calls the kind's task function with a :class:`JobContext` and the
job's canonical request, and checks for cancellation once more before handing the result back, so a job cancelled
while its task ran never returns a result.

Cancellation: when the server cancels a job it releases the Dask future; the worker then marks the running
task ``cancelled``. :meth:`Reporter.check_cancelled` looks at that state between stages and raises
:class:`JobCancelled`, so a cancelled job stops at the next stage boundary instead of running to the end. Long
computations have no stage boundaries (an order search, an SHRM synthesis: minutes with none), so while a task runs
a :class:`CancelWatch` thread looks at the state every :data:`CANCEL_POLL_S` and raises :class:`JobCancelled`
inside the computing thread: the job stops at its next Python bytecode, after the C call in progress (one SH
transform or BLAS call) returns.
"""

from __future__ import annotations

import ctypes
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from relight.worker.blobs import BlobStore

TOPIC: Final = "relight-progress"
#: Seconds between progress reports of the (test-only) artificial delay loop.
DELAY_STEP_S: Final = 0.05
#: Seconds between a :class:`CancelWatch`'s looks at its task's state (a cancelled job stops this much later).
CANCEL_POLL_S: Final = 0.2


class JobCancelled(Exception):
    """Raised inside a task whose future was cancelled."""


def _current_worker() -> Any:
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):  # ValueError: not running on a worker
        return None


def _current_key() -> Any:
    try:
        from distributed.worker import thread_state  # type: ignore[attr-defined]
    except ImportError:
        return None
    return getattr(thread_state, "key", None)


class Reporter:
    """Publishes stage/fraction updates for one job (see the module docstring)."""

    def __init__(
        self,
        job_id: str,
        submission: int = 0,
        *,
        min_interval: float = 0.1,
        callback: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        self.job_id = job_id
        self.submission = submission
        self.min_interval = min_interval
        self.callback = callback
        self._worker = _current_worker()
        self._key = _current_key()
        self._last_stage: str | None = None
        self._last_time = 0.0

    def emit(self, event: str, **fields: Any) -> None:
        """Send one message now (no throttling): ``event`` is ``started``, ``progress`` ..."""
        msg = {"job": self.job_id, "submission": self.submission, "event": event, "time": time.time(), **fields}
        if self._worker is not None:
            self._worker.log_event(TOPIC, msg)
        if self.callback is not None:
            self.callback(msg)

    def started(self) -> None:
        worker = getattr(self._worker, "address", None) if self._worker is not None else None
        self.emit("started", worker=worker)

    def __call__(self, stage: str, fraction: float) -> None:
        """Report that the job is in ``stage`` with overall completion ``fraction`` in [0, 1]."""
        self.check_cancelled()
        now = time.monotonic()
        if stage == self._last_stage and now - self._last_time < self.min_interval:
            return
        self._last_stage = stage
        self._last_time = now
        self.emit("progress", stage=stage, fraction=float(min(max(fraction, 0.0), 1.0)))

    def check_cancelled(self) -> None:
        """Raise :class:`JobCancelled` if the Dask task running this job has been cancelled."""
        if self._worker is None or self._key is None:
            return
        ts = self._worker.state.tasks.get(self._key)
        if ts is None or ts.state in ("cancelled", "released", "forgotten"):
            raise JobCancelled(f"job {self.job_id} was cancelled")


class CancelWatch:
    """``with CancelWatch(report): compute()`` — raise :class:`JobCancelled` inside the computing thread once the
    Dask task is cancelled (module docstring). Outside a worker it does nothing.

    The exception is delivered with ``PyThreadState_SetAsyncExc`` only while the block runs: leaving it disarms the
    watch under its lock and withdraws an exception not yet raised, so nothing outside the block (Dask's own code)
    can ever be interrupted.
    """

    def __init__(self, report: Reporter) -> None:
        self.report = report
        self.fired = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._armed = False
        self._target = 0
        self._thread: threading.Thread | None = None

    def __enter__(self) -> CancelWatch:
        if self.report._worker is None or self.report._key is None:
            return self
        self._target = threading.get_ident()
        self._armed = True
        self._thread = threading.Thread(target=self._run, name=f"relight-cancel-{self.report.job_id[:12]}",
                                        daemon=True)
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(CANCEL_POLL_S):
            try:
                self.report.check_cancelled()
            except JobCancelled:
                with self._lock:
                    if self._armed:
                        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(self._target),
                                                                   ctypes.py_object(JobCancelled))
                        self.fired = True
                return

    def __exit__(self, *exc: object) -> None:
        with self._lock:
            self._armed = False
            if self.fired:  # withdraw it if it is still pending (the block ended just as the job was cancelled)
                ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(self._target), None)
        self._stop.set()
        if self._thread is not None:
            self._thread.join()


@dataclass(frozen=True)
class JobContext:
    """What a job's task function gets besides its request: the job's id, the blob store, the progress reporter
    and the server's input limit."""

    job_id: str
    store: BlobStore
    report: Reporter
    max_pixels: int | None = None


#: A job kind's task function: ``task(ctx, request) -> result`` (plain data in, plain JSON-able data out).
Task = Callable[[JobContext, dict[str, Any]], dict[str, Any]]


def artificial_delay(seconds: float, report: Reporter) -> None:
    """TEST ONLY (settings.test_job_delay_s): wait in small steps, reporting progress and honouring cancel."""
    if seconds <= 0:
        return
    steps = max(1, math.ceil(seconds / DELAY_STEP_S))
    for i in range(steps):
        report("test_delay", 0.5 * i / steps)
        time.sleep(seconds / steps)


def run_job(task: Task, store_root: str, job: dict[str, Any]) -> dict[str, Any]:
    """Run one job of any kind on a worker (module docstring).

    ``job``: ``job_id``, ``submission``, ``request`` (the kind's canonical request), ``max_pixels`` and
    ``test_delay_s`` (TEST ONLY). Raises :class:`JobCancelled` when the job was cancelled meanwhile.
    """
    report = Reporter(str(job["job_id"]), int(job.get("submission", 0)))
    report.started()
    artificial_delay(float(job.get("test_delay_s") or 0.0), report)
    ctx = JobContext(str(job["job_id"]), BlobStore(store_root), report, job.get("max_pixels"))
    try:
        with CancelWatch(report):
            result = task(ctx, job["request"])
    except JobCancelled as exc:
        raise JobCancelled(str(exc) or f"job {report.job_id} was cancelled while computing") from None
    report.check_cancelled()
    report("done", 1.0)
    return result
