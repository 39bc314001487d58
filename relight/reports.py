"""Typed reports of the core: orders and predicted errors (seed 000 §5.1, App. B) and the prefilter report.

Each report is a frozen, keyword-only dataclass whose field names are the keys of its JSON form, so the API's models
(``Orders``, ``PredictedError``) can wrap or derive from them. :meth:`Report.to_json` gives that JSON form: fields in
declaration order, nested reports converted, tuples as lists; a field declared with :data:`OMIT_NONE` metadata is
left out while it is None (a key present in only some reports, e.g. a plan's budget keys). The key sets are pinned by
``tests/relight/test_reports.py``: the CLI's ``--report`` JSON, the stored job results and the API are contracts.

Other reports: the scene plan (``relight.planning.report``), the job plan (``relight.planning.job``) and the
accuracy-time sweep's points (``relight.tradeoff.points``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

#: Field metadata: leave the key out of :meth:`Report.to_json` while the value is None.
OMIT_NONE: dict[str, Any] = {"omit_none": True}


def to_json(obj: Any) -> Any:
    """The JSON form of a report, a list or a mapping of them (module docstring); other values as they are."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out: dict[str, Any] = {}
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if v is None and f.metadata.get("omit_none"):
                continue
            out[f.name] = to_json(v)
        return out
    if isinstance(obj, dict):
        return {k: to_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_json(v) for v in obj]
    return obj


class Report:
    """Base of the typed reports: :meth:`to_json`."""

    def to_json(self) -> dict[str, Any]:
        """The report as plain JSON types (module docstring)."""
        out: dict[str, Any] = to_json(self)
        return out


@dataclass(frozen=True, kw_only=True)
class Orders(Report):
    """Orders of an expansion (seed 000 §5.1): the lighting's F_L for the tolerance (None: not reached within the
    orders examined, or no tolerance), the BRDF's F_rho, the output's ``F_B = min(F_L, F_rho)`` and its view order."""

    F_L: int | None = None
    F_rho: int | None = None
    F_B: int
    P_B: int = 0


@dataclass(frozen=True, kw_only=True)
class ViewBand(Report):
    """The predicted error for views with ``ndotv[0] <= N.V <= ndotv[1]`` (``relight.shrm.view_bands``): ``rms``
    the prediction (``rms_average``, the average over orientations of the lighting, times a margin for single
    views), ``rms_appendix_b`` App. B's bound on that average, ``epsilon*`` the energies behind them and
    ``epsilon_brdf`` the lobe's own uncaptured energy there. ``enforced``: the band lies above the grazing limit,
    so the order search held ``epsilon_brdf`` to the tolerance there; ``met``: whether it did (both absent without
    a tolerance)."""

    ndotv: tuple[float, float]
    rms: float
    rms_appendix_b: float
    rms_average: float
    epsilon: float
    epsilon_appendix_b: float
    epsilon_brdf: float
    enforced: bool | None = field(default=None, metadata=OMIT_NONE)
    met: bool | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class PredictedError(Report):
    """Predicted uncaptured energy fractions of the output and the relative RMS errors they mean
    (``rms = sqrt(epsilon)``, ``relight.orders.rms_from_energy``): minimum of orders (§5.1) and App. B's bound;
    ``by_view`` the same per view band (:class:`ViewBand`; N.V in [0, 0.3], [0.3, 0.7], [0.7, 1]) and
    ``grazing_limit`` the smallest N.V the tolerance was held to (issue 18)."""

    epsilon_lighting: float | None = None
    epsilon_brdf: float | None = None
    epsilon_min_of_errors: float | None = None
    rms_min_of_errors: float | None = None
    epsilon_appendix_b: float | None = None
    rms_appendix_b: float | None = None
    by_view: list[ViewBand] | None = field(default=None, metadata=OMIT_NONE)
    grazing_limit: float | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True, kw_only=True)
class OrderReport(PredictedError, Orders):
    """Orders and predicted errors together: the ``orders`` of a prefilter report (the fields of :class:`Orders`,
    then those of :class:`PredictedError`)."""

    def orders(self) -> Orders:
        return Orders(F_L=self.F_L, F_rho=self.F_rho, F_B=self.F_B, P_B=self.P_B)

    def predicted(self) -> PredictedError:
        return PredictedError(**{f.name: getattr(self, f.name) for f in dataclasses.fields(PredictedError)})


@dataclass(frozen=True, kw_only=True)
class Ringing(Report):
    """The ringing of a band-limited radial lobe: the most negative value of its kernel ``u_F``, the lower bound it
    puts on every output texel, per colour, and the output's smallest texel per colour (``relight.prefilter``)."""

    kernel_min: float
    lower_bound_rgb: list[float]
    min_output_rgb: list[float]


@dataclass(frozen=True, kw_only=True)
class LatlongOutput(Report):
    """An ``S x 2S`` lat-long output, and the cube map's face size when one was made."""

    height: int
    width: int
    layout: str = "latlong"
    cube_size: int | None = None


@dataclass(frozen=True, kw_only=True)
class PrefilterReport(Report):
    """What ``relight.prefilter.prefilter_radial`` did: the lobe, the tolerance or order asked for, the orders and
    predicted errors (``orders``; ``predicted`` repeats the errors), the ringing bound, input and output shapes, seconds
    per stage. ``input`` holds the map's ``height`` and ``width``; callers add where it came from (the CLI: ``path``,
    ``negatives_clamped``, ``min_negative``)."""

    representation: str = "reflection_map"
    center: str
    brdf: dict[str, Any]
    epsilon: float | None
    order_requested: int | None
    window: str
    orders: OrderReport
    predicted: PredictedError
    ringing: Ringing
    input: dict[str, Any] = field(default_factory=dict)
    output: LatlongOutput
    timings: dict[str, float]
    total_seconds: float
    backend: str
    relight_version: str
