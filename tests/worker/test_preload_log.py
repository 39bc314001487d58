"""The worker's heartbeat log filter (``relight.worker.preload``): Dask's own heartbeat-failure record, logged the way
``distributed.worker`` logs it, becomes one warning line without a traceback; other records keep theirs."""

from __future__ import annotations

import inspect
import logging

import distributed.worker
import pytest

from relight.worker.preload import HEARTBEAT_FAILED, install_log_filter


def test_dask_still_logs_the_message_the_filter_matches() -> None:
    assert f'logger.exception("{HEARTBEAT_FAILED}.")' in inspect.getsource(distributed.worker.Worker.heartbeat)


def test_heartbeat_failure_is_one_line_other_records_unchanged(caplog: pytest.LogCaptureFixture) -> None:
    install_log_filter()
    install_log_filter()  # idempotent: one filter
    logger = logging.getLogger("distributed.worker")
    assert sum(type(f).__name__ == "HeartbeatLogFilter" for f in logger.filters) == 1
    with caplog.at_level(logging.INFO, logger="distributed.worker"):
        try:
            raise TimeoutError("connect timed out")
        except TimeoutError:
            logger.exception(f"{HEARTBEAT_FAILED}.")
            logger.exception("Unexpected exception during heartbeat. Closing worker.")
    beat, other = caplog.records
    assert beat.levelno == logging.WARNING and beat.exc_info is None
    assert "TimeoutError: connect timed out" in beat.getMessage()
    assert "Traceback" not in caplog.text.split("Unexpected")[0]
    assert other.levelno == logging.ERROR and other.exc_info is not None
