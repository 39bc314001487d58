"""The cost-model calibration behind ``/plan`` (``relight.costmodel``), owned by one service created at start-up
and closed at shutdown (:class:`relight.server.state.Services`).

``/plan`` predicts seconds with ``relight.planning.plan_job``: the calibration cached for this machine if one exists,
else the built-in constants while a calibration runs once in a worker
(:func:`relight.worker.analysis.calibrate_costmodel`, a few seconds), which writes the calibration file that later
plans read. :meth:`CalibrationService.ensure` starts it at most once per server process; :meth:`close` cancels one
still running.
"""

from __future__ import annotations

import logging
from typing import Any

from relight.server.cluster import Cluster
from relight.worker.analysis import calibrate_costmodel

log = logging.getLogger("relight.server")

#: The Dask key of the calibration (one per cluster at a time).
CALIBRATION_KEY = "relight-costmodel-calibration"


class CalibrationService:
    def __init__(self, cluster: Cluster) -> None:
        self.cluster = cluster
        self.future: Any = None  # distributed.Future of the one calibration this process started

    def ensure(self) -> None:
        """Start the calibration in a worker unless this process started one already; call on the event loop."""
        if self.future is not None:
            return
        try:
            self.future = self.cluster.submit(calibrate_costmodel, key=CALIBRATION_KEY)
        except RuntimeError as exc:  # the cluster is not started
            log.warning("could not start the cost-model calibration: %s", exc)

    async def close(self) -> None:
        """Cancel the calibration if it is still running (its file is written only when it completes)."""
        if self.future is not None and not self.future.done():
            await self.cluster.cancel(self.future)
        self.future = None
