"""Predicted errors of planner v2's representations, cheap enough for a plan (issue 16 item 4; design notes §5.4).

* **SH tables and PRT** (seed 003): the min-of-errors rule of seed 000 §5.1 generalised to the BRDF product function
  f* = f max(0, s_z). Per local view v, ``e_l(v)`` is f*'s energy in band l (``relight.sh_table.product_energy``, the
  table's own lobe quadrature, to band :data:`PRED_ORDER`, the rest of ``int f*^2`` lumped one band above); for a
  lighting of power ``P_L(l)`` per band in a random orientation the shaded value's mean square is
  ``sum_l e_l(v) P_L(l) / (2l + 1)``. An order-F table loses the bands above F, so the predicted relative RMS is

      sqrt( sum_v w_v sum_{l > F} e_l(v) P_L(l) / (2l+1)  /  sum_v w_v sum_l e_l(v) P_L(l) / (2l+1) )

  over views at elevations :data:`VIEW_THETAS` weighted by ``sin 2 theta`` (the share of a sphere's pixels seen
  orthographically at elevation theta) and, for anisotropic BRDFs, azimuths :data:`VIEW_PHIS`.
* **Gaussian lobes** (seed 002): a K = 3 fit (:data:`FIT_SETTINGS`; the plan's own fit, cached and reused by the run)
  gives the per-elevation relative L2 error; weighted by ``sin 2 theta`` over its elevations; plus the chain's
  tolerance (its levels' orders meet epsilon, seed 000 App. B) and the blend of two levels at mid-level
  (``relight.gaussian_chain.blend_kernel_error``), added in quadrature.
* **In-out PRT** (seed 004): K at the energy fraction ``1 - epsilon`` (``relight.factor_predict.terms_for_tolerance``),
  the uncaptured singular energy at most epsilon; plus the lighting's uncaptured energy above the transport's order n.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Largest SH-table order the viewer draws (81 coefficients; issue 15: 9 / 25 / 49 / 81 in the viewer, 225 offline).
F_MAX: Final = 8
#: Band energies of the product function are computed to this band (the table module's offline maximum).
PRED_ORDER: Final = 14
#: View elevations (radians) and their weights ``sin 2 theta`` (module docstring), and azimuths for anisotropy.
VIEW_THETAS: Final = (math.radians(15.0), math.radians(45.0), math.radians(75.0))
VIEW_PHIS: Final = (0.0, math.pi / 4, math.pi / 2)
#: The plan's Gaussian-lobe fit: K = 3 (the paper's), 8 elevations, a 80 x 12 slice grid (about 0.4 s per BRDF here;
#: the issue's K = 3, N = 15 default fit is ~10x costlier for < 0.5 % change of the mean error on TS alpha = 0.2).
FIT_LOBES: Final = 3
FIT_ELEVATIONS: Final = 8
FIT_GRID: Final = (80, 12)
FIT_MAX_NFEV: Final = 60
#: Chain level ratio the plan uses: sqrt(2) (a mid-level blend error of ~4 % against ~16 % for ratio 2).
CHAIN_RATIO: Final = math.sqrt(2.0)


def spec_key(spec: Any) -> str:
    return json.dumps(spec, sort_keys=True)


@lru_cache(maxsize=256)
def _product_bands(key: str, view: tuple[float, float, float]) -> tuple[tuple[float, ...], float]:
    from relight.brdf.spec import parse_frame_brdf
    from relight.sh_table import product_energy

    f = parse_frame_brdf(json.loads(key))
    bands, total = product_energy(f, np.array(view), PRED_ORDER, refine=1)
    return tuple(float(x) for x in np.asarray(bands).mean(axis=-1)), float(np.mean(total))


def views(isotropic: bool) -> list[tuple[tuple[float, float, float], float]]:
    """(local view, weight) pairs of the prediction (module docstring)."""
    out = []
    for th in VIEW_THETAS:
        phis = (0.0,) if isotropic else VIEW_PHIS
        for ph in phis:
            v = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
            out.append((v, math.sin(2.0 * th) / len(phis)))
    return out


def lighting_weights(band_energy: NDArray[np.floating]) -> FloatArray:
    """``P_L(l) / (2l + 1)`` for l = 0 .. PRED_ORDER + 1 (bands beyond the projection repeat its last band)."""
    p = np.asarray(band_energy, dtype=np.float64)
    l = np.arange(PRED_ORDER + 2)
    idx = np.minimum(l, p.size - 1)
    return np.asarray(p[idx] / (2 * idx + 1), dtype=np.float64)


def table_band_loss(spec: Any, isotropic: bool, band_energy: NDArray[np.floating]) -> FloatArray:
    """Predicted relative RMS of an order-F table for F = 0 .. PRED_ORDER (module docstring), one call per
    material and environment (the band energies per view are cached by spec)."""
    key = spec_key(spec)
    w_l = lighting_weights(band_energy)
    num = np.zeros(PRED_ORDER + 2)
    den = 0.0
    for v, wv in views(isotropic):
        bands, total = _product_bands(key, v)
        e = np.zeros(PRED_ORDER + 2)
        e[: PRED_ORDER + 1] = bands
        e[PRED_ORDER + 1] = max(total - sum(bands), 0.0)
        contrib = e * w_l * wv
        num += contrib
        den += float(contrib.sum())
    if den <= 0.0:
        return np.zeros(PRED_ORDER + 1)
    above = den - np.cumsum(num)  # energy in bands > F, F = 0 .. PRED_ORDER + 1
    return np.sqrt(np.clip(above[: PRED_ORDER + 1] / den, 0.0, 1.0))


def table_order(loss: FloatArray, epsilon: float, f_cap: int = F_MAX) -> tuple[int, float]:
    """Smallest order F <= f_cap whose predicted relative RMS meets sqrt(epsilon), else f_cap; with its error."""
    target = math.sqrt(epsilon)
    for f in range(2, f_cap + 1):
        if loss[f] <= target:
            return f, float(loss[f])
    return f_cap, float(loss[f_cap])


# ------------------------------------------------------------------------------------------------ seed 002
@lru_cache(maxsize=128)
def _fit(key: str) -> Any:
    from relight.brdf.spec import parse_brdf
    from relight.sgfit import FitSettings, fit_gaussian_lobes

    settings = FitSettings(lobes=FIT_LOBES, elevations=FIT_ELEVATIONS, n_gamma=FIT_GRID[0], n_psi=FIT_GRID[1],
                           max_nfev=FIT_MAX_NFEV)
    return fit_gaussian_lobes(parse_brdf(json.loads(key)), settings)


def gaussian_fit(spec: Any) -> Any:
    """The plan's fit of one isotropic lobe (``relight.brdf.gaussian_lobes.GaussianLobes``), cached by spec."""
    return _fit(spec_key(spec))


def gaussian_error(spec: Any, epsilon: float) -> dict[str, float]:
    """Predicted relative RMS of a Gaussian-lobe render (module docstring) and its parts."""
    from relight.gaussian_chain import blend_kernel_error

    fit = gaussian_fit(spec)
    th = np.asarray(fit.elevations)
    err = np.asarray(fit.errors)
    w = np.sin(2.0 * th)
    w[-1] = max(w[-1], 0.0)
    fit_rms = float(math.sqrt(float(np.sum(w * err**2) / np.sum(w)))) if np.sum(w) > 0 else float(err.mean())
    blend = float(blend_kernel_error(CHAIN_RATIO, 0.5))
    total = math.sqrt(fit_rms**2 + blend**2 + epsilon)
    return {"rms": total, "fit": fit_rms, "fit_max": float(err.max()), "chain_blend": blend,
            "chain": math.sqrt(epsilon)}


@lru_cache(maxsize=64)
def chain_levels(height: int, epsilon: float, f_l: int | None) -> tuple[list[int], list[int], list[float]]:
    """Orders, rows and sigmas of the chain ``relight.gaussian_chain.build_chain`` builds at this tolerance
    (the orders capped by the lighting's F_L and the map's H - 1, as there), without building it."""
    from relight.brdf.coefficients import spectrum_for_tolerance
    from relight.brdf.vmf import VonMisesFisher
    from relight.gaussian_chain import chain_sigmas, default_sigma0
    from relight.prefilter import MIN_SIZE, size_for_order

    sig = chain_sigmas(default_sigma0(height), CHAIN_RATIO)
    orders, rows = [], []
    for s in sig:
        _, f = spectrum_for_tolerance(VonMisesFisher(float(s)), epsilon)
        f = min(f, height - 1, f if f_l is None else f_l)
        orders.append(int(f))
        rows.append(int(max(min(size_for_order(f), height), min(MIN_SIZE, height))))
    return orders, rows, [float(x) for x in sig]


# ------------------------------------------------------------------------------------------------ seed 004
@lru_cache(maxsize=256)
def _terms(key: str, epsilon: float) -> tuple[int, str]:
    from relight.brdf.spec import parse_brdf
    from relight.factor_predict import terms_for_tolerance

    out = terms_for_tolerance(parse_brdf(json.loads(key)), epsilon)
    return int(out["terms"]), str(out["method"])


def inout_terms(spec: Any, epsilon: float) -> tuple[int, str]:
    """K capturing ``1 - epsilon`` of the BRDF's in-out energy over the visible hemisphere, and the method
    (``relight.factor_predict.terms_for_tolerance``: the radial spectrum, else a cached coarse block SVD)."""
    return _terms(spec_key(spec), float(epsilon))
