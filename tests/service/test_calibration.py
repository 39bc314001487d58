"""``relight.server.services.calibration.CalibrationService``: one calibration per server process, owned by the
service (started on the first uncalibrated plan, cancelled at shutdown if it still runs)."""

from __future__ import annotations

import asyncio
from typing import Any

from relight.server.services.calibration import CALIBRATION_KEY, CalibrationService
from relight.worker.analysis import calibrate_costmodel


class FakeFuture:
    def __init__(self) -> None:
        self.finished = False

    def done(self) -> bool:
        return self.finished


class FakeCluster:
    def __init__(self, started: bool = True) -> None:
        self.started = started
        self.submitted: list[tuple[Any, str]] = []
        self.cancelled: list[FakeFuture] = []

    def submit(self, fn: Any, *args: Any, key: str, **kwargs: Any) -> FakeFuture:
        if not self.started:
            raise RuntimeError("the Dask client is not started")
        self.submitted.append((fn, key))
        return FakeFuture()

    async def cancel(self, future: FakeFuture) -> None:
        self.cancelled.append(future)


def test_one_calibration_per_process_cancelled_at_close() -> None:
    cluster = FakeCluster()
    service = CalibrationService(cluster)  # type: ignore[arg-type]
    service.ensure()
    service.ensure()
    assert cluster.submitted == [(calibrate_costmodel, CALIBRATION_KEY)]
    running = service.future
    asyncio.run(service.close())
    assert cluster.cancelled == [running] and service.future is None


def test_a_finished_calibration_is_not_cancelled() -> None:
    cluster = FakeCluster()
    service = CalibrationService(cluster)  # type: ignore[arg-type]
    service.ensure()
    service.future.finished = True
    asyncio.run(service.close())
    assert cluster.cancelled == []


def test_no_cluster_no_calibration_and_no_error() -> None:
    cluster = FakeCluster(started=False)
    service = CalibrationService(cluster)  # type: ignore[arg-type]
    service.ensure()
    assert service.future is None
    cluster.started = True
    service.ensure()  # tried again once the cluster is up
    assert len(cluster.submitted) == 1
