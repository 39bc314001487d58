"""Predicted error of an SHRM per view band, N.V in [lo, hi] (seed 000 §5.1 and App. B applied per view; issue 18).

With the lighting ``L_lm`` (band energies ``E^L_l = sum_m |L_lm|^2``, total ``L_tot = int L^2``) and the lobe's
per-view spectrum (``relight.shrm.view_spectrum``: ``K_l(theta_o)``, the total ``K(theta_o)`` and what an SHRM at
(F, P) misses in band l, ``D^P_l(theta_o)``), the output at one view, averaged over every orientation of the
lighting relative to the lobe's centre (Parseval over the rotation group, ``int D^l D^l* = 8 pi^2 / (2l + 1)``),
has energy ``sum_l Lambda_l^2 E^L_l K_l(theta_o)`` (``Lambda_l^2 = 4 pi / (2l + 1)``, as in
``relight.shrm.creation.predicted_errors``) and the SHRM's error there has energy

    e(theta_o) = sum_{l <= F} Lambda_l^2 E^L_l D^P_l(theta_o) + sum_{l > F} Lambda_l^2 E^L_l K_l(theta_o).

A band's relative RMS is ``sqrt(int_band e / int_band energy)`` over ``d cos theta_o`` (the texels of a global
reflection map, eq. 12, whose view cosine falls in the band). The figures per band:

* ``rms_average`` — the estimate of that orientation average: the sums run to ``L* = min(F_spectrum, lighting
  order)`` with the lighting's own band energies; beyond L* the lighting's level ``Lambda_l^2 E^L_l`` is continued
  flat at its mean over ``L*/2 < l <= L*`` (:func:`lighting_level`) and multiplies what the lobe holds beyond L*,
  ``K - sum_{l <= L*} K_l``, in numerator and denominator. Flat, because the brute force the SHRM is measured against
  (and every renderer) integrates the map's pixels as point samples: ``Lambda_l^2 E^L_l = sum_{j,k} w_j w_k
  P_l(cos gamma_jk)`` (``w_k`` a pixel's radiance times its solid angle) does not decay beyond the map's order
  ``H - 1`` but tends to the level ``sum_k w_k^2`` of its single pixels, which a map with point-like lamps reaches
  already below H (city: 45 % of its energy beyond l = 63 at 64 rows). App. B's step (all the lighting's remaining
  energy at ``L* + 1``) had over-predicted city by up to 7 times (``docs/accuracy/grazing.md``); on a smooth map the
  continued level over-estimates a decaying tail, which then meets a lobe that holds little beyond L*;
* ``rms`` — the prediction: ``VIEW_MARGIN`` (1.5) times ``rms_average``. One map seen from a few views samples
  only some orientations of its lighting: on four sample maps at 64 rows the measured band error stayed within
  0.76–1.23 times ``rms_average`` (2400 texels of 100 views per band, jackknife standard errors 3–25 %;
  ``docs/accuracy/grazing.md``), so the margin keeps the prediction above what is measured while staying within
  3 times it (issue 18's test, ``tests/relight/test_view_bands.py``);
* ``rms_appendix_b`` — App. B's bound: ``sum_{l > F}`` replaced by its step at F + 1,
  ``Lambda_{F+1}^2 (L_tot - sum_{l <= F} E^L_l) (K - sum_{l <= F} K_l)``, and the denominator by the
  energy the bands l <= F carry, a lower bound of the true energy (1 when that is 0); never below
  ``rms_average``.

``epsilon_brdf`` per band is the lobe's own uncaptured energy at the view (the lighting white), the quantity the
order search holds to the tolerance (``relight.shrm.order_search``). These are orientation averages: one view of one
map sees one part of the lighting and can differ either way (``docs/accuracy/grazing.md`` measures by how much).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from relight.brdf.coefficients import lambda_l
from relight.reports import Report, ViewBand
from relight.shrm.view_spectrum import ViewSpectrum

FloatArray = NDArray[np.float64]

#: Margin of ``rms`` over the orientation average ``rms_average`` (module docstring).
VIEW_MARGIN = 1.5
#: The bands every report lists (issue 18); the fine bands of ``view_spectrum.FINE_EDGES`` come beside them.
REPORT_BANDS: tuple[tuple[float, float], ...] = ((0.0, 0.3), (0.3, 0.7), (0.7, 1.0))


class Lighting(Protocol):
    """What the prediction reads of the lighting (``relight.prefilter.LightingSpectrum``, a plan's stored one)."""

    @property
    def lmax(self) -> int: ...

    @property
    def total_energy(self) -> float: ...

    def band_energy(self) -> NDArray[np.float64]: ...


def lighting_level(lam2: FloatArray, e_light: FloatArray, l_star: int, l_max: int) -> float:
    """``Lambda_l^2 E^L_l`` continued beyond ``l_star``: its mean over the known bands ``l_star / 2 < l <= l_max``
    (module docstring: a map's pixels keep this level to every order)."""
    lo = l_star // 2 + 1
    n = min(l_max, lam2.size - 1, e_light.size - 1)
    if n < lo:
        return float(lam2[min(n, lam2.size - 1)] * e_light[n]) if n >= 0 else 0.0
    return float(np.mean(lam2[lo : n + 1] * e_light[lo : n + 1]))


def brdf_band_epsilon(spec: ViewSpectrum, p_order: int, f_max: int | None = None, *,
                      k_l: FloatArray | None = None, d_l: FloatArray | None = None) -> FloatArray:
    """The lobe's uncaptured energy fraction per fine band for every F <= f_max at view order P: (F+1, n_bands),
    maximum over colour channels (the lighting white). ``k_l``, ``d_l``: the spectrum's
    ``band_energy_per_view()`` and ``truncation_error_per_view(P)`` when the caller has them."""
    f_max = spec.F if f_max is None else f_max
    k_l = (spec.band_energy_per_view() if k_l is None else k_l)[: f_max + 1]
    d_l = (spec.truncation_error_per_view(p_order) if d_l is None else d_l)[: f_max + 1]
    err = np.cumsum(d_l, axis=0) + np.clip(spec.k_tot[None] - np.cumsum(k_l, axis=0), 0.0, None)
    tot = spec.band_sum(spec.k_tot[None])[0]  # (n_bands, C)
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = np.where(tot[None] > 0.0, spec.band_sum(err) / tot[None], 0.0)
    return np.asarray(eps.max(axis=-1), dtype=np.float64)


def _error_and_output(spec: ViewSpectrum, lighting: Lighting, f_b: int, p_b: int,
                      window: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Per view node (n_o, C): the orientation average's error energy ``e(theta_o)`` of an SHRM at (F_B, P_B) and
    the output energy, both with the flat continuation beyond L* (module docstring, ``rms_average``)."""
    e_light = np.asarray(lighting.band_energy(), dtype=np.float64)
    l_star = min(spec.F, int(lighting.lmax))
    f_b_l = min(f_b, l_star)
    lam2 = lambda_l(max(spec.F, f_b, int(lighting.lmax)) + 1) ** 2
    a = lam2[: l_star + 1] * e_light[: l_star + 1]
    k_l = spec.band_energy_per_view()
    d_l = spec.truncation_error_per_view(p_b, window)
    k_cum = np.cumsum(k_l, axis=0)
    tail = lighting_level(lam2, e_light, l_star, int(lighting.lmax)) * np.clip(spec.k_tot - k_cum[l_star], 0.0, None)
    num = np.einsum("l,loc->oc", a[: f_b_l + 1], d_l[: f_b_l + 1])
    num += np.einsum("l,loc->oc", a[f_b_l + 1 :], k_l[f_b_l + 1 : l_star + 1]) + tail
    den = np.einsum("l,loc->oc", a, k_l[: l_star + 1]) + tail
    return np.asarray(num, dtype=np.float64), np.asarray(den, dtype=np.float64)


def error_and_output_by_band(spec: ViewSpectrum, lighting: Lighting, f_b: int,
                             p_b: int) -> tuple[FloatArray, FloatArray]:
    """Per fine band of ``spec`` (n_bands, C): the error energy an SHRM at (F_B, P_B) makes under ``lighting`` and
    the output energy, integrated over the band's ``d cos theta_o`` (``epsilon`` of :func:`predicted_by_view` is
    their ratio). Energies, not ratios, so that errors of parts of a lighting can be held to one output's energy
    (``relight.planning.sun_orders``)."""
    num, den = _error_and_output(spec, lighting, f_b, p_b)
    return spec.band_sum(num[None])[0], spec.band_sum(den[None])[0]


def _merge(spec: ViewSpectrum, lo: float, hi: float) -> NDArray[np.bool_]:
    e = np.asarray(spec.edges)
    return np.asarray((e[:-1] >= lo - 1e-9) & (e[1:] <= hi + 1e-9))


def predicted_by_view(
    spec: ViewSpectrum,
    lighting: Lighting,
    f_b: int,
    p_b: int,
    *,
    bands: Sequence[tuple[float, float]] | None = None,
    epsilon: float | None = None,
    grazing_limit: float | None = None,
    window: FloatArray | None = None,
) -> list[ViewBand]:
    """The predicted error per band at orders (F_B, P_B) under ``lighting`` (module docstring).

    ``bands`` default to the fine bands of the spectrum; each must be a union of them. ``epsilon`` and
    ``grazing_limit`` fill ``enforced`` and ``met``; ``window`` the factors a ringing window applied to l <= F_B.
    """
    if not (0 <= f_b <= spec.F and 0 <= p_b <= spec.P):
        raise ValueError(f"orders ({f_b}, {p_b}) outside the spectrum's (0..{spec.F}, 0..{spec.P})")
    e_light = np.asarray(lighting.band_energy(), dtype=np.float64)
    l_tot = float(lighting.total_energy)
    l_star = min(spec.F, int(lighting.lmax))
    f_b_l = min(f_b, l_star)
    lam2 = lambda_l(max(spec.F, f_b, int(lighting.lmax)) + 1) ** 2
    a = lam2[: l_star + 1] * e_light[: l_star + 1]
    k_l = spec.band_energy_per_view()  # (F+1, n_o, C)
    d_l = spec.truncation_error_per_view(p_b, window)
    k_cum = np.cumsum(k_l, axis=0)
    e_cum = np.cumsum(e_light[: l_star + 1])
    num, den = _error_and_output(spec, lighting, f_b, p_b, window)

    def step(order: int) -> FloatArray:  # App. B's bound on sum_{l > order} Lambda_l^2 E^L_l K_l, per node
        rest_l = max(l_tot - float(e_cum[min(order, l_star)]), 0.0)
        rest_k = np.clip(spec.k_tot - k_cum[order], 0.0, None)
        return np.asarray(lam2[order + 1] * rest_l * rest_k, dtype=np.float64)

    num_b = np.einsum("l,loc->oc", a[: f_b_l + 1], d_l[: f_b_l + 1]) + step(f_b_l)
    den_b = np.einsum("l,loc->oc", a[: f_b_l + 1], k_l[: f_b_l + 1])
    sums = [spec.band_sum(x[None])[0] for x in (num, den, num_b, den_b)]  # (n_bands, C) each
    eps_brdf = brdf_band_epsilon(spec, p_b, f_b)[f_b]
    k_band = spec.band_sum(spec.k_tot[None])[0].max(axis=-1)
    out = []
    for lo, hi in (bands if bands is not None else list(zip(spec.edges[:-1], spec.edges[1:], strict=True))):
        sel = _merge(spec, lo, hi)
        if not sel.any():
            raise ValueError(f"band [{lo}, {hi}] is not a union of the spectrum's bands {spec.edges}")
        n, d, nb, db = (s[sel].sum(axis=0) for s in sums)
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = float(np.max(np.where(d > 0.0, n / d, 0.0)))
            eps_b = float(np.max(np.where(db > 0.0, nb / db, np.where(nb > 0.0, 1.0, 0.0))))
        eps_b = max(eps_b, eps)
        w = k_band[sel]
        e_rho = float(np.sum(eps_brdf[sel] * w) / np.sum(w)) if np.sum(w) > 0.0 else 0.0
        enforced = None if epsilon is None else bool(grazing_limit is None or lo >= grazing_limit - 1e-9)
        met = None if epsilon is None else bool(e_rho <= epsilon)
        out.append(ViewBand(ndotv=(float(lo), float(hi)), rms=VIEW_MARGIN * math.sqrt(max(eps, 0.0)),
                            rms_appendix_b=math.sqrt(max(eps_b, 0.0)), rms_average=math.sqrt(max(eps, 0.0)),
                            epsilon=eps, epsilon_appendix_b=eps_b,
                            epsilon_brdf=e_rho, enforced=enforced, met=met))
    return out


@dataclass(frozen=True, kw_only=True)
class ViewPrediction(Report):
    """``by_view`` (the report bands) and ``by_view_fine`` (the fine bands) of one SHRM component, and the grazing
    limit the tolerance was held to."""

    by_view: list[ViewBand]
    by_view_fine: list[ViewBand]
    grazing_limit: float | None = None
    notes: dict[str, Any] = field(default_factory=dict)


def view_prediction(spec: ViewSpectrum, lighting: Lighting, f_b: int, p_b: int, *, epsilon: float | None = None,
                    grazing_limit: float | None = None,
                    achievable: Sequence[float] | None = None) -> ViewPrediction:
    """Both band lists of :func:`predicted_by_view`. With a tolerance, a report band is ``enforced`` when one of its
    fine bands is, and ``met`` when all its enforced fine bands are; ``achievable`` (per fine band, from the order
    search) gives ``achievable_epsilon_brdf`` to the enforced bands (a report band: the largest of its own)."""
    fine = predicted_by_view(spec, lighting, f_b, p_b, epsilon=epsilon, grazing_limit=grazing_limit)
    if achievable is not None:
        fine = [replace(b, achievable_epsilon_brdf=float(a)) if b.enforced else b
                for b, a in zip(fine, achievable, strict=True)]
    coarse = predicted_by_view(spec, lighting, f_b, p_b, bands=REPORT_BANDS)
    if epsilon is not None:
        out = []
        for band in coarse:
            inner = [b for b in fine if b.ndotv[0] >= band.ndotv[0] - 1e-9 and b.ndotv[1] <= band.ndotv[1] + 1e-9
                     and b.enforced]
            ach = [b.achievable_epsilon_brdf for b in inner if b.achievable_epsilon_brdf is not None]
            out.append(replace(band, enforced=bool(inner), met=all(b.met for b in inner) if inner else None,
                               achievable_epsilon_brdf=max(ach) if ach else None))
        coarse = out
    return ViewPrediction(by_view=coarse, by_view_fine=fine, grazing_limit=grazing_limit)


def radial_by_view(lobe: Any, lighting: Lighting, f_b: int, *, window: FloatArray | None = None,
                   grazing_limit: float | None = None) -> list[ViewBand]:
    """``by_view`` of a radially symmetric lobe's reflection map (``relight.prefilter``): the lobe does not depend on
    the view, so every band has the same predicted error (the lighting's orientations averaged as for SHRMs)."""
    from relight.shrm.view_spectrum import band_edges, view_spectrum

    spec = view_spectrum(lobe, max(f_b, int(lighting.lmax)), 0, edges=band_edges(grazing_limit))
    return predicted_by_view(spec, lighting, f_b, 0, bands=REPORT_BANDS, window=window)
