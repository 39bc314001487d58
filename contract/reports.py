"""The API's models of the core's typed reports (:mod:`relight.reports`): the same fields, checked when this
module loads, so each report schema exists once.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Self

from pydantic import Field

from relight import reports
from relight.contract.base import Public


class CoreReport(Public):
    """A model that wraps one of the core's typed reports (``relight.reports``) field for field: the same names
    (checked when this module loads, :func:`_same_fields`), built from the report's JSON form (:meth:`from_core`)."""

    core: ClassVar[type[Any]]

    @classmethod
    def from_core(cls, report: Any) -> Self:
        """The model of a core report instance (its ``to_json()``)."""
        if not isinstance(report, cls.core):
            raise TypeError(f"{cls.__name__} wraps {cls.core.__name__}, got {type(report).__name__}")
        return cls.model_validate(report.to_json())


class Orders(CoreReport):
    core: ClassVar[type[Any]] = reports.Orders

    F_L: int | None = None
    F_rho: int | None = None
    F_B: int
    P_B: int = 0


class ViewBand(CoreReport):
    """The predicted error for views with N.V in ``ndotv`` (``relight.reports.ViewBand``, issue 18)."""

    core: ClassVar[type[Any]] = reports.ViewBand

    ndotv: tuple[float, float]
    rms: float = Field(description="predicted relative RMS error in the band (average over orientations x margin)")
    rms_appendix_b: float = Field(description="App. B's bound on the band's average relative RMS error")
    rms_average: float = Field(description="the band's relative RMS error averaged over orientations of the light")
    epsilon: float
    epsilon_appendix_b: float
    epsilon_brdf: float = Field(description="the lobe's own uncaptured energy in the band")
    enforced: bool | None = Field(None, description="the band lies above the grazing limit: the tolerance holds")
    met: bool | None = Field(None, description="the orders meet the tolerance in the band")
    achievable_epsilon_brdf: float | None = Field(None, description="the smallest epsilon_brdf the band can reach "
                                                  "within the caps (F <= 1024, P <= 16)")


class PredictedError(CoreReport):
    core: ClassVar[type[Any]] = reports.PredictedError

    epsilon_lighting: float | None = None
    epsilon_brdf: float | None = None
    epsilon_min_of_errors: float | None = None
    rms_min_of_errors: float | None = Field(None, description="predicted relative RMS error (sqrt of epsilon)")
    epsilon_appendix_b: float | None = None
    rms_appendix_b: float | None = None
    by_view: list[ViewBand] | None = Field(None, description="the predicted error per view band (N.V in [0, 0.3], "
                                           "[0.3, 0.7], [0.7, 1])")
    grazing_limit: float | None = Field(None, description="the tolerance holds for views with N.V at least this")


def _same_fields(model: type[CoreReport]) -> None:
    core = {f.name for f in dataclasses.fields(model.core)}
    if set(model.model_fields) != core:
        raise TypeError(f"{model.__name__} must have the fields of {model.core.__qualname__}: {sorted(core)}")


for _m in (Orders, ViewBand, PredictedError):
    _same_fields(_m)
