"""Fitting Gaussian lobes to an isotropic BRDF (Green, Kautz & Durand 2007, §3.2, §4, eq. 8).

Per view elevation theta_o, minimise ``|| T_theta_o - sum_k w_k G_{sigma_k}(c_k(mu_k) . w) ||^2`` over the sphere
(solid-angle weighted, ``T = 0`` below the horizon; ``relight.sg_slice``), with lobes as in ``docs/conventions.md``.
Better than the paper's trust-region fit of all 5K parameters (~10 min per BRDF in MATLAB):

* **Variable projection** (Golub & Pereyra 1973): for fixed (mu, sigma) the weights solve a non-negative linear
  least-squares problem (``scipy.optimize.nnls``); the 2K nonlinear unknowns (mu_k, log sigma_k) go to
  ``scipy.optimize.least_squares`` (TRF, bounds) with Kaufman's (1975) analytic Jacobian
  ``J = -(I - Q Q^T) (dPhi/dp) w`` (Q: orthonormal basis of the active columns).
* **Shape on luminance, weights per channel** (coloured and measured BRDFs, design notes §2.4 item 6).
* **Continuation**: theta_o = 0 first (mu = 0 by symmetry, several widths), then each elevation warm-started from
  the previous one, plus restarts with dead lobes re-seeded at the residual's peak and a fresh start; the best wins.
* **Canonical order**: widest lobe first at theta_o = 0; afterwards each elevation's lobes are matched to the previous
  elevation's: for K <= 5, of the permutations whose interpolation with the previous elevation fits the
  mid-elevation slice within 5 % of the best, the one with the fewest fades (a live lobe keeps its slot), else
  ``scipy.optimize.linear_sum_assignment`` on the parameter distance; so interpolating between
  neighbouring elevations blends the same lobe. Near-duplicate lobes are merged; a lobe with no weight takes the
  (mu, sigma) of the same lobe at the nearest elevation where it lives (interpolation then only fades it).
* **More lobes only where needed** (``max_lobes`` > K): at elevations whose error exceeds ``refine_above`` a lobe is
  added at the residual's peak and kept if the error falls; other elevations carry it with weight 0.
* **Reports**: per-elevation relative L2 error, the error at each mid-elevation with *interpolated* parameters, the
  energy check ``sum_k w_k`` against the directional albedo ``int T dw``, the fitted mass leaking below the horizon.

One elevation's solve is ``relight.sg_varpro``, the lobe order across elevations ``relight.sg_order``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import Lobe
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.models import SumBRDF
from relight.conventions import LUMINANCE_WEIGHTS
from relight.errors import InputError
from relight.sg_order import (
    DEAD_FRACTION,
    MAX_PERMUTED_LOBES,
    best_permutation,
    match_lobes,
    merge_duplicates,
    pin_dead,
)
from relight.sg_slice import SliceGrid, slice_grid, transfer_slice
from relight.sg_varpro import SIGMA_LO, Solution, VarPro, basis, channel_weights, luminance, peak, relative_error, solve
from relight.sgfit_refine import MAX_INSERTED, Elevation, refine_elevations

FloatArray = NDArray[np.float64]

#: Defaults of the paper (§3.2, §5): K = 3 lobes, N = 15 elevations; theta_max = 87 degrees (theta_o = 90 is
#: degenerate: the view lies in the tangent plane; the design notes' measured baseline uses 0..87 degrees).
DEFAULT_LOBES, DEFAULT_ELEVATIONS = 3, 15
#: ``relight fit`` adds up to this many lobes beyond K, only at elevations whose error exceeds ``refine_above``
#: (Torrance-Sparrow alpha 0.2: K = 3 everywhere up to 56 degrees, 4-5 lobes from 62 degrees; errors at 62, 75,
#: 81 degrees 2.3, 2.7, 5.2 % instead of K = 3's 5.1, 12.1, 18.6 %, tests/relight/test_sgfit.py).
DEFAULT_EXTRA_LOBES = 2
DEFAULT_THETA_MAX = math.radians(87.0)
#: The warm-started solution is kept unless another start lowers the cost by more than this fraction: switching
#: basins between neighbouring elevations makes interpolated parameters blend unrelated lobes.
CONTINUATION_SLACK = 0.02


@dataclass
class FitSettings:
    lobes: int = DEFAULT_LOBES
    elevations: int = DEFAULT_ELEVATIONS
    theta_max: float = DEFAULT_THETA_MAX
    max_lobes: int | None = None
    refine_above: float = 0.05
    n_gamma: int = 160
    n_psi: int = 24
    max_nfev: int = 200
    #: Elevations the bisection pass may add where interpolation fails (``relight.sgfit_refine``; 0: none).
    max_inserted: int = MAX_INSERTED

    def check(self) -> None:
        validate.int_in_range("fit: lobes", self.lobes, 1, 8)
        validate.int_in_range("fit: elevations", self.elevations, 2, 64)
        if not (math.isfinite(self.theta_max) and 0.0 < self.theta_max < math.pi / 2):
            raise InputError(f"fit: theta_max must lie in (0, pi/2) radians, got {self.theta_max!r}")
        validate.int_in_range("fit: max_inserted", self.max_inserted, 0, 64)
        ml = self.lobes if self.max_lobes is None else self.max_lobes
        if not self.lobes <= ml <= 8:
            raise InputError(f"fit: max_lobes must lie in [lobes, 8], got {self.max_lobes}")


@dataclass
class ColdElevation:
    """What one elevation's fit needs before the continuation: its slice (M, 3) and sqrt quadrature weights (M,),
    the peak (mu, sigma) of the luminance and the solutions from the cold starts (``cold_elevation``)."""

    theta: float
    t: FloatArray
    sq: FloatArray
    peak: tuple[float, float]
    sols: list[Solution]


def cold_elevation(brdf: Lobe | SumBRDF | Any, settings: FitSettings, theta: float, first: bool) -> ColdElevation:
    """The part of one elevation's fit that depends on nothing else (a pure function of its arguments, so it can
    run anywhere: ``relight.worker.gaussian`` fans it out over the Dask workers): the slice and the fits from the
    cold starts -- at the first elevation three spreads of widths around the peak (mu = 0 at theta_o = 0), later
    one spread and the lobes spread across the plane of incidence."""
    grid = slice_grid(settings.n_gamma, settings.n_psi)
    t, sq = _slice_at(brdf, grid, theta)
    y = sq * luminance(t)
    if not np.any(y > 0.0):
        raise InputError(f"fit: the BRDF slice is zero at theta_o = {math.degrees(theta):.3g} degrees")
    mu_pk, sig_pk = peak(grid.local, y, sq)
    k = settings.lobes
    fix_mu = first and theta == 0.0
    prob = VarPro(grid.local, sq, y, k, fix_mu)
    starts: list[tuple[FloatArray, FloatArray]] = []
    fresh_mu = np.zeros(k) if fix_mu else np.full(k, mu_pk)
    for spread in ((0.5, 1.0, 2.0), (0.7, 1.0, 1.4), (0.3, 1.0, 3.0)) if first else ((0.5, 1.0, 2.0),):
        f = np.geomspace(spread[0], spread[2], k) if k > 1 else np.ones(1)
        starts.append((fresh_mu, np.log(sig_pk * f)))
    if not first and k > 1:  # lobes spread across the plane of incidence around the peak
        starts.append((mu_pk + sig_pk * np.linspace(-0.8, 0.8, k), np.full(k, math.log(0.8 * sig_pk))))
    sols = [solve(prob, mu0, s0, settings.max_nfev) for mu0, s0 in starts]
    return ColdElevation(theta, t, sq, (mu_pk, sig_pk), sols)


#: Maps ``[(theta, first), ...]`` to their :class:`ColdElevation` in order (serial here; a Dask map in the worker).
ColdMap = Callable[[list[tuple[float, bool]]], list[ColdElevation]]


def _serial_map(brdf: Any, settings: FitSettings) -> ColdMap:
    return lambda items: [cold_elevation(brdf, settings, th, first) for th, first in items]


def fit_gaussian_lobes(brdf: Lobe | SumBRDF | Any, settings: FitSettings | None = None, *,
                       cold_map: ColdMap | None = None) -> GaussianLobes:
    """Fit K Gaussian lobes at N elevations in [0, theta_max] (module docstring); returns the material with its
    report in ``.fit`` (per-elevation errors, mid-elevation errors, energy check, timings). ``cold_map`` runs the
    independent per-elevation part (:func:`cold_elevation`) -- the result does not depend on where it ran."""
    st = settings or FitSettings()
    st.check()
    k_max = st.lobes if st.max_lobes is None else st.max_lobes
    t_start = time.perf_counter()
    grid: SliceGrid = slice_grid(st.n_gamma, st.n_psi)
    local = grid.local
    thetas = np.linspace(0.0, st.theta_max, st.elevations)
    errors = np.zeros(st.elevations)
    albedo = np.zeros((st.elevations, 3))
    used = np.zeros(st.elevations, dtype=np.intp)
    slices: list[tuple[FloatArray, FloatArray]] = []
    prev: Solution | None = None
    prev_full: Solution | None = None
    bests: list[Solution] = []
    probs: list[VarPro] = []
    colds = (cold_map or _serial_map(brdf, st))([(float(th), i == 0) for i, th in enumerate(thetas)])
    for i, th in enumerate(thetas):
        cold = colds[i]
        t, sq = cold.t, cold.sq
        slices.append((t, sq))
        y = sq * luminance(t)
        albedo[i] = _albedo(t, sq)
        mu_pk, sig_pk = cold.peak
        k = st.lobes
        fix_mu = i == 0 and th == 0.0
        prob = VarPro(local, sq, y, k, fix_mu)
        starts: list[tuple[FloatArray, FloatArray]] = []
        warm = -1
        if prev is not None:
            warm = len(cold.sols)
            starts.append((prev.mu[:k], prev.s[:k]))
            dead = prev.w[:k] <= DEAD_FRACTION * max(prev.w[:k].sum(), 1e-300)
            if dead.any():
                mu_r, s_r = prev.mu[:k].copy(), prev.s[:k].copy()
                mu_r[dead] = mu_pk
                s_r[dead] = math.log(sig_pk) + np.linspace(-0.7, 0.7, int(dead.sum()))
                starts.append((mu_r, s_r))
        sols = list(cold.sols) + [solve(prob, mu0, s0, st.max_nfev) for mu0, s0 in starts]
        best = min(sols, key=lambda x: x.cost)
        if warm >= 0 and sols[warm].cost <= (1.0 + CONTINUATION_SLACK) * best.cost:
            best = sols[warm]  # the warm start, unless another basin is clearly better
        # more lobes only where needed
        while k < k_max:
            g, _, _ = basis(local, best.mu, best.s)
            resid = y - (g * sq[:, None]) @ best.w
            if math.sqrt(best.cost) / float(np.linalg.norm(y)) <= st.refine_above:
                break
            mu_n, sig_n = peak(local, np.maximum(resid, 0.0), sq)
            bigger = VarPro(local, sq, y, k + 1, fix_mu)
            seeds = [(np.append(best.mu, 0.0 if fix_mu else mu_n), np.append(best.s, math.log(max(sig_n, SIGMA_LO))))]
            big = int(np.argmax(best.w))  # or split the heaviest lobe across the plane of incidence
            half = 0.5 * math.exp(best.s[big]) * (0.0 if fix_mu else 1.0)
            mu_split = np.append(best.mu, best.mu[big] + half)
            mu_split[big] -= half
            seeds.append((mu_split, np.append(best.s, best.s[big])))
            if prev_full is not None and prev_full.mu.size == k + 1:
                seeds.append((prev_full.mu, prev_full.s))
            cand = min((solve(bigger, m0, s0, st.max_nfev) for m0, s0 in seeds), key=lambda x: x.cost)
            if cand.cost >= 0.98 * best.cost:
                break
            best, k = cand, k + 1
        used[i] = k
        bests.append(best)
        probs.append(prob)
        # the continuation carries the K heaviest lobes: extra lobes are re-added only where needed
        prev_full = best
        keep = np.sort(np.argsort(-best.w, kind="stable")[: st.lobes])
        prev = Solution(mu=best.mu[keep], s=best.s[keep], w=best.w[keep], cost=best.cost)
    k_max = int(used.max())  # as many slots as the most lobes any elevation needed
    mus, ss = np.zeros((st.elevations, k_max)), np.zeros((st.elevations, k_max))
    ws = np.zeros((st.elevations, k_max, 3))
    for i, th in enumerate(thetas):
        t, sq = slices[i]
        best, k, fix_mu = bests[i], int(used[i]), probs[i].fix_mu
        mu, s = best.mu, best.s
        phi = basis(local, mu, s)[0] * sq[:, None]
        w = channel_weights(phi, sq, t)
        mu, s, w = merge_duplicates(mu, s, w)
        if fix_mu:
            mu = np.zeros_like(mu)
        mu_full = np.concatenate([mu, np.zeros(k_max - k)])
        s_full = np.concatenate([s, np.full(k_max - k, s.max())])
        w_full = np.concatenate([w, np.zeros((k_max - k, 3))])
        if i == 0:
            order = np.lexsort((mu_full, -s_full - 1e3 * (w_full.sum(axis=1) > 0)))
        else:
            order = match_lobes(mus[i - 1], ss[i - 1], ws[i - 1].sum(axis=1), mu_full, s_full, w_full.sum(axis=1))
            if k_max <= MAX_PERMUTED_LOBES:
                mid_t, mid_sq = _slice_at(brdf, grid, 0.5 * float(thetas[i - 1] + th))
                order = best_permutation(local, mid_sq, mid_t, (mus[i - 1], ss[i - 1], ws[i - 1]),
                                          (mu_full, s_full, w_full), order)
        mus[i], ss[i], ws[i] = mu_full[order], s_full[order], w_full[order]
        errors[i] = relative_error(local, sq, t, mus[i], ss[i], ws[i])
    pin_dead(mus, ss, ws)
    if thetas[0] == 0.0:
        mus[0] = 0.0  # mu = 0 at normal view by symmetry, dead lobes included (they only fade in from there)
    n_fitted = thetas.size
    fitted_thetas = thetas.copy()
    if st.max_inserted > 0:
        fitted = [Elevation(float(th), mus[i], ss[i], ws[i], float(errors[i])) for i, th in enumerate(thetas)]
        rows = refine_elevations(brdf, grid, fitted, st, max_inserted=st.max_inserted)
        if len(rows) > n_fitted:
            thetas = np.array([r.theta for r in rows])
            mus, ss = np.stack([r.mu for r in rows]), np.stack([r.s for r in rows])
            ws, errors = np.stack([r.w for r in rows]), np.array([r.error for r in rows])
            alive = ws.sum(axis=2) > DEAD_FRACTION * np.maximum(ws.sum(axis=(1, 2)), 1e-300)[:, None]
            was = np.searchsorted(fitted_thetas, thetas)  # fitted rows keep their count; inserted: live lobes
            used = np.where(np.isin(thetas, fitted_thetas), used[np.minimum(was, n_fitted - 1)], alive.sum(axis=1))
            albedo = np.stack([_albedo(*_slice_at(brdf, grid, float(th))) for th in thetas])
    leak = np.array([_leak(grid, float(th), mus[i], ss[i], ws[i]) for i, th in enumerate(thetas)])
    mid = _mid_errors(brdf, grid, thetas, mus, ss, ws)
    envelope = _envelope(thetas[np.isin(thetas, fitted_thetas)], thetas, errors, mid)
    sigma = np.exp(ss)
    report: dict[str, Any] = {
        "method": "variable projection (NNLS weights, TRF on mu and log sigma, Kaufman Jacobian), continuation",
        "lobes": st.lobes,
        "max_lobes": st.lobes if st.max_lobes is None else st.max_lobes,
        "lobes_used": [int(x) for x in used],
        "elevations_fitted": n_fitted,
        "elevations_inserted": int(thetas.size - n_fitted),
        "theta_max": st.theta_max,
        "grid": {"n_gamma": st.n_gamma, "n_psi": st.n_psi, "nodes": grid.size},
        "errors": [float(x) for x in errors],
        "mid_elevations": [float(x) for x in 0.5 * (thetas[1:] + thetas[:-1])],
        "mid_errors": [float(x) for x in mid],
        "envelope_ratios": [float(x) for x in envelope],
        "albedo": albedo.tolist(),
        "sum_weights": ws.sum(axis=1).tolist(),
        "leak_below_horizon": [float(x) for x in leak],
        "seconds": time.perf_counter() - t_start,
        "brdf": _brdf_spec(brdf),
    }
    return GaussianLobes(thetas, mus, sigma, ws, errors=errors, fit=report)


def _envelope(fitted: FloatArray, thetas: FloatArray, errors: FloatArray, mid: FloatArray) -> FloatArray:
    """Per interval of the fitted grid: the largest error inside it (inserted elevations and every mid-elevation
    with interpolated parameters) over the larger error at its ends -- the mid-elevation rule measured against
    the original neighbours, so inserted elevations cannot pass it by being bad themselves."""
    out = np.zeros(fitted.size - 1)
    idx = np.searchsorted(fitted, thetas, side="right") - 1  # the fitted interval each elevation starts
    ends = errors[np.isin(thetas, fitted)]
    for j, (i0, e) in enumerate(zip(idx[:-1], mid, strict=True)):
        inner = errors[j + 1] if thetas[j + 1] not in fitted else 0.0
        out[i0] = max(out[i0], e, inner)
    return np.asarray(out / np.maximum(np.maximum(ends[:-1], ends[1:]), 1e-300), dtype=np.float64)


def _albedo(t: FloatArray, sq: FloatArray) -> FloatArray:
    return np.asarray((sq * sq) @ t, dtype=np.float64)


def _leak(grid: SliceGrid, theta: float, mu: FloatArray, s: FloatArray, w: FloatArray) -> float:
    """The fraction of the fitted lobes' mass below the horizon at elevation theta."""
    g = (basis(grid.local, mu, s)[0] @ w).sum(axis=1)
    z = grid.world(theta)[:, 2]
    tot = float(grid.weights @ g)
    return float(grid.weights @ np.where(z <= 0.0, g, 0.0)) / tot if tot else 0.0


def _brdf_spec(brdf: Any) -> Any:
    try:
        return brdf.spec()
    except Exception:  # noqa: BLE001 - an unsaved table or a callable lobe has no spec; the report says so
        return None


def _slice_at(brdf: Any, grid: SliceGrid, theta: float) -> tuple[FloatArray, FloatArray]:
    t, valid = transfer_slice(brdf, grid, theta)
    return (np.repeat(t, 3, axis=1) if t.shape[1] == 1 else t), np.sqrt(grid.weights * valid)


def _mid_errors(brdf: Any, grid: SliceGrid, thetas: FloatArray, mus: FloatArray, ss: FloatArray,
                ws: FloatArray) -> FloatArray:
    """Error at each mid-elevation with parameters interpolated linearly (sigma linearly, as a texture does)."""
    out = np.zeros(thetas.size - 1)
    sig = np.exp(ss)
    for i in range(thetas.size - 1):
        th = 0.5 * (thetas[i] + thetas[i + 1])
        t, valid = transfer_slice(brdf, grid, float(th))
        if t.shape[1] == 1:
            t = np.repeat(t, 3, axis=1)
        sq = np.sqrt(grid.weights * valid)
        mu = 0.5 * (mus[i] + mus[i + 1])
        s = np.log(0.5 * (sig[i] + sig[i + 1]))
        w = 0.5 * (ws[i] + ws[i + 1])
        out[i] = relative_error(grid.local, sq, t, mu, s, w)
    return out


def error_table(material: GaussianLobes) -> str:
    """The per-elevation error table printed by ``relight fit``."""
    rep = material.fit
    lines = [f"{'theta_o':>8} {'error %':>8} {'mid %':>8} {'sum w / albedo':>15} {'lobes (mu, sigma in degrees)'}"]
    mid = rep.get("mid_errors", [])
    for i, th in enumerate(material.elevations):
        alb = np.asarray(rep["albedo"][i]) if "albedo" in rep else np.full(3, np.nan)
        sw = material.weight[i].sum(axis=0)
        ratio = float(sw @ LUMINANCE_WEIGHTS / max(float(alb @ LUMINANCE_WEIGHTS), 1e-300))
        err = material.errors[i] if material.errors is not None else float("nan")
        m = f"{100 * mid[i]:8.2f}" if i < len(mid) else f"{'':>8}"
        lobes = " ".join(f"({math.degrees(material.mu[i, k]):+.1f}, {math.degrees(material.sigma[i, k]):.2f})"
                         for k in range(material.n_lobes) if material.weight[i, k].sum() > 0.0)
        lines.append(f"{math.degrees(th):8.2f} {100 * err:8.2f} {m} {ratio:15.4f} {lobes}")
    lines.append(f"fit time {rep.get('seconds', float('nan')):.2f} s")
    return "\n".join(lines)
