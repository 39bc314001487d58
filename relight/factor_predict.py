"""Numbers of in-out terms K predicted without an SVD (Mahajan, Tseng & Ramamoorthi 2008, §3.3, §3.4, §4).

* **Radial lobes about R** (Phong and any ``u(R . L)``): over the sphere the SVD *is* the SH expansion (eq. 9):
  sigma = |F_l| with multiplicity 2l + 1, ``F_l = Lambda_l rho_l`` = relight's transfer factor
  (``relight.brdf.coefficients.radial_transfer``), and the total energy is ``4 pi int u^2``. So the sphere's K at any
  threshold follows exactly from relight's spectrum (whole bands up to the order search's F plus part of band F).
  Over the visible hemisphere the paper's Fig. 5 observes l + 1 (instead of 2l + 1) values near F_l per band:
  the same count with multiplicity l + 1 is the hemisphere prediction (eq. 13's "(l* + 1)^2 / 2", band by band).
  Lobes about N (Lambert) are rank one: K = 1.
* **Other isotropic BRDFs** (half-angle lobes, microfacet models, measured tables): §4's 1-D recipe. The factored
  kernel is averaged over theta_d in [0, ``THETA_D_MAX``] and phi_d to a curve in theta_h (the paper omits grazing
  theta_d); the curve, as a lobe ``u(cos theta_h)``, is SH-transformed with relight's order search and l* is the
  order capturing the threshold's energy. The paper reads ``K ~ (l*)^2 / 4``; the block SVD gives
  ``K ~ HALF_ANGLE_SLOPE[tau] (l*)^2`` instead (calibration in bench/factorize.py). l* is always computed,
  never taken from the paper's printed ``l* ~ 1 / (2 sigma^2)``, which contradicts its own examples.

The paper's closed forms for Phong (eq. 12: K ~ 6 s; Fig. 3A: 5 s on the sphere, 2.5 s on the hemisphere) are
reported alongside.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from relight import validate
from relight.brdf.base import IsotropicBRDF, Lobe, RadialLobe
from relight.brdf.coefficients import spectrum_for_tolerance
from relight.brdf.lobe_cache import lobe_cache
from relight.brdf.measured import half_diff_to_dirs
from relight.brdf.radial import Lobe1D, Phong
from relight.errors import InputError
from relight.factor_kernel import DOMAINS, make_kernel, unwrap
from relight.factorization import THRESHOLDS, terms_for

#: Largest theta_d averaged into the theta_h curve (radians): 60 deg leaves out the grazing differences whose
#: measured data are "incomplete or noisy" (§4); the paper gives no value.
THETA_D_MAX = np.radians(60.0)
#: Samples of the theta_h curve (square-root spacing as MERL's, dense near theta_h = 0) and of theta_d, phi_d.
N_THETA_H, N_THETA_D, N_PHI_D = 512, 24, 24
#: Energy fraction left out when the radial spectrum is computed (its tail beyond is negligible for every count).
SPECTRUM_TAIL = 1e-8
#: K / (l*)^2 of eq. 14's half-angle lobe on the hemisphere from the converged block SVD (bench/factorize.py):
#: 90 %: 0.22-0.28, 95 %: 0.25-0.30, 99 %: 0.32-0.34 for sigma = 0.15 ... 0.3 (0.43 at sigma = 0.4: wide lobes need
#: more, as the paper notes). The paper's "(l*)^2 / 4" is 0.25; at 99 % it under-predicts by ~25 %.
HALF_ANGLE_SLOPE: dict[float, float] = {0.9: 0.24, 0.95: 0.27, 0.99: 0.33}
#: Grids (n_theta, n_phi) of :func:`terms_for_tolerance`'s block SVD: coarse first, fine when K > n_theta.
COARSE_GRID = (24, 48)
FINE_GRID = (64, 96)
#: Results of :func:`terms_for_tolerance` by the BRDF's JSON spec (a bounded ``relight.brdf.lobe_cache``): a plan
#: asks about each material again for every scene.
_TERMS_CACHE = lobe_cache()


def half_angle_slope(tau: float) -> float:
    """K / (l*)^2 at the energy fraction tau: :data:`HALF_ANGLE_SLOPE`, linear between its thresholds and held
    constant beyond them (the calibration covers 90-99 %)."""
    keys = sorted(HALF_ANGLE_SLOPE)
    return float(np.interp(tau, keys, [HALF_ANGLE_SLOPE[k] for k in keys]))


def mean_lobe(lobe: RadialLobe) -> RadialLobe:
    if lobe.channels == 1:
        return lobe
    return Lobe1D(func=lambda t: np.asarray(lobe.u(t), dtype=np.float64).mean(axis=-1), center=lobe.center)


def radial_terms(lobe: RadialLobe, domain: str, thresholds: tuple[float, ...] = THRESHOLDS) -> dict[str, Any]:
    """K per threshold of a radial lobe from its SH spectrum (module docstring), with the order l* per threshold."""
    if domain not in DOMAINS:
        raise InputError(f"domain must be one of {', '.join(DOMAINS)}, got {domain!r}")
    if lobe.center == "N":
        return {"method": "rank-one", "terms": {t: 1 for t in thresholds}, "l_star": {t: 0 for t in thresholds}}
    if lobe.center != "R":
        raise InputError(f"{lobe.kind}: radial predictions need a lobe about R or N, got centre {lobe.center!r}")
    mean = mean_lobe(lobe)
    spec, _ = spectrum_for_tolerance(mean, SPECTRUM_TAIL)
    transfer = np.abs(spec.transfer[:, 0])
    l = np.arange(transfer.size)
    mult = 2 * l + 1 if domain == "sphere" else l + 1
    values = np.sort(np.repeat(transfer, mult))[::-1]
    total = 4.0 * np.pi * float(spec.total_energy[0]) if domain == "sphere" else float(np.sum(mult * transfer**2))
    band = np.cumsum(transfer**2 * (2 * l + 1)) / (4.0 * np.pi * float(spec.total_energy[0]))
    l_star = {t: int(np.searchsorted(band, t * (1.0 - 1e-12))) for t in thresholds}
    return {"method": f"radial-spectrum-{domain}", "terms": terms_for(values, total, thresholds), "l_star": l_star}


def theta_h_curve(brdf: Any, *, include_cosine: bool = True, theta_d_max: float = THETA_D_MAX) -> dict[str, Any]:
    """The factored kernel averaged over theta_d in [0, theta_d_max] and phi_d: ``{"theta_h", "value"}`` (§4)."""
    if not 0.0 < theta_d_max <= np.pi / 2:
        raise InputError(f"theta_d_max must lie in (0, pi/2], got {theta_d_max}")
    kernel = make_kernel(brdf, domain="hemisphere", include_cosine=include_cosine)
    th = 0.5 * np.pi * np.linspace(0.0, 1.0, N_THETA_H) ** 2
    td = (np.arange(N_THETA_D) + 0.5) * theta_d_max / N_THETA_D
    pd = (np.arange(N_PHI_D) + 0.5) * np.pi / N_PHI_D
    wi, wo = half_diff_to_dirs(th[:, None, None], td[None, :, None], pd[None, None, :])
    ok = (wi[..., 2] > 0.0) & (wo[..., 2] > 0.0)
    vals = np.where(ok, kernel.full(wi, wo), 0.0)
    count = ok.sum(axis=(1, 2))
    curve = np.where(count > 0, vals.sum(axis=(1, 2)) / np.maximum(count, 1), 0.0)
    return {"theta_h": th, "value": curve}


def half_angle_terms(
    brdf: Any, *, include_cosine: bool = True, thresholds: tuple[float, ...] = THRESHOLDS
) -> dict[str, Any]:
    """§4's recipe: l* of the theta_h curve per threshold, K ~ slope (l*)^2 (calibrated) and the paper's (l*)^2/4."""
    c = theta_h_curve(brdf, include_cosine=include_cosine)
    t = np.cos(c["theta_h"])[::-1]
    u = c["value"][::-1]
    if not np.any(u > 0.0):
        raise InputError("the BRDF is zero on the visible hemisphere: nothing to factor")
    keep = np.concatenate([[True], np.diff(t) > 0.0])
    lobe = Lobe1D(np.stack([t[keep], u[keep]], axis=1), center="R")
    l_star: dict[float, int] = {}
    for tau in thresholds:
        _, order = spectrum_for_tolerance(lobe, 1.0 - tau)
        l_star[tau] = order
    slope = {tau: half_angle_slope(tau) for tau in thresholds}
    return {
        "method": "half-angle-curve",
        "terms": {tau: max(1, int(round(slope[tau] * l_star[tau] ** 2))) for tau in thresholds},
        "paper_terms": {tau: max(1, int(round(l_star[tau] ** 2 / 4.0))) for tau in thresholds},
        "l_star": l_star,
        "slope": slope,
    }


def predict_terms(
    brdf: Any, *, domain: str = "hemisphere", include_cosine: bool = True, thresholds: tuple[float, ...] = THRESHOLDS
) -> dict[str, Any]:
    """The cheapest applicable prediction of K per threshold (module docstring), with the paper's closed forms."""
    brdf = unwrap(brdf)
    lobes = brdf.lobes if hasattr(brdf, "lobes") and not isinstance(brdf, Lobe) else None
    if isinstance(lobes, list) and len(lobes) == 1:
        brdf = lobes[0]
    if isinstance(brdf, RadialLobe) and include_cosine:
        out = radial_terms(brdf, domain, thresholds)
        if isinstance(brdf, Phong):
            s = brdf.s
            out["paper"] = {"eq12_6s": 6.0 * s, "fig3a": (5.0 if domain == "sphere" else 2.5) * s}
        return out
    if isinstance(brdf, Lobe) and brdf.center == "T" or isinstance(lobes, list) and any(
            isinstance(x, Lobe) and x.center == "T" for x in lobes):
        raise InputError("no SVD-free prediction for a lobe about the tangent (anisotropic): run the SVD")
    if isinstance(brdf, (Lobe, IsotropicBRDF)) or isinstance(lobes, list):
        out = half_angle_terms(brdf, include_cosine=include_cosine, thresholds=thresholds)
        if domain == "sphere":
            out["note"] = "calibrated on the hemisphere; the kernel is 0 outside it, so the sphere's K is the same"
        return out
    raise InputError(f"no SVD-free prediction for {type(brdf).__name__} (anisotropic or a callable): run the SVD")


def _spec_key(brdf: Any, *parts: Any) -> str | None:
    import json

    try:
        return json.dumps([type(brdf).__qualname__, brdf.spec(), *parts], sort_keys=True)
    except (AttributeError, TypeError, ValueError):
        return None  # no JSON spec: never cached


def terms_for_tolerance(brdf: Any, epsilon: float, *, domain: str = "hemisphere", include_cosine: bool = True) -> dict[
        str, Any]:
    """The planner's K: in-out terms capturing ``1 - epsilon`` of the BRDF's energy (the paper's 99 % is
    epsilon = 0.01): ``{"terms": K, "method": ..., "seconds": ...}``.

    Radial lobes: :func:`radial_terms` (relight's spectrum; milliseconds). Other isotropic BRDFs: the block SVD on a
    small grid (``COARSE_GRID``, 20-50 ms), refined once to ``FINE_GRID`` when K exceeds the coarse grid's n_theta
    (sharp lobes the coarse grid under-resolves). Not the theta_h recipe: it takes longer (0.2-0.4 s) and
    mispredicts microfacet models with shadowing (Torrance-Sparrow alpha 0.4 at 99 %: 12 predicted vs 31 by the
    SVD at 64 x 96; Blinn-Phong s = 50: 74 vs 38). Results are cached per BRDF spec (``"cached": True``)."""
    import time

    from relight.factorization import factorize

    validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    tau = 1.0 - float(epsilon)
    t0 = time.perf_counter()
    b = unwrap(brdf)
    lobes = b.lobes if hasattr(b, "lobes") and not isinstance(b, Lobe) else None
    if isinstance(lobes, list) and len(lobes) == 1:
        b = lobes[0]
    if isinstance(b, RadialLobe) and include_cosine and b.center in ("R", "N"):
        k = int(radial_terms(b, domain, (tau,))["terms"][tau])
        return {"terms": k, "method": f"radial-spectrum-{domain}", "seconds": time.perf_counter() - t0}
    key = _spec_key(b, tau, domain, include_cosine)
    if key is not None and key in _TERMS_CACHE:
        return {**_TERMS_CACHE[key], "cached": True, "seconds": time.perf_counter() - t0}
    n_t, n_p = COARSE_GRID
    k = factorize(b, domain=domain, n_theta=n_t, n_phi=n_p, include_cosine=include_cosine, method="block",
                  thresholds=(tau,)).terms[tau]
    grid = COARSE_GRID
    if k > n_t:
        grid = FINE_GRID
        k = factorize(b, domain=domain, n_theta=grid[0], n_phi=grid[1], include_cosine=include_cosine,
                      method="block", thresholds=(tau,)).terms[tau]
    out = {"terms": int(k), "method": f"block-svd-{grid[0]}x{grid[1]}", "seconds": time.perf_counter() - t0}
    if key is not None:
        _TERMS_CACHE[key] = out
    return out
