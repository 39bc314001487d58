"""The typed reports of an accuracy–time sweep (``relight.tradeoff``; seed 000 §7.4, the reference App. D's angular
method untruncated): each point (:class:`TradeoffPoint`, one entry of ``tradeoff.json``) and what the sweep ran on
(:class:`TradeoffMeta`, the ``meta`` of a :class:`~relight.tradeoff.sweeps.Tradeoff`).

Frozen, keyword-only report dataclasses (``relight.reports``): their field names are the keys of the stored JSON
(``tradeoff_meta.json``, a ``tradeoff`` job's ``meta``), and the API's ``TradeoffPublic`` (``relight.contract``)
validates a stored result into them. Optional keys (:data:`relight.reports.OMIT_NONE`) are left out while None: the
input's ``envmap`` (the service's map digest) or ``path`` (the CLI's file), and every key of a Mitsuba 3 comparison
that did not run except ``computed`` and ``reason``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from relight.reports import OMIT_NONE, Report

#: ``meta.mitsuba`` of a result stored before sweeps compared with Mitsuba 3 (the ``tradeoff`` kind's result
#: version 1): such results validate, and say why nothing was measured.
NOT_RECORDED = "not measured: the result predates the Mitsuba 3 comparison"


@dataclass(frozen=True, kw_only=True)
class Grid(Report):
    """A lat-long grid's rows and columns."""

    height: int
    width: int


@dataclass(frozen=True, kw_only=True)
class SweepInput(Report):
    """The map the sweep ran on (after area-averaging to its rows), and where it came from."""

    height: int
    width: int
    envmap: str | None = field(default=None, metadata=OMIT_NONE)  # the service's map digest
    path: str | None = field(default=None, metadata=OMIT_NONE)  # the CLI's file
    original_height: int | None = field(default=None, metadata=OMIT_NONE)  # rows before averaging (CLI)


@dataclass(frozen=True, kw_only=True)
class SweepReference(Report):
    """The reference every point is measured against: the angular method, untruncated (App. D)."""

    method: str
    truncation: float
    seconds: float


@dataclass(frozen=True, kw_only=True)
class SweepCalibration(Report):
    """The cost model behind every point's predicted seconds (``relight.costmodel.Calibration``)."""

    key: str
    calibrated: bool
    created: str
    constants: dict[str, float]


@dataclass(frozen=True, kw_only=True)
class MitsubaComparison(Report):
    """The comparison with Mitsuba 3 (``relight.tradeoff.mitsuba``): its settings, the render's seconds and the two
    floors (``noise``: the image's own noise; ``reference_error``: the angular reference against Mitsuba), or, when
    ``computed`` is False, only the ``reason``."""

    computed: bool
    reason: str | None = field(default=None, metadata=OMIT_NONE)
    variant: str | None = field(default=None, metadata=OMIT_NONE)
    bsdf: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)
    view: tuple[float, float, float] | None = field(default=None, metadata=OMIT_NONE)
    image: Grid | None = field(default=None, metadata=OMIT_NONE)
    spp: int | None = field(default=None, metadata=OMIT_NONE)
    seed: int | None = field(default=None, metadata=OMIT_NONE)
    block: int | None = field(default=None, metadata=OMIT_NONE)
    radius: float | None = field(default=None, metadata=OMIT_NONE)
    max_angle_nv_deg: float | None = field(default=None, metadata=OMIT_NONE)
    blocks: int | None = field(default=None, metadata=OMIT_NONE)
    supersample: int | None = field(default=None, metadata=OMIT_NONE)
    texels_per_pixel: int | None = field(default=None, metadata=OMIT_NONE)
    map_center: str | None = field(default=None, metadata=OMIT_NONE)
    seconds: float | None = field(default=None, metadata=OMIT_NONE)
    noise: float | None = field(default=None, metadata=OMIT_NONE)
    reference_error: float | None = field(default=None, metadata=OMIT_NONE)
    metric: str | None = field(default=None, metadata=OMIT_NONE)


@dataclass(kw_only=True)
class TradeoffPoint(Report):
    """One point (``relight.tradeoff`` module docstring): the method and its setting (``epsilon`` or
    ``truncation``), the orders it ran at (frequency: F_B, P_B, F_rho, F_L, F_proj and per-lobe ``components`` for
    SHRMs; angular: truncation, theta*, App. D's W and the share of pairs visited), predicted and measured error and
    seconds (per stage too), the errors against Mitsuba 3's and the reference's sphere images (None without a twin),
    and whether it is on its method's and on the overall Pareto front (set once every point is measured)."""

    method: str
    representation: str
    setting: dict[str, float]
    orders: dict[str, Any]
    predicted_error: float | None
    predicted_error_bound: float | None
    measured_error: float
    predicted_seconds: float
    measured_seconds: float
    predicted_stages: dict[str, float]
    measured_stages: dict[str, float]
    mitsuba_error: float | None = None
    image_error: float | None = None
    pareto: bool = False
    pareto_overall: bool = False


@dataclass(frozen=True, kw_only=True)
class TradeoffMeta(Report):
    """What a sweep ran on: the material, the representation, input and output grids, the view (None for a
    reflection map), the error metric, the reference, the cost model, the range of predicted over measured seconds
    over all points, and the Mitsuba 3 comparison."""

    relight_version: str
    brdf: Any  # the material's canonical spec (None for a lobe without one)
    representation: str
    input: SweepInput
    output: Grid
    view: tuple[float, float, float] | None
    metric: str
    reference: SweepReference
    calibration: SweepCalibration
    time_ratio_range: tuple[float, float] | None
    mitsuba: MitsubaComparison = field(default_factory=lambda: MitsubaComparison(computed=False,
                                                                                   reason=NOT_RECORDED))


__all__ = ["NOT_RECORDED", "Grid", "MitsubaComparison", "SweepCalibration", "SweepInput", "SweepReference",
           "TradeoffMeta", "TradeoffPoint"]
