"""A job kind that is nothing but a task function and a registration (no route, no service): the server of
``test_jobs_submit.py`` loads this module through ``RELIGHT_JOB_KIND_MODULES``, its Dask workers import the task
from here. It proves that ``POST /jobs``, progress, SSE, cancellation, ``GET /jobs/{id}/result`` and
``GET /jobs/{id}/files/{name}`` need nothing else.

The task sums k^2 for k < n (checked by the test against the closed form n (n - 1) (2n - 1) / 6) and stores the
squares as a file of little-endian int64 (checked against NumPy in the test process).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from relight.server.services.kinds import JobKind, register
from relight.worker.progress import JobContext

#: Largest n: sum k^2 < n^3 / 3 stays far below 2^63 (int64) and the file below 8 MB.
MAX_N = 1_000_000


class SquaresCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    n: int = Field(ge=1, le=MAX_N, description="sum k^2 for k < n")


def sum_of_squares(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    k = np.arange(int(request["n"]), dtype=np.int64)
    ctx.report("squaring", 0.6)
    squares = k * k
    digest = ctx.store.put_bytes(squares.astype("<i8").tobytes())
    return {"sum": int(squares.sum()),
            "files": {"squares.bin": {"sha256": digest, "media_type": "application/octet-stream"}}}


SQUARES = register(JobKind("squares", sum_of_squares, request=SquaresCreate))
