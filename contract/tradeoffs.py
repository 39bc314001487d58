"""Accuracy–time sweeps (``POST /tradeoffs``, ``relight.tradeoff``): the request, and the answer whose points and
``meta`` are the core's typed reports (``relight.tradeoff.report``).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import Field

from relight.contract.base import Digest, Fraction, JobState, Public, Strict, Vector3
from relight.contract.resources import BrdfRef
from relight.tradeoff.report import TradeoffMeta, TradeoffPoint


class TradeoffCreate(Strict):
    """An accuracy–time sweep (``relight.tradeoff``): the frequency method at several tolerances and the angular
    method at several truncations, on one map and BRDF, measured against the untruncated angular reference."""

    envmap: Digest
    brdf: BrdfRef
    rows: int | None = Field(None, ge=8, le=256, description="area-average the map to this many rows (default 64)")
    size: int | None = Field(None, ge=4, le=128, description="output rows S of every map (default rows / 2)")
    epsilons: list[Fraction] | None = Field(None, min_length=1, max_length=10, description="frequency method")
    truncations: list[Fraction] | None = Field(None, max_length=10, description="angular method (App. D)")
    view: Vector3 | None = Field(None, description="view direction for view-dependent BRDFs")


class TradeoffPublic(Public):
    id: Digest
    state: JobState
    stage: str | None = None
    progress: float = 0.0
    failure_reason: str | None = None
    envmap: Digest
    brdf: Digest
    brdf_spec: dict[str, Any]
    params: dict[str, Any]
    points: list[TradeoffPoint] | None = Field(None, description="per point: method, orders, predicted_error, "
                                               "measured_error, mitsuba_error (null without a Mitsuba 3 twin), "
                                               "image_error, predicted_seconds, measured_seconds, pareto, ... (the "
                                               "core's relight.tradeoff.TradeoffPoint)")
    meta: TradeoffMeta | None = Field(None, description="what the sweep ran on (the core's "
                                      "relight.tradeoff.TradeoffMeta); mitsuba: the Mitsuba 3 comparison's settings, "
                                      "noise floor and reference_error, or computed false and the reason")
    created_at: datetime
    finished_at: datetime | None = None
    links: dict[str, str] = {}
