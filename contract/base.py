"""The contract's building blocks: the request/response base models, content ids, job states, problem details and
the service's health (pydantic only: no FastAPI, no NumPy).

``...Create`` models are request bodies (:class:`Strict`), ``...Public`` models are responses (:class:`Public`),
full-stack-fastapi-template style.
"""

from __future__ import annotations

import math
from datetime import datetime
from enum import StrEnum
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

Digest = Annotated[str, Field(pattern=r"^[0-9a-f]{64}$", description="SHA-256, 64 lowercase hex digits")]
Fraction = Annotated[float, Field(gt=0.0, lt=1.0)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3, description="x, y, z (normalised here)")]


class Strict(BaseModel):
    """Request models: unknown keys and NaN/Inf are rejected (422 naming the field)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Public(BaseModel):
    model_config = ConfigDict(extra="ignore")


class JobState(StrEnum):
    queued = "queued"
    running = "running"
    succeeded = "succeeded"
    failed = "failed"
    cancelled = "cancelled"

    @property
    def terminal(self) -> bool:
        return self in (JobState.succeeded, JobState.failed, JobState.cancelled)


ACTIVE_STATES = (JobState.queued, JobState.running)


class Problem(Public):
    """RFC 9457 problem details (``application/problem+json``)."""

    type: str = "about:blank"
    title: str
    status: int
    detail: str | None = None
    instance: str | None = None
    errors: list[dict[str, Any]] | None = Field(default=None, description="per-field validation errors")


class Health(Public):
    status: str = Field(description="ok, or degraded (the reasons are in problems)")
    version: str
    algorithm_version: str
    scheduler: str = Field(description="embedded or external (the address is never published)")
    workers: int
    database: str
    problems: list[str] = Field(default_factory=list,
                                description="what is degraded: workers, scheduler, database, disk")
    probed_at: datetime | None = Field(None, description="when the probes behind this answer ran (they run in the "
                                                         "background, every second by default)")


def parse_view(text: str) -> tuple[float, float, float]:
    """``"x,y,z"`` to a unit vector; raises ``ValueError`` quoting the text when it is not one."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"view must be three comma-separated numbers x,y,z, got {text!r}")
    try:
        v = tuple(float(p) for p in parts)
    except ValueError:
        raise ValueError(f"view must be three comma-separated numbers x,y,z, got {text!r}") from None
    if not all(math.isfinite(c) for c in v):
        raise ValueError(f"view components must be finite, got {text!r}")
    n = math.sqrt(sum(c * c for c in v))
    if n < 1e-12:
        raise ValueError(f"view must be a non-zero vector, got {text!r}")
    return (v[0] / n, v[1] / n, v[2] / n)
