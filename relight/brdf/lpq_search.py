"""App. C's order search over the BRDF coefficients ``rho_hat_lpq`` (seed 000 App. C, step 1, second paragraph):
the smallest (F, P) whose uncaptured energy meets a tolerance, for the whole lobe.

Order selection from a tolerance (App. C, step 1, second paragraph): compute the coefficients at generous
starting orders (F0, P0); if the uncaptured energy ``epsilon(F0, P0)`` meets the tolerance, reduce P as far as the
tolerance still holds at F0, then reduce F at that P; if not, grow (F0, P0) and repeat. ``epsilon(F, P) =
1 - sum_{l<=F, p<=P} E_lp / E_tot`` with ``E_tot = int int rho_hat^2`` integrated directly on the grid (not the sum
of the computed coefficients), maximum over colour channels.

``relight.shrm.create_shrm`` holds the tolerance per view band instead (``relight.shrm.order_search``, issue 18);
this whole-lobe search is the scene planner's (``relight.planning.lobes``) and the cost model's estimate of probes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from cachetools import LRUCache

from relight import validate
from relight.brdf.base import Lobe
from relight.brdf.lobe_cache import lobe_cache, lobe_cache_key
from relight.brdf.lpq import BRDFCoefficients, as_channels, brdf_coefficients


def lobe_width(lobe: Lobe) -> float:
    """Angle from the centre where the lobe's phi-averaged magnitude at theta_o = 0 first drops below 1e-2 of peak.

    Only used to pick the starting order F0 of :func:`select_orders`.
    """
    theta = np.concatenate([np.geomspace(1e-4, 0.05, 60), np.linspace(0.05, np.pi, 300)])
    phi = (np.arange(8) + 0.5) * np.pi / 8
    vals = as_channels(lobe.rho_hat(theta[:, None], np.zeros((1, 1)), phi[None, :]), (theta.size, phi.size))
    mag = np.abs(vals).mean(axis=1).max(axis=-1)
    peak = float(mag.max())
    if not np.isfinite(peak) or peak <= 0.0:
        return float(np.pi)
    above = np.nonzero(mag >= 1e-2 * peak)[0]
    return float(theta[above[-1]]) if above.size else float(np.pi)


@dataclass(frozen=True)
class OrderSelection:
    """Result of :func:`select_orders`: the chosen (F, P), the coefficients at the probe orders, the history."""

    F: int
    P: int
    epsilon_achieved: float
    met: bool
    coefficients: BRDFCoefficients  # at the last probe orders (>= F, P)
    history: list[dict[str, Any]]

    def as_dict(self) -> dict[str, Any]:
        return {
            "F_rho": self.F,
            "P_rho": self.P,
            "epsilon_brdf": self.epsilon_achieved,
            "tolerance_met": self.met,
            "probes": self.history,
        }


def starting_orders(lobe: Lobe) -> tuple[int, int]:
    """(F0, P0) for :func:`select_orders`.

    ``F0 = clamp(12 / width, 8, 64)`` with the lobe width of :func:`lobe_width` (about 1.2 F for a Gaussian lobe,
    whose F ~ 1 / sigma, §7.1); ``P0`` = 0 for radially symmetric lobes, 8 for azimuthally symmetric ones (cheap:
    no phi samples; Kajiya–Kay needs P ~ 8, §7.1), 4 otherwise (§5.2: P <= 3 suffices for most BRDFs).
    """
    f0 = int(np.clip(math.ceil(12.0 / max(lobe_width(lobe), 1e-3)), 8, 64))
    p0 = 0 if lobe.radially_symmetric else (8 if lobe.azimuthally_symmetric else 4)
    return f0, p0


def select_orders(
    lobe: Lobe,
    epsilon: float,
    *,
    start: tuple[int, int] | None = None,
    f_cap: int = 1024,
    p_cap: int = 16,
    oversample: float = 1.0,
) -> OrderSelection:
    """Smallest (F, P) with ``epsilon(F, P) <= epsilon``, found as seed 000 App. C describes.

    Start at (F0, P0) (:func:`starting_orders`); while the tolerance fails at the probe orders, grow them: F0
    doubles when the top quarter of its bands (l > 3 F0 / 4) still holds more than a tenth of the allowed
    uncaptured energy (the spectrum in l has not decayed), P0 grows by 4 when the same holds for p > 3 P0 / 4, and
    both grow when neither test points at one of them (within ``f_cap``, ``p_cap``; radially symmetric lobes keep
    P = 0). Then shrink P as far as ``epsilon(F0, P) <= epsilon`` holds, and then F at that P. If the caps are
    reached first the caps are returned with ``met = False``.
    """
    validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    f0, p0 = start if start is not None else starting_orders(lobe)
    if lobe.radially_symmetric:
        p0 = 0
    f0, p0 = min(f0, f_cap), min(p0, p_cap)
    history: list[dict[str, Any]] = []
    while True:
        coeffs = brdf_coefficients(lobe, f0, p0, oversample=oversample)
        table = coeffs.epsilon_table()
        history.append({"F": f0, "P": p0, "epsilon": float(table[f0, p0]), "grid": list(coeffs.grid_shape)})
        if table[f0, p0] <= epsilon:
            break
        can_f, can_p = f0 < f_cap, p0 < p_cap and not lobe.radially_symmetric
        if not (can_f or can_p):
            return OrderSelection(f0, p0, float(table[f0, p0]), False, coeffs, history)
        e_lp = coeffs.band_energy().max(axis=2)
        threshold = 0.1 * epsilon * float(coeffs.total_energy.max())
        f_short = float(e_lp[(3 * f0) // 4 + 1 :, :].sum()) > threshold
        p_short = float(e_lp[:, (3 * p0) // 4 + 1 :].sum()) > threshold
        grow_f = can_f and (f_short or not p_short or not can_p)
        grow_p = can_p and (p_short or not f_short or not can_f)
        if grow_f:
            f0 = min(2 * f0, f_cap)
        if grow_p:
            p0 = min(p0 + 4, p_cap)
    p_sel = int(np.nonzero(table[f0, :] <= epsilon)[0][0])
    f_sel = int(np.nonzero(table[:, p_sel] <= epsilon)[0][0])
    return OrderSelection(f_sel, p_sel, float(table[f_sel, p_sel]), True, coeffs, history)


_select_cache: LRUCache[str, OrderSelection] = lobe_cache()


def cached_select_orders(lobe: Lobe, epsilon: float) -> tuple[OrderSelection, bool]:
    """:func:`select_orders` through the cache; returns (selection, whether it was a cache hit)."""
    key = lobe_cache_key(lobe, epsilon)
    if key is not None and key in _select_cache:
        return _select_cache[key], True
    sel = select_orders(lobe, epsilon)
    if key is not None:
        _select_cache[key] = sel
    return sel, False
