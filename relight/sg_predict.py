"""Predicted error and cost of seed 002's representation (Green, Kautz & Durand 2007) before anything is computed:
what a planner weighs against an SHRM (seed 000) for one object.

* :func:`predict_fit_error` -- the relative L2 error of K Gaussian lobes per view elevation, from a *coarse fit*
  (the real fitter, ``relight.sgfit``, on a quarter of its quadrature nodes, 6 elevations, fewer iterations and no
  bisection), and the error an orthographic sphere image would show:
  per-elevation errors weighted by the fraction of the sphere's projected disc at that elevation,
  ``cos(theta) sin(theta) d theta`` (pixels near the silhouette are grazing), up to the fit's theta_max.
* :func:`chain_cost` -- the Gaussian chain of one map (shared by every material under it): levels, their orders
  (the vMF's order for the tolerance, seed 000 §5.1, capped at H - 1: an upper bound, the lighting may need less)
  and rows, float16 bytes, and predicted seconds from the cost model's projection and synthesis terms
  (``relight.costmodel``, seed 000 Table 3).
* :func:`object_cost` -- per object and frame: the material's bytes (two K x N RGBA16F textures: the paper's "~1 KB"),
  texture fetches per pixel (two chain levels blended per lobe, plus the K x 2 lobe texels), visibility floats per
  vertex ((F + 1)^2, 16 for the paper's order 3).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from relight import validate
from relight.brdf.vmf import VonMisesFisher
from relight.errors import InputError
from relight.sgfit import DEFAULT_EXTRA_LOBES, DEFAULT_LOBES, DEFAULT_THETA_MAX, FitSettings

#: The coarse fit: elevations, quadrature nodes (n_gamma x n_psi; the full fit uses 160 x 24) and iterations.
COARSE_ELEVATIONS, COARSE_GAMMA, COARSE_PSI, COARSE_NFEV = 6, 80, 12, 80


@dataclass(frozen=True)
class FitPrediction:
    """Predicted per-elevation errors (relative L2 of the cosine-weighted slice), the sphere-image error and the
    measured seconds of the coarse fit (the full fit, K = 3, N = 15: 2-17 s of CPU, ``bench/fit.py``)."""

    theta_o: list[float]
    errors: list[float]
    sphere_error: float
    coarse_seconds: float

    def as_dict(self) -> dict[str, Any]:
        return {"theta_o": self.theta_o, "errors": self.errors, "sphere_error": self.sphere_error,
                "coarse_seconds": self.coarse_seconds}


def sphere_error(theta_o: np.ndarray, errors: np.ndarray) -> float:
    """RMS of per-elevation errors over an orthographic sphere image: weight ``cos(t) sin(t)`` (the projected disc's
    area per elevation), trapezoid rule over the given elevations."""
    t = np.asarray(theta_o, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    w = np.cos(t) * np.sin(t)
    num = np.trapezoid(w * e * e, t)
    den = np.trapezoid(w, t)
    return float(math.sqrt(num / den)) if den > 0 else float(e[0])


def predict_fit_error(brdf: Any, lobes: int = DEFAULT_LOBES, *, max_lobes: int | None = None,
                      theta_max: float = DEFAULT_THETA_MAX) -> FitPrediction:
    """The coarse fit of the module docstring (K = ``lobes``, up to ``max_lobes``, default K + 2 as ``relight
    fit``)."""
    from relight.sgfit import fit_gaussian_lobes

    ml = min(lobes + DEFAULT_EXTRA_LOBES, 8) if max_lobes is None else max_lobes
    st = FitSettings(lobes=lobes, max_lobes=ml, elevations=COARSE_ELEVATIONS, theta_max=theta_max,
                     n_gamma=COARSE_GAMMA, n_psi=COARSE_PSI, max_nfev=COARSE_NFEV, max_inserted=0)
    st.check()
    t0 = time.perf_counter()
    m = fit_gaussian_lobes(brdf, st)
    secs = time.perf_counter() - t0
    assert m.errors is not None
    return FitPrediction(theta_o=[float(x) for x in m.elevations], errors=[float(x) for x in m.errors],
                         sphere_error=sphere_error(m.elevations, m.errors), coarse_seconds=secs)


def chain_cost(height: int, width: int, *, epsilon: float = 1e-3, ratio: float = 2.0, sigma0: float | None = None,
               calibration: Any = None) -> dict[str, Any]:
    """Levels, orders, rows, float16 bytes and predicted seconds of ``build_chain`` for an H x W map (module
    docstring). ``calibration``: a ``relight.costmodel.calibration.Calibration`` (default: the stored one)."""
    from relight.brdf.coefficients import spectrum_for_tolerance
    from relight.costmodel.calibration import default_calibration
    from relight.costmodel.features import add_features, projection_features, synthesis_features
    from relight.gaussian_chain import chain_sigmas, default_sigma0
    from relight.prefilter import MIN_SIZE, size_for_order

    if height < 2 or width != 2 * height:
        raise InputError(f"chain_cost: need an H x 2H lat-long map, got {height} x {width}")
    sig = chain_sigmas(default_sigma0(height) if sigma0 is None else sigma0, ratio)
    orders = [min(spectrum_for_tolerance(VonMisesFisher(float(s)), epsilon)[1], height - 1) for s in sig]
    rows = []
    for f in orders:
        s = max(min(size_for_order(f), height), min(MIN_SIZE, height))
        rows.append(s - (s % 2 if s > 2 else 0))
    feats = add_features(projection_features(height, width, max(orders)),
                         *(synthesis_features(s, f, 1, 0) for s, f in zip(rows, orders, strict=True)))
    cal = calibration or default_calibration()
    pred = cal.predict(feats)
    return {"levels": len(sig), "sigmas": [float(x) for x in sig], "orders": orders, "rows": rows,
            "bytes": int(sum(6 * 2 * s * s for s in rows)), "seconds": pred.seconds,
            "calibrated": bool(getattr(cal, "calibrated", True))}


def object_cost(lobes: int, elevations: int, *, visibility_order: int | None = None) -> dict[str, Any]:
    """Per object: material bytes, fetches per pixel and visibility floats per vertex (module docstring)."""
    validate.at_least("object_cost: lobes", lobes, 1)
    validate.at_least("object_cost: elevations", elevations, 1)
    vis = 0 if visibility_order is None else (visibility_order + 1) ** 2
    return {"material_bytes": 2 * 8 * lobes * elevations, "fetches_per_pixel": 2 * lobes + 2 * lobes,
            "chain_lookups_per_pixel": lobes, "visibility_floats_per_vertex": vis}
