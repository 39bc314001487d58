"""``relight.server.services.runner``: resubmission of lost Dask futures and the classification of failures, shared
by SHRM
jobs and analysis jobs. The futures here are plain asyncio ones that fail the way Dask's do when the scheduler
connection drops (``FutureCancelledError``); the real cluster paths run in ``test_resilience.py``."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any

import pytest
from distributed.client import FutureCancelledError
from distributed.scheduler import KilledWorker

from relight.errors import InputError
from relight.server.services import runner
from relight.worker.progress import JobCancelled


def settled(value: Any = None, exc: BaseException | None = None) -> asyncio.Future[Any]:
    fut: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
    if exc is not None:
        fut.set_exception(exc)
    else:
        fut.set_result(value)
    return fut


def run(outcomes: list[BaseException | str], *, wanted: bool = True) -> tuple[tuple[bool, Any], list[int]]:
    """Drive ``run_with_resubmits`` over futures failing or finishing as ``outcomes`` says; the attempts made."""
    attempts: list[int] = []

    async def main() -> tuple[bool, Any]:
        async def submit(attempt: int) -> Any:
            attempts.append(attempt)
            out = outcomes[attempt]
            return settled(exc=out) if isinstance(out, BaseException) else settled(out)

        async def still() -> bool:
            return wanted

        return await runner.run_with_resubmits(submit, still, name="test")

    return asyncio.run(main()), attempts


@pytest.fixture(autouse=True)
def no_backoff(monkeypatch: pytest.MonkeyPatch) -> None:
    real_sleep = asyncio.sleep
    monkeypatch.setattr(runner.asyncio, "sleep", lambda s: real_sleep(0))


def lost(k: int) -> FutureCancelledError:
    return FutureCancelledError(f"key-{k}", "scheduler-connection-lost")


def test_a_lost_future_is_submitted_again_until_it_finishes() -> None:
    (done, result), attempts = run([lost(0), lost(1), "result"])
    assert (done, result) == (True, "result") and attempts == [0, 1, 2]


def test_a_job_no_longer_wanted_is_not_resubmitted() -> None:
    (done, result), attempts = run([lost(0), "never"], wanted=False)
    assert (done, result) == (False, None) and attempts == [0]


def test_too_many_losses_fail_retryably() -> None:
    with pytest.raises(runner.SchedulerLost) as info:
        run([lost(k) for k in range(runner.MAX_RESUBMITS + 1)])
    reason, retryable = runner.failure_of(info.value)
    assert retryable and f"{runner.MAX_RESUBMITS + 1} times" in reason


def test_the_task_error_propagates_without_resubmission() -> None:
    with pytest.raises(InputError, match="bad map"):
        run([InputError("bad map"), "never"])


def test_submit_returning_none_stops() -> None:
    async def main() -> tuple[bool, Any]:
        async def submit(attempt: int) -> Any:
            return None

        async def still() -> bool:
            raise AssertionError("not asked")

        return await runner.run_with_resubmits(submit, still, name="test")

    assert asyncio.run(main()) == (False, None)


@pytest.mark.parametrize(("exc", "retryable", "fragment"), [
    (InputError("the map has NaN texels"), False, "NaN texels"),
    (KilledWorker("task", SimpleNamespace(address="tcp://127.0.0.1:1"), 2), True, "memory limit"),
    (JobCancelled("job j was cancelled"), True, "cancelled"),
    (ValueError("boom"), True, "ValueError: boom"),
])
def test_failure_classification(exc: BaseException, retryable: bool, fragment: str) -> None:
    reason, again = runner.failure_of(exc)
    assert again is retryable and fragment in reason


def test_a_full_disk_fails_retryably_without_the_path() -> None:
    """Issue 12: a full disk failed the job with the raw OSError text (a server path); the reason now says what
    happened, and the job can be resubmitted."""
    import errno

    from relight.server.services.runner import failure_of

    reason, retryable = failure_of(OSError(errno.ENOSPC, "No space left on device", "/srv/relight/blobs/tmp/x.part"))
    assert retryable and "full" in reason and "/srv" not in reason


def test_full_disk_in_other_words_and_paths_are_never_in_a_reason() -> None:
    """OpenEXR reports a full disk as a RuntimeError with the file's path (found by
    tests/service/test_reliability_disk.py); any other error's text loses its absolute paths."""
    from relight.server.services.runner import failure_of

    exr = RuntimeError('Failed to write pixel data to image file "/srv/relight/blobs/tmp/ab12.exr". No space left '
                       "on device.")
    reason, retryable = failure_of(exr)
    assert retryable and "full" in reason and "/srv" not in reason
    reason, _ = failure_of(RuntimeError("cannot open /srv/relight/blobs/sha256/ab/cd/abcd for reading (see a/b)"))
    assert reason == "RuntimeError: cannot open <path> for reading (see a/b)", reason
