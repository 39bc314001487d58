"""Typed reports of the core: orders and predicted errors (seed 000 §5.1, App. B) and the prefilter report.

Each report is a frozen, keyword-only dataclass whose field names are the keys of its JSON form, so the API's models
(``Orders``, ``PredictedError``) can wrap or derive from them. :meth:`Report.to_json` gives that JSON form: fields in
declaration order, nested reports converted, tuples as lists; a field declared with :data:`OMIT_NONE` metadata is
left out while it is None (a key present in only some reports, e.g. a plan's budget keys). The key sets are pinned by
``tests/relight/test_reports.py``: the CLI's ``--report`` JSON, the stored job results and the API are contracts.

The SHRM report (:class:`ShrmReport`, :class:`ShrmComponentReport`, :class:`ShrmPredicted`) also reads as its JSON
form (:class:`JsonView`) and is rebuilt from it when an SHRM is read from a file (``from_json``).

Other reports: the scene plan (``relight.planning.report``), the job plan (``relight.planning.job``) and the
accuracy-time sweep's points (``relight.tradeoff.points``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
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
    a tolerance); ``achievable_epsilon_brdf``: the smallest ``epsilon_brdf`` the band can reach within the caps
    (F <= 1024, P <= 16, 4 GiB), when the order search ran."""

    ndotv: tuple[float, float]
    rms: float
    rms_appendix_b: float
    rms_average: float
    epsilon: float
    epsilon_appendix_b: float
    epsilon_brdf: float
    enforced: bool | None = field(default=None, metadata=OMIT_NONE)
    met: bool | None = field(default=None, metadata=OMIT_NONE)
    achievable_epsilon_brdf: float | None = field(default=None, metadata=OMIT_NONE)


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


class JsonView(Report, Mapping[str, Any]):
    """A report that also reads as its JSON form (``report["key"]``, ``.get``, ``**report``): the SHRM reports were
    plain dicts, and their readers (the CLI, the worker, the cost model, the tradeoff sweep) keep working while they
    move to the typed fields. Read-only: each access converts the report anew."""

    def __getitem__(self, key: str) -> Any:
        return self.to_json()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_json())

    def __len__(self) -> int:
        return len(self.to_json())


def typed_or_plain(cls: type[Any], data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``cls.from_json(data)`` when ``data`` holds every key of ``cls``'s JSON form that has no default (a report
    ``create_shrm`` wrote), else ``data`` as a plain dict (hand-made or older manifests stay as they were, so a file
    read and written again is the same file)."""
    need = {f.name for f in dataclasses.fields(cls)
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    if need <= set(data):
        out: Mapping[str, Any] = cls.from_json(data)
        return out
    return dict(data)


def _known(cls: type, data: Mapping[str, Any]) -> dict[str, Any]:
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in data.items() if k in names}


def _bands(data: Any) -> list[ViewBand] | None:
    if data is None:
        return None
    return [ViewBand(**{**_known(ViewBand, b), "ndotv": tuple(b["ndotv"])}) for b in data]


@dataclass(frozen=True, kw_only=True)
class ShrmPredicted(PredictedError):
    """The predicted errors of an SHRM component (``relight.shrm.creation.predicted_errors``) and per view band
    (``relight.shrm.view_bands``): ``rms_brdf`` is the lobe's own relative RMS at the orders, ``by_view_fine`` the
    0.1-wide bands beside the report bands of ``by_view``."""

    rms_brdf: float | None = None
    by_view_fine: list[ViewBand] | None = field(default=None, metadata=OMIT_NONE)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ShrmPredicted:
        """From the JSON form (a stored manifest; bands absent in files written before issue 18)."""
        d = _known(cls, data)
        d["by_view"], d["by_view_fine"] = _bands(data.get("by_view")), _bands(data.get("by_view_fine"))
        return cls(**d)


@dataclass(frozen=True, kw_only=True)
class ShrmComponentReport(JsonView):
    """One lobe of an SHRM: its centre, structure and why, the lobe, the orders (``F_B``, ``P_B``, ``F_L`` and what
    the order search said: ``F_rho``, ``P_rho``, ``tolerance_met``, ``unmet_bands``, ``achievable_by_view``, ... or
    ``explicit``), the search's probes, the maps, the predicted errors and the lobe's energy."""

    center: str
    structure: str
    reason: str
    lobe: dict[str, Any]
    orders: dict[str, Any]
    probes: list[Any] = field(default_factory=list)
    n_maps: int
    predicted: ShrmPredicted
    brdf_energy: float

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ShrmComponentReport:
        d = _known(cls, data)
        d.setdefault("center", "R")
        d.setdefault("structure", "general")
        d.setdefault("reason", "")
        d.setdefault("lobe", {})
        d.setdefault("orders", {})
        d.setdefault("n_maps", 0)
        d.setdefault("brdf_energy", 0.0)
        d["predicted"] = ShrmPredicted.from_json(data.get("predicted") or {})
        return cls(**d)


@dataclass(frozen=True, kw_only=True)
class ShrmReport(JsonView):
    """What ``relight.shrm.create_shrm`` did: the material, the tolerance (or orders) asked for and the grazing limit
    it held to, one :class:`ShrmComponentReport` per lobe, ``predicted`` (the component whose lobe misses the most
    energy: its relative errors bound the material's, whose other lobes only add signal), input and output shapes,
    seconds per stage. ``input`` holds the map's ``height`` and ``width``; callers add where it came from."""

    representation: str = "shrm"
    layout: str = "local"
    brdf: dict[str, Any] | None
    epsilon: float | None
    order_requested: list[int | None] | None
    grazing_limit: float | None = field(default=None, metadata=OMIT_NONE)
    components: list[ShrmComponentReport]
    predicted: ShrmPredicted
    input: dict[str, Any] = field(default_factory=dict)
    output: dict[str, Any] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    total_seconds: float = 0.0
    backend: str = "ducc0"
    relight_version: str = ""

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ShrmReport:
        """From the JSON form (``relight.shrm_io.read_shrm``'s manifest); missing keys get their defaults."""
        d = _known(cls, data)
        d.setdefault("brdf", None)
        d.setdefault("epsilon", None)
        d.setdefault("order_requested", None)
        d["components"] = [c if isinstance(c, ShrmComponentReport) else ShrmComponentReport.from_json(c)
                           for c in data.get("components") or []]
        d["predicted"] = ShrmPredicted.from_json(data.get("predicted") or {})
        return cls(**d)
