"""Dask preload module (``preload=["relight.worker.preload"]``): imports the numerical core when a worker process
starts, so the first job does not pay for it; stops the worker's HTTP server (nothing but the scheduler talks to a
worker); and turns Dask's heartbeat-failure traceback into one line (:class:`HeartbeatLogFilter`)."""

from __future__ import annotations

import logging
from typing import Any

from relight.worker.tasks import warmup

#: The message Dask's worker logs, with a traceback, when a heartbeat to the scheduler fails.
HEARTBEAT_FAILED = "Failed to communicate with scheduler during heartbeat"


class HeartbeatLogFilter(logging.Filter):
    """A failed heartbeat is an operational event (the scheduler is busy, restarting or shutting down: a server's
    SIGTERM closes the scheduler while its workers still beat), not a defect of the worker: log it as one warning line
    naming the exception, without the traceback of Dask's connection code that an operator cannot act on. Every
    other record passes unchanged."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage().startswith(HEARTBEAT_FAILED) and record.exc_info:
            exc = record.exc_info[1]
            record.msg = f"{HEARTBEAT_FAILED} ({type(exc).__name__}: {exc}); the worker retries or closes"
            record.args = ()
            record.exc_info = None
            record.exc_text = None
            record.levelno, record.levelname = logging.WARNING, "WARNING"
        return True


def install_log_filter() -> None:
    logger = logging.getLogger("distributed.worker")
    if not any(isinstance(f, HeartbeatLogFilter) for f in logger.filters):
        logger.addFilter(HeartbeatLogFilter())


def dask_setup(worker: Any) -> None:
    """Stop the worker's HTTP server (Dask starts one even without a dashboard: metrics, call stacks), install the
    heartbeat log filter, then warm up."""
    install_log_filter()
    http = getattr(worker, "http_server", None)
    if http is not None:
        http.stop()
    warmup()
