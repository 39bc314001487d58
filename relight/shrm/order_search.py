"""Orders (F, P) of an SHRM that hold a tolerance in every view band down to a grazing limit, found in about a second
(seed 000 §5.1, App. C order selection per view band; issue 18).

The tolerance ``epsilon`` is the lobe's uncaptured energy fraction (§5.1), here required of every fine view band
(``relight.shrm.view_spectrum``) whose N.V is at least the grazing limit (default 0.1,
:data:`relight.settings.CoreSettings.grazing_limit`): App. C's whole-lobe figure is dominated by the energy of the
few views near N.V = 0 (a Torrance–Sparrow lobe grows as 1 / N.V there) and hid the rim's error (issue 18).

Coarse to fine, one tabulation:

1. ``view_spectrum`` at ``(F0, P_cap)`` (:func:`starting_order`, about 0.1–0.5 s) gives every band's
   ``epsilon_b(F, P)`` for F <= F0 and P <= P_cap at once (``view_bands.brdf_band_epsilon``).
2. Beyond F0 the bands' l-tails are extrapolated with the slowest decay a bounded lobe with a jump has (the horizon
   cut N.L = 0): band energies ``E_l ~ A l^-2``, so the tail beyond F falls as ``T(F) = T(F0) F0 / F``; the share
   ``r`` of the l-band energy near F0 that the view order P misses is assumed to stay (measured over
   ``F0 / 2 < l <= F0``), so ``epsilon_b(F) = pe_b + r T_b + (1 - r) T_b F0 / F`` with floor ``pe_b + r T_b``. A
   smooth lobe's tail falls faster: then the F found is larger than needed, never smaller in the model.
3. Per P the smallest F meeting every enforced band; among the P's the one with the smallest SHRM
   ``(P + 1)^2 (F + 1)^3`` (maps times synthesis work, App. C's O(F P^2 S^2) with S ~ 10 F) within the caps
   (F <= ``f_cap``, P <= ``p_cap``) and the 4 GiB guard of ``relight.shrm.creation``.
4. When no (F, P) within the caps meets some band, the search says so before anything is computed: which bands,
   and the smallest ``epsilon_b`` each can reach within the caps (``achievable``); it then returns the orders that
   reach twice those figures (and the tolerance in every other band) at the least cost.

Searches are cached per lobe, tolerance, limit and caps (``cached_search``) and the spectra per lobe and orders.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from cachetools import LRUCache
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import Lobe
from relight.brdf.coefficients import spectrum_for_tolerance
from relight.brdf.lobe_cache import lobe_cache, lobe_cache_key
from relight.shrm.view_bands import brdf_band_epsilon
from relight.shrm.view_spectrum import ViewSpectrum, band_edges, view_spectrum

FloatArray = NDArray[np.float64]

#: Caps of the search (as ``relight.brdf.lpq_search.select_orders``): F <= 1024, P <= 16.
F_CAP = 1024
P_CAP = 16
#: Largest coefficient-map set an SHRM may need (``relight.shrm.creation.MAX_SHRM_BYTES``; float64 RGB maps).
MAX_SHRM_BYTES = 4 * 2**30
#: Margin on the achievable figures when a band cannot meet the tolerance (step 4): twice the smallest figure a
#: band can reach within the caps is reached at a moderate F (the extrapolated tail falls to the floor as 1 / F),
#: where 1.25 times it drove F to the caps for little gain.
ACHIEVABLE_MARGIN = 2.0


def starting_order(lobe: Lobe) -> int:
    """``F0 = clamp(24 / width, 32, 96)`` with the lobe width of ``relight.brdf.lpq_search.lobe_width`` (twice App. C's
    start: the search reads the l-tail beyond the lobe's bulk)."""
    from relight.brdf.lpq_search import lobe_width

    return int(np.clip(math.ceil(24.0 / max(lobe_width(lobe), 1e-3)), 32, 96))


def shrm_bytes(f_order: int, p_order: int, structure: str, size: int | None = None) -> int:
    """Bytes of the coefficient maps an SHRM at (F, P) holds (float64 RGB, S = ``size`` or S ~ 10 F)."""
    from relight.prefilter import size_for_order

    s = size if size is not None else size_for_order(f_order)
    n_maps = 1 if structure == "radial" else (p_order + 1 if structure == "azimuthal" else (p_order + 1) ** 2)
    return n_maps * s * 2 * s * 3 * 8


@dataclass(frozen=True)
class BandSearch:
    """Result of :func:`search_orders` (module docstring). ``band_epsilon``: each fine band's predicted uncaptured
    energy at (F, P) (``edges``); ``enforced``: the bands held to the tolerance; ``achievable``: the smallest each
    band can reach within the caps; ``unmet``: enforced bands that cannot meet it; ``extrapolated``: F lies beyond
    the tabulated ``spectrum.F`` (step 2)."""

    F: int
    P: int
    epsilon: float
    grazing_limit: float
    met: bool
    edges: tuple[float, ...]
    band_epsilon: tuple[float, ...]
    enforced: tuple[bool, ...]
    achievable: tuple[float, ...]
    unmet: tuple[tuple[float, float], ...]
    extrapolated: bool
    spectrum: ViewSpectrum
    seconds: float
    probes: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """The search for a report: orders, met, the bands that are not, what is achievable, seconds."""
        bands = list(zip(self.edges[:-1], self.edges[1:], strict=True))
        return {
            "F_rho": self.F,
            "P_rho": self.P,
            "epsilon_brdf": max((e for e, on in zip(self.band_epsilon, self.enforced, strict=True) if on),
                                default=0.0),
            "tolerance_met": self.met,
            "grazing_limit": self.grazing_limit,
            "extrapolated": self.extrapolated,
            "unmet_bands": [list(b) for b in self.unmet],
            "achievable_by_view": [
                {"ndotv": list(b), "epsilon_brdf": a} for b, a, on in zip(bands, self.achievable, self.enforced,
                                                                           strict=True) if on],
            "search_seconds": self.seconds,
            "probes": self.probes,
        }


def _band_model(spec: ViewSpectrum, p: int, k_l: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per band at view order P: the table ``epsilon_b(F)`` for F <= F0 (F0+1, nb) and, for step 2, ``pe_b``,
    ``T_b`` (normalised by the band's energy) and ``r_b`` (max over channels folded in at the end). ``k_l`` is
    ``spec.band_energy_per_view()``."""
    d_l = spec.truncation_error_per_view(p)
    table = brdf_band_epsilon(spec, p, k_l=k_l, d_l=d_l)
    f0 = spec.F
    tot = spec.band_sum(spec.k_tot[None])[0]  # (nb, C)
    tail = spec.band_sum(np.clip(spec.k_tot - k_l.sum(axis=0), 0.0, None)[None])[0]
    pe = spec.band_sum(d_l.sum(axis=0)[None])[0]
    lo = f0 // 2 + 1
    near_k = spec.band_sum(k_l[lo:].sum(axis=0)[None])[0]
    near_d = spec.band_sum(d_l[lo:].sum(axis=0)[None])[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t_b = np.where(tot > 0.0, tail / tot, 0.0)
        pe_b = np.where(tot > 0.0, pe / tot, 0.0)
        r_b = np.clip(np.where(near_k > 0.0, near_d / near_k, 1.0), 0.0, 1.0)
    c = np.argmax(pe_b + t_b, axis=-1)  # the channel that is worst at F0
    pick = np.arange(c.size)
    return table, pe_b[pick, c], t_b[pick, c], r_b[pick, c]


def _f_needed(table: FloatArray, pe: FloatArray, t: FloatArray, r: FloatArray, targets: FloatArray,
              on: NDArray[np.bool_]) -> float:
    """Smallest F meeting ``targets`` in the enforced bands (table, then step 2); inf if it cannot."""
    ok = np.nonzero(np.all(table[:, on] <= targets[on], axis=1))[0]
    if ok.size:
        return float(ok[0])
    f0 = table.shape[0] - 1
    need = 0.0
    for b in np.nonzero(on)[0]:
        room = targets[b] - pe[b] - r[b] * t[b]
        if room <= 0.0:
            return math.inf
        need = max(need, (1.0 - r[b]) * t[b] * f0 / room)
    return float(max(math.ceil(need), f0 + 1))


def _extrapolate(table: FloatArray, pe: FloatArray, t: FloatArray, r: FloatArray, f: int) -> FloatArray:
    f0 = table.shape[0] - 1
    if f <= f0:
        return np.asarray(table[f], dtype=np.float64)
    return np.asarray(pe + r * t + (1.0 - r) * t * f0 / f, dtype=np.float64)


def search_orders(
    lobe: Lobe,
    epsilon: float,
    *,
    grazing_limit: float = 0.1,
    f_cap: int = F_CAP,
    p_cap: int = P_CAP,
    structure: str = "general",
    size: int | None = None,
) -> BandSearch:
    """Smallest SHRM orders holding ``epsilon`` in every view band with N.V >= ``grazing_limit`` (module
    docstring). ``structure`` ("radial", "azimuthal", "general") and ``size`` price the maps for the guard."""
    validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    validate.in_range("grazing_limit", grazing_limit, 0.0, 1.0, hi_open=True)
    t0 = time.perf_counter()
    edges = band_edges(grazing_limit)
    lo_edges = np.asarray(edges[:-1])
    on = lo_edges >= grazing_limit - 1e-9
    bands = tuple(zip(edges[:-1], edges[1:], strict=True))
    if lobe.radially_symmetric:  # no view dependence: every band is the whole lobe (seed 000 §3.1)
        radial, f_r = spectrum_for_tolerance(lobe, epsilon)  # type: ignore[arg-type]
        f_r = min(f_r, f_cap)
        spec = view_spectrum(lobe, f_r, 0, edges=edges)
        eps_f = float(radial.epsilon()[min(f_r, radial.lmax)])
        n = len(bands)
        return BandSearch(F=f_r, P=0, epsilon=epsilon, grazing_limit=grazing_limit, met=eps_f <= epsilon,
                          edges=edges, band_epsilon=(eps_f,) * n, enforced=tuple(bool(x) for x in on),
                          achievable=(eps_f,) * n, unmet=() if eps_f <= epsilon else tuple(
                              b for b, x in zip(bands, on, strict=True) if x),
                          extrapolated=False, spectrum=spec, seconds=time.perf_counter() - t0)
    p_top = min(p_cap, P_CAP)
    f0 = min(starting_order(lobe), f_cap)
    spec = cached_spectrum(lobe, f0, p_top, edges)
    k_l = spec.band_energy_per_view()
    models = [_band_model(spec, p, k_l) for p in range(p_top + 1)]

    def feasible_f(p: int) -> int:  # the largest F the caps and the guard allow at P
        f = f_cap
        while f > 0 and shrm_bytes(f, p, structure, size) > MAX_SHRM_BYTES:
            f = int(f * 0.9)
        return f

    f_max = [feasible_f(p) for p in range(p_top + 1)]
    achievable = np.min([_extrapolate(*m, f_max[p]) if f_max[p] > f0 else m[0][: f_max[p] + 1].min(axis=0)
                         for p, m in enumerate(models)], axis=0)
    targets = np.full(len(bands), float(epsilon))
    unmet = on & (achievable > epsilon)
    if unmet.any():
        targets = np.maximum(targets, ACHIEVABLE_MARGIN * achievable)
    best: tuple[float, int, int] | None = None
    for p, m in enumerate(models):
        f = _f_needed(*m, targets, on)
        if f > f_max[p]:
            continue
        cost = (p + 1) ** 2 * (f + 1) ** 3
        if best is None or cost < best[0]:
            best = (cost, int(f), p)
    if best is None:  # no P reaches even the margin: the P whose worst band is best at its largest F
        p = int(np.argmin([np.max((_extrapolate(*m, f_max[q]) / targets)[on]) for q, m in enumerate(models)]))
        best = (0.0, f_max[p], p)
    _, f_sel, p_sel = best
    band_eps = _extrapolate(*models[p_sel], f_sel)
    met = not bool(np.any(band_eps[on] > epsilon))
    return BandSearch(
        F=f_sel, P=p_sel, epsilon=epsilon, grazing_limit=grazing_limit, met=met, edges=edges,
        band_epsilon=tuple(float(x) for x in band_eps), enforced=tuple(bool(x) for x in on),
        achievable=tuple(float(x) for x in achievable),
        unmet=tuple(b for b, x in zip(bands, unmet, strict=True) if x), extrapolated=f_sel > spec.F,
        spectrum=spec, seconds=time.perf_counter() - t0,
        probes=[{"F": spec.F, "P": spec.P, "grid": list(spec.grid_shape)}],
    )


def enforced_epsilon(search: BandSearch, f_order: int, p_order: int) -> float:
    """The worst enforced band's predicted uncaptured energy at (F, P), from the search's own tabulation and its
    step-2 tail model: the figure :func:`search_orders` holds to the tolerance (1.0 below order 0 or beyond the
    tabulated P)."""
    spec = search.spectrum
    if f_order < 0 or p_order < 0 or p_order > spec.P:
        return 1.0
    eps = _extrapolate(*_band_model(spec, p_order, spec.band_energy_per_view()), f_order)
    on = np.asarray(search.enforced, dtype=bool)
    return float(eps[on].max()) if on.any() else 0.0


# ------------------------------------------------------------------------------------------------- caching
# bounded caches keyed by the lobe's spec (relight.brdf.lobe_cache; its clear() empties them)
_spectra: LRUCache[str, ViewSpectrum] = lobe_cache()
_searches: LRUCache[str, BandSearch] = lobe_cache()


def cached_spectrum(lobe: Lobe, f_order: int, p_order: int, edges: tuple[float, ...]) -> ViewSpectrum:
    """:func:`view_spectrum` through a per-lobe cache keyed by the exact orders (the grid depends on F, so a
    truncated larger spectrum would differ in the last digits: results must not depend on what ran before)."""
    key = lobe_cache_key(lobe, f_order, p_order, list(edges))
    if key is not None and key in _spectra:
        return _spectra[key]
    spec = view_spectrum(lobe, f_order, p_order, edges=edges)
    if key is not None:
        _spectra[key] = spec
    return spec


def cached_search(lobe: Lobe, epsilon: float, **kw: Any) -> tuple[BandSearch, bool]:
    """:func:`search_orders` through the cache; returns (search, whether it was a cache hit)."""
    key = lobe_cache_key(lobe, epsilon, sorted(kw.items()))
    if key is not None and key in _searches:
        return _searches[key], True
    res = search_orders(lobe, epsilon, **kw)
    if key is not None:
        _searches[key] = res
    return res, False
