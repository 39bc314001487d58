"""Cost model of prefiltering (seed 000 §6.2 Table 3, App. C, App. D), calibrated on the running machine.

Seed 000 Table 3 gives the asymptotic costs: ``O(F_B S_B^2)`` for a radially symmetric (1-D) lobe,
``O(F_B P_B^2 S_B^2)`` for an SHRM, and ``O(W S_L^2 S_B^2)`` for the angular method, W the fraction of the
environment's pixels a lobe touches (App. D). Here each stage of relight's pipeline gets a linear model
``t = sum_k c_k phi_k`` in features ``phi_k`` counted from the operation's sizes and orders, and the constants
``c_k`` (seconds per unit) are fitted by non-negative least squares on relative error to a few timed runs on this
machine (:func:`calibrate`, a few seconds), cached in a JSON file keyed by machine and relight version
(:func:`load_calibration`).

Notes: the terms
----------------
``C`` colour channels (3), ``S_L x 2 S_L`` input, ``S_B x 2 S_B`` output, orders F, P.

* **SH projection of the lighting** (App. C step 1, ``relight.prefilter.project_lighting``). The paper's separable
  algorithm costs ``O(F S_L^2)``: a direct DFT over phi for 2F + 1 values of m on every ring. ducc0 does that step
  by FFT, ``O(S_L^2 log S_L)``, and keeps the paper's ``O(F^2 S_L)`` Legendre sums over theta, so the features are
  ``proj_call = C``, ``proj_px = C S_L 2S_L log2(2 S_L)`` and ``proj_leg = C S_L (F + 1)^2``.
* **Synthesis** (App. C step 3, eq. 14): one ducc0 synthesis per map, colour and ``|q|`` group; with S ~ 10 F the
  Legendre part ``S_B (F + 1)^2`` is the paper's ``F S_B^2`` per map, ``(P + 1)^2`` maps for a general SHRM,
  P + 1 without azimuthal dependence, 1 for a radial lobe (Table 3's ``F_B P_B^2 S_B^2``). Spin-weighted syntheses
  (q != 0, two output fields) get their own constants: ``syn_px``/``syn_leg`` (q = 0) and ``synq_px``/``synq_leg``
  (``S_B 2S_B log2(2 S_B)`` and ``S_B (F + 1)^2`` summed over the syntheses), plus ``syn_call`` per call and
  ``comp_call`` per component (its report and predicted errors).
* **BRDF coefficients** (App. C step 1). A radial lobe's ``Lambda_l rho_l`` by composite quadrature costs
  ``O(F S_rho)`` with S_rho the quadrature nodes (about ``32 (F + 2)``, more for narrow lobes): ``lobe1d = sum over
  the order search's probes of (F + 1) x nodes`` (:func:`radial_nodes`), and the ringing bound
  ``ring = (F_B + 1) x samples`` (:func:`ringing_work`), both ``O(F^2)``. A general lobe is tabulated on the
  ``S_rho x T_rho x T_rho`` grid of ``relight.brdf.lpq`` for every probe of the order search, ``O(P S_rho
  T_rho^2)``: ``brdf_evals`` = grid points x this lobe's seconds per ``rho_hat`` evaluation (measured live by
  :func:`lobe_eval_seconds`, so a costly model such as Torrance–Sparrow is priced as such) and ``brdf_ops`` =
  grid points x (Q + 1) for the cosine transform and Legendre sums.
* **One view** (eq. 8 and eq. 12, ``relight.shrm.reflect`` on a fresh SHRM): ``view_base = S_B 2S_B`` (the
  normals of every pixel), ``view_px`` = maps x ``S_B 2S_B`` (the eq. 12 sum), ``eq8_px = sum_p (2p + 1)^2
  S_B 2S_B`` (eq. 8's rotation of a general component) and ``lookup_px = S_B 2S_B`` per N- or T-centred component
  (its bilinear lookup at N or T(N)).
* **Angular method** (``relight.reference.reference_radial``): ``ang_pairs`` = (output pixel, input pixel) pairs
  visited. App. D's ``W = (1 - cos theta*) / 2`` counts the pixels inside the lobe's cone; this implementation visits
  the whole latitude band that can meet the cone, ``W_band ~ 2 theta* / pi`` of the rows, so ``ang_pairs =
  W_band S_L 2S_L S_B 2S_B`` exactly (:func:`angular_pairs`; the tradeoff reports both W). For view-dependent
  BRDFs (``relight.reference_view``): ``angv_pairs`` pairs visited and ``angv_evals`` = lobe evaluations (the pairs
  inside the cones, or every pair of a row block whose cones fill more than 30 % of it) x seconds per evaluation
  (:func:`integrand_eval_seconds`, timed the way that code evaluates the lobe), counted block by block as that code
  runs (:func:`angular_view_counts`).
* ``lobe_call`` and ``ring_call``: fixed costs per lobe and per ringing bound (Python overheads);
  ``call`` (1 per prefilter) and ``conv = (F + 1)^2``: order selection (power spectra) and the convolution
  ``B_lm = Lambda_l rho_l L_lm`` (App. C step 2, ``O(F_B^2)`` for radial lobes).

The fit is per stage (each stage's features against that stage's own timings from the reports), which keeps every
constant determined by the runs that exercise it. Predictions are for the machine the calibration ran on; the
machines are noisy, so :class:`Calibration` keeps the in-sample ratio of predicted to measured time.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import platform
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, sh
from relight.brdf.base import Lobe
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: Features of each stage (module docstring). Stage names match the ``timings`` of the prefilter reports.
STAGES: dict[str, tuple[str, ...]] = {
    "brdf_coefficients": ("lobe_call", "lobe1d", "brdf_evals", "brdf_ops"),
    "lighting_projection": ("proj_call", "proj_px", "proj_leg"),
    "synthesis": ("comp_call", "syn_call", "syn_px", "syn_leg", "synq_px", "synq_leg"),
    "ringing_bound": ("ring_call", "ring"),
    "other": ("call", "conv"),
    "view": ("view_base", "view_px", "eq8_px", "lookup_px"),
    "angular": ("ang_pairs",),
    "angular_view": ("angv_pairs", "angv_evals"),
}
FEATURES: tuple[str, ...] = tuple(f for feats in STAGES.values() for f in feats)

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

#: Channels of every environment map (RGB).
CHANNELS = 3
#: A view-reference group's cones filling more than this share of its band are evaluated densely
#: (``relight.reference_view.reflected_radiance``).
_DENSE_FRACTION = 0.3
_VIEW_GROUP = 256


# --------------------------------------------------------------------------------------------------- features
def _log2(n: int) -> float:
    return math.log2(max(n, 2))


def projection_features(height: int, width: int, f_proj: int, channels: int = CHANNELS) -> dict[str, float]:
    """Features of projecting an ``H x W`` map to order ``f_proj`` (module docstring)."""
    return {
        "proj_call": float(channels),
        "proj_px": float(channels * height * width) * _log2(width),
        "proj_leg": float(channels * height) * (f_proj + 1) ** 2,
    }


def synthesis_features(size: int, f_b: int, n_spin0: int, n_spin: int) -> dict[str, float]:
    """Features of ``n_spin0`` spin-0 and ``n_spin`` spin-weighted syntheses of order F_B on ``S x 2S``."""
    px = float(size * 2 * size) * _log2(2 * size)
    leg = float(size) * (f_b + 1) ** 2
    return {
        "comp_call": 1.0,
        "syn_call": float(n_spin0 + n_spin),
        "syn_px": n_spin0 * px,
        "syn_leg": n_spin0 * leg,
        "synq_px": n_spin * px,
        "synq_leg": n_spin * leg,
    }


def synthesis_counts(structure: str, p_b: int, f_b: int, channels: int = CHANNELS) -> tuple[int, int]:
    """(spin-0, spin-weighted) syntheses of one SHRM component (``relight.shrm._synthesize_ducc0``'s groups)."""
    if structure == "radial":
        return channels, 0
    if structure == "azimuthal":
        return channels * (p_b + 1), 0
    n_q = sum(min(p, f_b) for p in range(p_b + 1))  # groups (p, |q|) with 0 < |q| <= min(p, F)
    return channels * (p_b + 1), channels * n_q


def n_maps(structure: str, p_b: int) -> int:
    """Maps stored for a component: 1, P + 1 or (P + 1)^2 (seed 000 §7.3; ``relight.shrm.terms_for``)."""
    return 1 if structure == "radial" else (p_b + 1 if structure == "azimuthal" else (p_b + 1) ** 2)


def tabulation_points(f_order: int, p_order: int, *, radial: bool, azimuthal: bool) -> tuple[int, int]:
    """(grid points, Q + 1) of ``relight.brdf.lpq.tabulation_grid(F, P)`` (App. C's S_rho x T_rho x T_rho)."""
    from relight.brdf.lpq import tabulation_grid

    n_i, n_o, n_phi = tabulation_grid(f_order, p_order, radial=radial, azimuthal=azimuthal).shape
    q = 1 if (radial or azimuthal) else p_order + 1
    return n_i * n_o * n_phi, q


def probe_orders(lobe: Lobe, f_order: int, p_order: int, *, explicit: bool) -> list[tuple[int, int]]:
    """The (F, P) at which the BRDF coefficients are tabulated to reach (F, P).

    Explicit orders: just (F, P). From a tolerance (``relight.brdf.lpq.select_orders``): the starting orders, then
    both grown (F doubles, P + 4) until they cover (F, P) — the path the search takes when neither order alone
    is short, an estimate (the search stops at the first probe meeting the tolerance).
    """
    if explicit:
        return [(f_order, p_order)]
    from relight.brdf.lpq import starting_orders

    f0, p0 = starting_orders(lobe)
    if lobe.radially_symmetric:
        p0 = 0
    probes = [(f0, p0)]
    while f0 < f_order or p0 < p_order:
        f0 = 2 * f0 if f0 < f_order else f0
        p0 = p0 + 4 if p0 < p_order else p0
        probes.append((f0, p0))
    return probes


_eval_cache: dict[str, float] = {}
_eval_lock = threading.Lock()


def lobe_eval_seconds(lobe: Lobe, *, repeat: int = 5) -> float:
    """Seconds per ``rho_hat`` evaluation of this lobe (best of ``repeat`` on a 16^3 grid), cached per spec."""
    try:
        key: str | None = json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        key = None
    if key is not None and key in _eval_cache:
        return _eval_cache[key]
    n = 16
    t = (np.arange(n) + 0.5) * np.pi / n
    ti, to, ph = t[:, None, None], t[None, :, None], t[None, None, :]
    best = math.inf
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        lobe.rho_hat(ti, to, ph)
        best = min(best, time.perf_counter() - t0)
    per = best / n**3
    if key is not None:
        with _eval_lock:
            _eval_cache[key] = per
    return per


def radial_nodes(lmax: int, width: float) -> int:
    """Quadrature nodes of ``relight.brdf.coefficients.radial_transfer`` at order lmax for a lobe of this width
    (its ``_theta_nodes``: panels of ``min(pi / (2 (lmax + 2)), width / 12, pi / 64)`` plus 2 x 40 graded ones,
    16 Gauss–Legendre nodes each)."""
    h = min(math.pi / (2.0 * (lmax + 2)), max(width, 1e-4) / 12.0, math.pi / 64)
    n_half = math.ceil((math.pi / 2) / h)
    return 16 * (2 * n_half + 80)


def radial_probes(lobe: Lobe, f_rho: int, *, explicit: bool) -> list[int]:
    """Orders at which ``spectrum_for_tolerance`` evaluates a radial lobe to find F_rho (its doubling search)."""
    if explicit:
        return [f_rho]
    from relight.brdf.coefficients import lobe_width

    probe = max(16, math.ceil(4.0 / max(lobe_width(lobe), 1e-3)))  # type: ignore[arg-type]
    probes = [probe]
    while probe < f_rho:
        probe *= 2
        probes.append(probe)
    return probes


def integrand_eval_seconds(lobe: Lobe, *, repeat: int = 5) -> float:
    """Seconds per lobe evaluation the way ``relight.reference_view`` evaluates it: ``u(C . w)`` for a radial lobe,
    ``f(w, V, N)`` for a general isotropic BRDF, ``rho_hat`` otherwise (best of ``repeat`` on 4096 samples)."""
    from relight.brdf.base import IsotropicBRDF, RadialLobe

    try:
        key: str | None = json.dumps(["integrand", type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        key = None
    if key is not None and key in _eval_cache:
        return _eval_cache[key]
    if not isinstance(lobe, RadialLobe | IsotropicBRDF):
        return lobe_eval_seconds(lobe, repeat=repeat)
    n = 4096
    r = np.random.default_rng(0)
    w = r.standard_normal((n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    v = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (n, 3))
    nrm = np.broadcast_to(np.array([0.0, 0.6, 0.8]), (n, 3))
    best = math.inf
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        if isinstance(lobe, RadialLobe):
            lobe.u(w[:, 2])
        else:
            lobe.f(w, v, nrm)
        best = min(best, time.perf_counter() - t0)
    per = best / n
    if key is not None:
        with _eval_lock:
            _eval_cache[key] = per
    return per


def _eval_cache_put(lobe: Lobe, seconds: float) -> None:
    try:
        key = json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        return
    with _eval_lock:
        _eval_cache[key] = seconds


def brdf_features(
    lobe: Lobe, f_rho: int, p_rho: int, *, explicit: bool, eval_seconds: float | None = None,
    search: str = "radial", probes: Sequence[tuple[int, int]] | None = None,
) -> dict[str, float]:
    """BRDF coefficient stage of one lobe (module docstring): ``lobe1d`` for radial lobes, else tabulation.

    ``search`` names the order search a tolerance runs: ``"radial"`` (``prefilter_radial``'s
    ``spectrum_for_tolerance``) or ``"lpq"`` (``create_shrm``'s ``lpq.select_orders``). ``probes`` gives the
    (F, P) the search actually tabulated (an SHRM report's ``probes``), else they are estimated
    (:func:`radial_probes`, :func:`probe_orders`).
    """
    if lobe.radially_symmetric:
        from relight.brdf.coefficients import lobe_width

        width = lobe_width(lobe)  # type: ignore[arg-type]
        if probes is not None:
            fs = [f for f, _ in probes]
        elif search == "radial":
            fs = radial_probes(lobe, f_rho, explicit=explicit)
        else:
            fs = [f for f, _ in probe_orders(lobe, f_rho, 0, explicit=explicit)]
        work = sum((f + 1) * radial_nodes(f, width) for f in fs)
        return {"lobe_call": 1.0, "lobe1d": float(work)}
    per = lobe_eval_seconds(lobe) if eval_seconds is None else eval_seconds
    evals = ops = 0.0
    path = list(probes) if probes is not None else probe_orders(lobe, f_rho, p_rho, explicit=explicit)
    for f, p in path:
        pts, q = tabulation_points(f, p, radial=False, azimuthal=bool(lobe.azimuthally_symmetric))
        evals += pts * per
        ops += pts * q
    return {"lobe_call": 1.0, "brdf_evals": evals, "brdf_ops": ops}


def view_features(components: Iterable[tuple[str, int, str]], size: int) -> dict[str, float]:
    """One distant view's map (``relight.shrm.reflect``) on ``S x 2S``; components as (structure, P_B, centre).

    ``view_base``: the normals ``N = normalize(R + V)`` of every pixel; ``view_px``: the eq. 12 sum over a
    component's maps; ``eq8_px``: eq. 8's rotation of a general component's local maps (cached after the first
    view); ``lookup_px``: the bilinear lookup of an N- or T-centred component at N or T(N).
    """
    px = float(size * 2 * size)
    view = eq8 = lookup = 0.0
    for structure, p_b, centre in components:
        if structure != "radial":
            view += n_maps(structure, p_b) * px
        if structure == "general" and p_b > 0:
            eq8 += sum((2 * p + 1) ** 2 for p in range(p_b + 1)) * px
        if centre != "R":
            lookup += px
    return {"view_base": px, "view_px": view, "eq8_px": eq8, "lookup_px": lookup}


def angular_pairs(height: int, size: int, theta_star: float) -> int:
    """Pairs (output pixel, input pixel) that ``reference_radial`` visits: the rows within theta* (+ half a pixel)
    of each output ring, times the columns of both."""
    from relight.conventions import ring_thetas

    env_theta = ring_thetas(height)
    out_theta = ring_thetas(size)
    rows = np.abs(env_theta[None, :] - out_theta[:, None]) <= theta_star + 0.5 * np.pi / height
    return int(rows.sum()) * 2 * size * 2 * height


def angular_features(height: int, size: int, theta_star: float) -> dict[str, float]:
    """Angular method for a radial lobe truncated at theta* (App. D)."""
    return {"ang_pairs": float(angular_pairs(height, size, theta_star))}


def _cone_row_counts(c_theta: FloatArray, theta_star: FloatArray, env_theta: FloatArray, width: int) -> FloatArray:
    """Expected pixels of each ring inside each output's cone, (n_out, H): the ring's azimuthal share of the cone.

    A ring at polar angle ``t_r`` meets the cone of half-angle ``t*`` about a centre at ``t_c`` where
    ``cos dphi >= (cos t* - cos t_c cos t_r) / (sin t_c sin t_r)``: ``2 arccos(.) / (2 pi)`` of its pixels.
    """
    ct, st = np.cos(c_theta)[:, None], np.sin(c_theta)[:, None]
    cr, sr = np.cos(env_theta)[None, :], np.sin(env_theta)[None, :]
    cs = np.cos(theta_star)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (cs - ct * cr) / (st * sr)
    x = np.where(np.isfinite(x), x, np.where(cs <= ct * cr, -1.0, 1.0))
    return np.asarray(np.arccos(np.clip(x, -1.0, 1.0)) / np.pi * width, dtype=np.float64)


def angular_view_counts(
    brdf: Any, view: Sequence[float] | FloatArray, height: int, size: int, truncation: float,
    *, chunk_elems: int = 500_000,
) -> tuple[int, list[int], float]:
    """(pairs visited, lobe evaluations per lobe, mean App. D W) of ``reference_view`` for one view (module
    docstring).

    Follows ``relight.reference_view.reflected_radiance``'s groups and row blocks exactly; a block's pairs inside
    the cones are the expected counts of :func:`_cone_row_counts` instead of a test of every pair, and a block whose
    cones fill more than 30 % of it is evaluated densely, as there.
    """
    from relight.conventions import latlong_dirs, ring_thetas
    from relight.reference_view import lobe_truncation_angles, truncation_for
    from relight.shrm import brdf_lobes, halfway_normals, lobe_centres, unit_view

    v = unit_view(view)
    r = latlong_dirs(size, 2 * size).reshape(-1, 3)
    n, ok = halfway_normals(r, v)
    n, r = n[ok], r[ok]
    width = 2 * height
    env_theta = ring_thetas(height)
    half_px = 0.5 * np.pi / height
    pairs = 0
    evals_per_lobe: list[int] = []
    w_sum, w_n = 0.0, 0
    facing = (n @ v) > 0.0
    for lobe in brdf_lobes(brdf):
        evals = 0
        table = lobe_truncation_angles(lobe, truncation)
        centres = lobe_centres(str(lobe.center), n, r)
        theta_star = truncation_for(table, centres @ v)
        w_sum += float((0.5 * (1.0 - np.cos(theta_star)))[facing].sum())
        w_n += int(facing.sum())
        c_theta = np.arccos(np.clip(centres[:, 1], -1.0, 1.0))
        order = np.argsort(c_theta, kind="stable")
        order = order[facing[order]]
        for g0 in range(0, order.size, _VIEW_GROUP):
            idx = order[g0 : g0 + _VIEW_GROUP]
            reach = float(theta_star[idx].max()) + half_px
            lo, hi = c_theta[idx].min(), c_theta[idx].max()
            rows = np.nonzero((env_theta >= lo - reach) & (env_theta <= hi + reach))[0]
            if rows.size == 0:
                continue
            inside = _cone_row_counts(c_theta[idx], theta_star[idx], env_theta[rows], width).sum(axis=0)
            step = max(1, chunk_elems // (idx.size * width))
            for r0 in range(0, rows.size, step):
                n_rows = min(step, rows.size - r0)
                block = idx.size * n_rows * width
                hit = float(inside[r0 : r0 + n_rows].sum())
                pairs += block
                evals += block if hit > _DENSE_FRACTION * block else int(round(hit))
        evals_per_lobe.append(evals)
    return pairs, evals_per_lobe, (w_sum / w_n if w_n else 0.0)


def angular_view_features(
    brdf: Any, view: Sequence[float] | FloatArray, height: int, size: int, truncation: float
) -> dict[str, float]:
    """Angular method for a view-dependent BRDF, one view (``relight.reference_view.reference_view``)."""
    from relight.shrm import brdf_lobes

    pairs, evals, _ = angular_view_counts(brdf, view, height, size, truncation)
    cost = sum(n * integrand_eval_seconds(lobe) for n, lobe in zip(evals, brdf_lobes(brdf), strict=True))
    return {"angv_pairs": float(pairs), "angv_evals": cost}


def add_features(*parts: Mapping[str, float]) -> dict[str, float]:
    """Sum feature dictionaries (the costs of several operations run one after the other)."""
    out: dict[str, float] = {}
    for p in parts:
        for k, v in p.items():
            out[k] = out.get(k, 0.0) + float(v)
    return out


def radial_features(
    lobe: Lobe, *, height: int, width: int, f_rho: int, f_proj: int, f_b: int, size: int, explicit: bool = True
) -> dict[str, float]:
    """``relight.prefilter.prefilter_radial`` (Table 3's 1-D BRDF row plus the projection and lobe stages);
    ``explicit=False`` when the order came from a tolerance (the order search's probes are priced too)."""
    n0, _ = synthesis_counts("radial", 0, f_b)
    return add_features(
        brdf_features(lobe, f_rho, 0, explicit=explicit),
        projection_features(height, width, f_proj),
        synthesis_features(size, f_b, n0, 0),
        {"ring_call": 1.0, "ring": float(ringing_work(f_b)), "call": 1.0, "conv": float((f_proj + 1) ** 2)},
    )


def ringing_work(f_b: int) -> int:
    """Legendre evaluations of ``relight.brdf.coefficients.ringing_minimum``: ``16 (F + 1) + 256`` samples and
    three zoom passes of 201, each ``F + 1`` polynomials."""
    return (f_b + 1) * (16 * (f_b + 1) + 256 + 3 * 201)


@dataclass(frozen=True)
class LobePlan:
    """One lobe of an SHRM for the cost model: its structure and orders (``relight.shrm.create_shrm``)."""

    lobe: Lobe
    structure: str  # "radial", "azimuthal" or "general"
    f_rho: int
    f_b: int
    p_b: int
    explicit: bool = False
    #: (F, P) the order search tabulated (``probes`` of an SHRM report); None: estimated
    probes: tuple[tuple[int, int], ...] | None = None


def shrm_features(
    lobes: Sequence[LobePlan], *, height: int, width: int, f_proj: int, size: int, views: int = 0
) -> dict[str, float]:
    """``relight.shrm.create_shrm`` (Table 3's SHRM row), plus ``views`` eq. 12 maps."""
    parts: list[Mapping[str, float]] = [
        projection_features(height, width, f_proj), {"call": 1.0, "conv": float((f_proj + 1) ** 2)},
    ]
    for lp in lobes:
        parts.append(brdf_features(lp.lobe, lp.f_rho, lp.p_b, explicit=lp.explicit, search="lpq", probes=lp.probes))
        n0, nq = synthesis_counts(lp.structure, lp.p_b, lp.f_b)
        parts.append(synthesis_features(size, lp.f_b, n0, nq))
    if views:
        vf = view_features([(lp.structure, lp.p_b, str(lp.lobe.center)) for lp in lobes], size)
        parts.append({k: views * v for k, v in vf.items()})
    return add_features(*parts)


def prefilter_report_features(lobe: Lobe, report: Mapping[str, Any], *, height: int, width: int) -> dict[str, float]:
    """Features of a finished ``prefilter_radial`` run from its report (orders and whether they were explicit)."""
    o = report["orders"]
    size = int(report["output"]["height"])
    f_rho, f_b = int(o["F_rho"]), int(o["F_B"])
    explicit = report.get("order_requested") is not None
    f_proj = min(f_rho, height - 1)
    return radial_features(lobe, height=height, width=width, f_rho=f_rho, f_proj=f_proj, f_b=f_b, size=size,
                           explicit=explicit)


def shrm_lobe_plans(brdf: Any, report: Mapping[str, Any]) -> list[LobePlan]:
    """:class:`LobePlan` per component of a finished ``create_shrm`` run (orders and the search's probes)."""
    from relight.shrm import brdf_lobes

    plans = []
    for lobe, c in zip(brdf_lobes(brdf), report["components"], strict=True):
        o = c["orders"]
        probes = tuple((int(q["F"]), int(q["P"])) for q in c.get("probes") or [])
        plans.append(LobePlan(lobe=lobe, structure=str(c["structure"]), f_rho=int(o["F_rho"]), f_b=int(o["F_B"]),
                              p_b=int(o["P_B"]), explicit=bool(o.get("explicit")), probes=probes or None))
    return plans


def shrm_report_features(
    brdf: Any, report: Mapping[str, Any], *, height: int, width: int, views: int = 0
) -> dict[str, float]:
    """Features of a finished ``create_shrm`` run (plus ``views`` eq. 12 maps) from its report."""
    plans = shrm_lobe_plans(brdf, report)
    f_proj = min(max(p.f_rho for p in plans), height - 1)
    size = int(report["output"]["height"])
    return shrm_features(plans, height=height, width=width, f_proj=f_proj, size=size, views=views)


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


def calibration_key(machine: Mapping[str, Any] | None = None, version: str = __version__) -> str:
    """SHA-256 of the machine description and the relight version: the cache key."""
    payload = json.dumps({"machine": dict(machine or machine_info()), "relight": version}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()


def cache_dir() -> Path:
    """``$RELIGHT_CACHE_DIR``, else ``$XDG_CACHE_HOME/relight``, else ``~/.cache/relight``."""
    env = os.environ.get("RELIGHT_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "relight"


def cache_path(directory: Path | None = None, key: str | None = None) -> Path:
    k = key or calibration_key()
    return (directory or cache_dir()) / f"costmodel-{__version__}-{k[:16]}.json"


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
    from relight.brdf import lpq
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
        record("prefilter_radial", feats, _stage_min([report_stages(r.report["timings"]) for r in runs]))

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
            lpq.clear_cache()
            shrm_obj = create_shrm(px, brdf, order=f, p_order=p, epsilon=eps, size=s)
            stages = report_stages(shrm_obj.report["timings"])
            stages["view"], _ = _best(functools.partial(reflect, shrm_obj, view), 1)  # fresh: eq. 8 included
            reps.append(stages)
        assert shrm_obj is not None
        stages = _stage_min(reps)
        _eval_cache_put(micro, per_eval)
        feats = shrm_report_features(brdf, shrm_obj.report, height=h, width=2 * h, views=1)
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
        constants=constants, key=calibration_key(machine), machine=machine, relight_version=__version__,
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
        relight_version=__version__, created="", calibration_seconds=0.0, calibrated=False,
    )


def save_calibration(cal: Calibration, path: Path) -> None:
    """Write atomically (a temporary file in the same folder, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".costmodel-", suffix=".json", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(cal.as_dict(), fh, indent=1, sort_keys=True)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


_memo: dict[str, Calibration] = {}
_lock = threading.Lock()


def load_calibration(
    directory: Path | None = None, *, run: bool = True, recalibrate: bool = False, quick: bool = False
) -> Calibration:
    """The calibration for this machine and relight version: from memory, else the cache file, else (``run``)
    a fresh :func:`calibrate` saved to the cache, else :func:`default_calibration`.

    Thread-safe: concurrent callers wait for one calibration. An unreadable cache file is replaced.
    """
    key = calibration_key()
    path = cache_path(directory, key)
    memo_key = str(path)
    with _lock:
        if not recalibrate and memo_key in _memo:
            return _memo[memo_key]
        if not recalibrate and path.is_file():
            try:
                cal = Calibration.from_dict(json.loads(path.read_text(encoding="utf-8")))
                if cal.key == key:
                    _memo[memo_key] = cal
                    return cal
            except (OSError, ValueError):
                pass  # unreadable or foreign: calibrate again
        if not run and not recalibrate:
            return default_calibration()
        cal = calibrate(quick=quick)
        try:
            save_calibration(cal, path)
        except OSError:
            pass  # a read-only cache folder: keep the calibration in memory only
        _memo[memo_key] = cal
        return cal


def forget() -> None:
    """Drop the in-memory calibrations (tests)."""
    with _lock:
        _memo.clear()
