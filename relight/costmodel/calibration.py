"""Calibration of the cost model: constants fitted by non-negative least squares on relative error to a few timed
runs on this machine (seed 000 Table 3's asymptotic costs, one linear model per stage; :mod:`relight.costmodel`)."""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import relight
from relight import sh
from relight.costmodel.angular import angular_features, angular_view_counts
from relight.costmodel.features import FEATURES, STAGES, prefilter_report_features, shrm_report_features
from relight.costmodel.timing import _eval_cache_put, integrand_eval_seconds, lobe_eval_seconds
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: Constants calibrated on the 2-core development machine (``relight costmodel --recalibrate`` prints this machine's).
#: Used only when no calibration is wanted (``load_calibration(run=False)`` without a cached file).
DEFAULT_CONSTANTS: dict[str, float] = {
    "lobe_call": 6.6e-04,
    "lobe1d": 6.9e-09,
    "brdf_evals": 0.86,
    "brdf_ops": 7.2e-09,
    "proj_call": 6.5e-05,
    "proj_px": 5.6e-10,
    "proj_leg": 1.6e-10,
    "comp_call": 0.0,
    "syn_call": 2.3e-05,
    "syn_px": 6.8e-10,
    "syn_leg": 2.1e-10,
    "synq_px": 2.3e-09,
    "synq_leg": 5.6e-10,
    "ring_call": 1.9e-04,
    "ring": 9.7e-09,
    "call": 8.5e-07,
    "conv": 4.5e-10,
    "view_base": 0.0,
    "view_px": 4.7e-08,
    "eq8_px": 2.4e-08,
    "lookup_px": 1.2e-07,
    "ang_pairs": 8.0e-09,
    "angv_pairs": 1.7e-08,
    "angv_evals": 0.55,
}


# ------------------------------------------------------------------------------------------------ calibration
@dataclass(frozen=True)
class Prediction:
    """Predicted seconds, per stage and in total, with the features they came from."""

    seconds: float
    stages: dict[str, float]
    features: dict[str, float]

    def as_dict(self) -> dict[str, Any]:
        return {"seconds": self.seconds, "stages": dict(self.stages)}


@dataclass
class Calibration:
    """Fitted constants (seconds per feature unit) and the runs they came from."""

    constants: dict[str, float]
    key: str
    machine: dict[str, Any]
    relight_version: str
    created: str
    calibration_seconds: float
    samples: list[dict[str, Any]] = field(default_factory=list)
    calibrated: bool = True

    def predict(self, features: Mapping[str, float]) -> Prediction:
        """Seconds per stage ``sum_k c_k phi_k`` and in total; unknown feature names are an error."""
        unknown = set(features) - set(FEATURES)
        if unknown:
            raise ValueError(f"unknown cost-model features {sorted(unknown)}; known: {list(FEATURES)}")
        stages: dict[str, float] = {}
        for stage, feats in STAGES.items():
            t = sum(self.constants.get(f, 0.0) * float(features.get(f, 0.0)) for f in feats)
            if any(f in features for f in feats):
                stages[stage] = t
        return Prediction(seconds=float(sum(stages.values())), stages=stages, features=dict(features))

    def ratio_range(self) -> tuple[float, float]:
        """Smallest and largest predicted / measured total time over the calibration runs (in-sample)."""
        r = [s["predicted"] / s["measured"] for s in self.samples if s.get("measured", 0) > 0]
        return (min(r), max(r)) if r else (math.nan, math.nan)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Calibration:
        try:
            consts = {str(k): float(v) for k, v in dict(d["constants"]).items()}
            cal = cls(
                constants=consts, key=str(d["key"]), machine=dict(d["machine"]),
                relight_version=str(d["relight_version"]), created=str(d["created"]),
                calibration_seconds=float(d["calibration_seconds"]), samples=list(d.get("samples", [])),
                calibrated=bool(d.get("calibrated", True)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a cost-model calibration: {exc}") from None
        if set(consts) != set(FEATURES) or not all(math.isfinite(v) and v >= 0.0 for v in consts.values()):
            raise InputError("cost-model calibration has missing, extra or invalid constants")
        return cal


def machine_info() -> dict[str, Any]:
    """What identifies this machine's speed: host, CPU model and count, Python, NumPy, ducc0, relight threads."""
    import ducc0

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "node": platform.node(),
        "machine": platform.machine(),
        "cpu": cpu or platform.processor(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "ducc0": getattr(ducc0, "__version__", "?"),
        "threads": sh.NTHREADS,
    }


def calibration_key(machine: Mapping[str, Any] | None = None, version: str | None = None) -> str:
    """SHA-256 of the machine description and the relight version (default: the running one): the cache key."""
    payload = json.dumps({"machine": dict(machine or machine_info()),
                          "relight": relight.__version__ if version is None else version}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()


def fit(rows: Sequence[tuple[Mapping[str, float], float]], features: Sequence[str]) -> dict[str, float]:
    """Non-negative least squares on relative error: minimise ``sum_i (sum_k c_k phi_ik / t_i - 1)^2``, c >= 0.

    ``rows`` are (features, measured seconds). Features that no row exercises get 0.
    """
    from scipy.optimize import nnls

    used = [f for f in features if any(r[0].get(f, 0.0) > 0.0 for r in rows)]
    if not used or not rows:
        return {f: 0.0 for f in features}
    a = np.array([[r[0].get(f, 0.0) / r[1] for f in used] for r in rows if r[1] > 0.0])
    if a.size == 0:
        return {f: 0.0 for f in features}
    scale = np.abs(a).max(axis=0)
    scale[scale == 0.0] = 1.0
    sol, _ = nnls(a / scale, np.ones(a.shape[0]))
    out = {f: 0.0 for f in features}
    for f, c, s in zip(used, sol, scale, strict=True):
        out[f] = float(c / s)
    return out


def _best(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    best, out = math.inf, None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _stage_min(reports: list[dict[str, float]]) -> dict[str, float]:
    keys = set().union(*reports) if reports else set()
    return {k: min(r.get(k, math.inf) for r in reports) for k in keys}


def report_stages(timings: Mapping[str, float]) -> dict[str, float]:
    """Map a prefilter report's ``timings`` onto the model's stages (order selection + convolution = other)."""
    out: dict[str, float] = {}
    for k, v in timings.items():
        stage = k if k in STAGES else "other"
        out[stage] = out.get(stage, 0.0) + float(v)
    return out


#: Timed runs of :func:`calibrate` on random maps. Radial prefilters: (H, Phong s, order F or None, epsilon, S);
#: SHRMs: (H, material, F or None, P or None, epsilon, S) with "m" the microfacet lobe sigma = 0.3 and "lm" a
#: Lambert + microfacet sum; angular: (H, S, Phong s) at truncation 0.01; view reference: (H, S, truncation).
CAL_RADIAL: list[tuple[int, float, int | None, float | None, int]] = [
    (32, 32.0, 8, None, 32), (64, 32.0, 30, None, 64), (128, 16.0, None, 1e-3, 96), (256, 32.0, 20, None, 128),
    (256, 1000.0, None, 1e-3, 48), (128, 64.0, 120, None, 64), (512, 200.0, None, 1e-2, 64),
]
CAL_SHRM: list[tuple[int, str, int | None, int | None, float | None, int]] = [
    (32, "m", 8, 2, None, 32), (64, "m", None, None, 0.03, 48), (64, "m", 10, 5, None, 32),
    (64, "lm", None, None, 0.01, 32), (32, "lm", 6, 2, None, 48), (128, "m", 30, 2, None, 64),
]
CAL_ANGULAR = [(32, 16, 8.0), (64, 16, 64.0), (64, 32, 1000.0)]
CAL_VIEW = [(16, 8, 0.01), (24, 16, 0.3), (32, 12, 1e-3), (32, 16, 0.05)]


def calibrate(*, repeat: int = 3, quick: bool = False, seed: int = 0) -> Calibration:
    """Time a few prefilters, SHRMs and angular runs on random maps and fit every constant (a few seconds).

    ``quick`` drops the largest runs (for tests). Stage timings are the best of ``repeat`` runs.
    """
    from relight.brdf import lobe_cache
    from relight.brdf.models import Microfacet, SumBRDF
    from relight.brdf.radial import Lambert, Phong
    from relight.prefilter import prefilter_radial
    from relight.reference import reference_radial, truncation_angle
    from relight.reference_view import reference_view
    from relight.shrm import create_shrm, reflect

    t_start = time.perf_counter()
    rng = np.random.default_rng(seed)
    rows: dict[str, list[tuple[dict[str, float], float]]] = {s: [] for s in STAGES}
    totals: list[tuple[str, dict[str, float], float]] = []

    def env(h: int) -> FloatArray:
        return np.asarray(rng.random((h, 2 * h, 3)), dtype=np.float64)

    def record(kind: str, feats: dict[str, float], stages: dict[str, float]) -> None:
        for stage, t in stages.items():
            if stage in rows and t > 0.0:
                rows[stage].append(({f: feats.get(f, 0.0) for f in STAGES[stage]}, t))
        totals.append((kind, feats, float(sum(stages.values()))))

    for h, expo, f, eps, s in CAL_RADIAL[:4] if quick else CAL_RADIAL:
        px, lobe = env(h), Phong(expo)
        runs = [prefilter_radial(px, lobe, order=f, epsilon=eps, size=s) for _ in range(repeat)]
        feats = prefilter_report_features(lobe, runs[0].report, height=h, width=2 * h)
        record("prefilter_radial", feats, _stage_min([report_stages(r.report.timings) for r in runs]))

    micro = Microfacet(0.3)
    per_eval = lobe_eval_seconds(micro)
    per_integrand = integrand_eval_seconds(micro)
    materials: dict[str, Any] = {"m": micro, "lm": SumBRDF([Lambert(0.5), micro])}
    view = np.array([0.3, 0.5, 0.8])
    for h, mat, f, p, eps, s in CAL_SHRM[:4] if quick else CAL_SHRM:
        px, brdf = env(h), materials[mat]
        reps = []
        shrm_obj = None
        for _ in range(repeat):
            lobe_cache.clear()
            shrm_obj = create_shrm(px, brdf, order=f, p_order=p, epsilon=eps, size=s)
            stages = report_stages(shrm_obj.typed_report.timings)
            stages["view"], _ = _best(functools.partial(reflect, shrm_obj, view), 1)  # fresh: eq. 8 included
            reps.append(stages)
        assert shrm_obj is not None
        stages = _stage_min(reps)
        _eval_cache_put(micro, per_eval)
        feats = shrm_report_features(brdf, shrm_obj.typed_report, height=h, width=2 * h, views=1)
        record("create_shrm+view", feats, stages)

    for h, s, expo in CAL_ANGULAR[:2] if quick else CAL_ANGULAR:
        px, lobe = env(h), Phong(expo)
        t, _ = _best(functools.partial(reference_radial, px, lobe, s, epsilon=0.01), repeat)
        record("reference_radial", angular_features(h, s, truncation_angle(lobe, 0.01)), {"angular": t})

    for h, s, tr in CAL_VIEW[:2] if quick else CAL_VIEW:
        px = env(h)
        reference_view(px, micro, view, s, truncation=tr)  # fills the truncation-table cache (not timed)
        t, _ = _best(functools.partial(reference_view, px, micro, view, s, truncation=tr), max(1, repeat - 1))
        pairs, evals, _ = angular_view_counts(micro, view, h, s, tr)
        record("reference_view", {"angv_pairs": float(pairs), "angv_evals": evals[0] * per_integrand},
               {"angular_view": t})

    constants: dict[str, float] = {}
    for stage, names in STAGES.items():
        fitted = fit(rows[stage], names)
        for name in names:
            # a stage no run exercised keeps the development machine's constant
            constants[name] = fitted[name] if rows[stage] else DEFAULT_CONSTANTS[name]
    machine = machine_info()
    cal = Calibration(
        constants=constants, key=calibration_key(machine), machine=machine, relight_version=relight.__version__,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        calibration_seconds=time.perf_counter() - t_start,
    )
    for kind, used, measured in totals:
        cal.samples.append({"kind": kind, "measured": measured, "predicted": cal.predict(used).seconds})
    return cal


def default_calibration() -> Calibration:
    """The development machine's constants, flagged ``calibrated = False``."""
    machine = machine_info()
    return Calibration(
        constants=dict(DEFAULT_CONSTANTS), key=calibration_key(machine), machine=machine,
        relight_version=relight.__version__, created="", calibration_seconds=0.0, calibrated=False,
    )

