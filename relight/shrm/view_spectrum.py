"""A lobe's spectrum per outgoing direction: ``rho_hat_lpq`` and the per-view coefficients ``k_lq(theta_o)``
(seed 000 App. A eq. 13, App. C step 1, §5.1 applied per view; issue 18).

For a fixed outgoing direction ``w_o = (theta_o, phi_o)`` about the lobe's centre C the lobe is a function of the
incident direction only, ``rho_hat(w_i; w_o) = sum_{l,|q|} c_lq(w_o) Y*_lq(w_i)`` with (App. A)

    c_lq(w_o) = sum_p rho_hat_lpq Y_pq(w_o) = k_lq(theta_o) e^{i q phi_o} / (2 pi),
    k_lq(theta_o) = int_0^pi rho_q(theta_i, theta_o) f_lq(theta_i) sin(theta_i) dtheta_i,
    rho_q(theta_i, theta_o) = 2 pi int_0^{2 pi} rho_hat(theta_i, theta_o, phi) cos(q phi) dphi

(App. C's steps 1 and 3 without the theta_o sum; ``sum_p f_pq(t) f_pq(t') = delta(cos t - cos t') / (2 pi)`` gives
the 2 pi). App. C's step 2 is then a quadrature over theta_o of the same values:
``rho_hat_lpq = int k_lq(theta_o) f_pq(theta_o) sin(theta_o) dtheta_o``, and the SHRM truncated at P has, at that
view, ``k^P_lq(theta_o) = 2 pi sum_{p <= P} rho_hat_lpq f_pq(theta_o)``. By Parseval over w_i the lobe's energy at
one view splits over l as ``K_l(theta_o) = sum_q U_q k_lq^2 / (4 pi^2)`` (``U_0 = 1``, ``U_q = 2``), its total
``K(theta_o) = int rho_hat^2 dw_i`` is integrated directly, and what an SHRM at (F, P) misses at that view is
``sum_{l <= F} sum_q U_q (k_lq - k^P_lq)^2 / (4 pi^2) + (K - sum_{l <= F} K_l)``.

One tabulation serves both: ``theta_o`` runs over composite Gauss–Legendre nodes (in ``cos theta_o``) on the view
bands' intervals (:func:`view_nodes`), which tile [0, pi] and crowd the nodes toward grazing views (N.V -> 0 is
theta_o -> pi for an R-centred lobe, where the lobe is cut by the horizon); ``theta_i`` on Gauss–Legendre nodes in
``cos theta_i`` (:data:`SAMPLES_PER_ORDER` per order), ``phi`` on midpoints of [0, pi] (the lobe is even in phi,
``relight.brdf.lpq``). Which N.V a node belongs to depends on the centre: ``N = normalize(R + V)`` gives
``N.V = cos(theta_o / 2)`` about R; ``N.V = cos theta_o`` about N (nodes with N.V < 0 belong to no band: the surface
faces away); about a tangent T (Kajiya–Kay) the convention is ``sin theta_o``, the cosine of V to the plane normal
to T (``docs/conventions.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import sh
from relight.brdf import lpq
from relight.brdf.base import Lobe

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Edges in N.V of the fine view bands (0.1 wide); the grazing limit is added as an edge when it is not one.
FINE_EDGES: tuple[float, ...] = tuple(round(0.1 * i, 1) for i in range(11))
#: Gauss–Legendre nodes in theta_o per band interval (60 for an R-centred lobe: measured against 12 per band,
#: band errors agree to a few per cent of themselves, ``tests/relight/test_view_bands.py``).
NODES_PER_BAND = 6
#: theta_i nodes per order (App. C's S_rho ~ 10 F uses 10; the horizon jump makes every rule first order, and 4
#: per order keeps epsilon within 2e-4 of the 10-per-order grid on the lobes of the tests).
SAMPLES_PER_ORDER = 4
MIN_THETA_I = 64
#: phi midpoints on [0, pi]: ``2 Q + 16`` resolves q <= Q with 16 samples' margin against aliasing.
MIN_PHI = 16
#: Lobe evaluations per tabulation block (as ``relight.brdf.lpq``).
_CHUNK = 50_000


def band_edges(grazing_limit: float | None = None) -> tuple[float, ...]:
    """The fine band edges in N.V, with ``grazing_limit`` added when it is not already an edge."""
    edges = set(FINE_EDGES)
    if grazing_limit is not None and 0.0 < grazing_limit < 1.0:
        edges.add(round(float(grazing_limit), 6))
    return tuple(sorted(edges))


def theta_o_intervals(center: str, lo: float, hi: float) -> list[tuple[float, float]]:
    """The theta_o intervals whose views have ``lo <= N.V <= hi`` for a lobe centred on ``center``."""
    if center == "R":
        return [(2.0 * math.acos(hi), 2.0 * math.acos(lo))]
    if center == "N":
        return [(math.acos(hi), math.acos(lo))]
    if center == "T":
        a, b = math.asin(lo), math.asin(hi)
        return [(a, b), (math.pi - b, math.pi - a)]
    raise ValueError(f"unknown lobe centre {center!r}; expected 'R', 'N' or 'T'")


def ndotv(center: str, theta_o: FloatArray) -> FloatArray:
    """N.V of the views at ``theta_o`` about the centre (module docstring; negative: facing away)."""
    t = np.asarray(theta_o, dtype=np.float64)
    if center == "R":
        return np.asarray(np.cos(t / 2.0), dtype=np.float64)
    if center == "N":
        return np.asarray(np.cos(t), dtype=np.float64)
    if center == "T":
        return np.asarray(np.sin(t), dtype=np.float64)
    raise ValueError(f"unknown lobe centre {center!r}; expected 'R', 'N' or 'T'")


def view_nodes(center: str, edges: tuple[float, ...], per_band: int = NODES_PER_BAND
               ) -> tuple[FloatArray, FloatArray, IntArray]:
    """theta_o nodes, weights in ``cos theta_o`` (sum 2 over [0, pi]) and band index (-1: no band) per node."""
    x, wx = np.polynomial.legendre.leggauss(per_band)
    pieces: list[tuple[float, float, int]] = []
    for b in range(len(edges) - 1):
        pieces += [(a, c, b) for a, c in theta_o_intervals(center, edges[b], edges[b + 1])]
    if center == "N":  # views behind the surface complete [0, pi] for App. C's theta_o sum
        pieces.append((math.pi / 2, math.pi, -1))
    th, w, band = [], [], []
    for a, c, b in pieces:
        t = 0.5 * (c - a) * x + 0.5 * (c + a)
        th.append(t)
        w.append(0.5 * (c - a) * wx * np.sin(t))
        band.append(np.full(per_band, b))
    order = np.argsort(np.concatenate(th))
    return (np.concatenate(th)[order], np.concatenate(w)[order],
            np.asarray(np.concatenate(band)[order], dtype=np.intp))


@dataclass(frozen=True)
class ViewSpectrum:
    """``rho_hat_lpq`` and ``k_lq(theta_o)`` of one lobe (module docstring).

    ``k[l, q, o, c]`` at the nodes ``theta_o[o]`` (weights ``w_o`` in ``cos theta_o``, band ``band[o]`` of
    ``edges``; -1: none), ``k_tot[o, c] = int rho_hat^2 dw_i``, ``rho[l, p, q, c]``, ``total_energy[c] = int int
    rho_hat^2``. ``f_o[p, q, o] = f_pq(theta_o)``.
    """

    center: str
    edges: tuple[float, ...]
    theta_o: FloatArray
    w_o: FloatArray
    band: IntArray
    k: FloatArray
    k_tot: FloatArray
    rho: FloatArray
    f_o: FloatArray
    total_energy: FloatArray
    grid_shape: tuple[int, int, int]
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def F(self) -> int:
        return int(self.k.shape[0] - 1)

    @property
    def P(self) -> int:
        return int(self.rho.shape[1] - 1)

    @property
    def n_bands(self) -> int:
        return len(self.edges) - 1

    def coefficients(self) -> lpq.BRDFCoefficients:
        """The ``rho_hat_lpq`` as :class:`relight.brdf.lpq.BRDFCoefficients` (same total energy)."""
        return lpq.BRDFCoefficients(rho=self.rho, total_energy=self.total_energy, grid_shape=self.grid_shape,
                                    center=self.center, meta=dict(self.meta))

    def band_energy_per_view(self) -> FloatArray:
        """``K_l(theta_o)`` as (F+1, n_o, C)."""
        u = np.where(np.arange(self.k.shape[1]) == 0, 1.0, 2.0)
        return np.asarray(np.einsum("lqoc,q->loc", self.k**2, u) / (4.0 * np.pi**2), dtype=np.float64)

    def truncation_error_per_view(self, p_order: int, window: FloatArray | None = None) -> FloatArray:
        """``sum_q U_q (k_lq - w_l k^P_lq)^2 / (4 pi^2)`` at P = ``p_order``, (F+1, n_o, C): the l-band energy an
        SHRM with view order P misses at each node (0 <= P <= self.P); ``window`` ``w_l`` (default 1) is a ringing
        window applied to the computed bands (``relight.brdf.coefficients.window_factors``; 0 beyond its length)."""
        if not 0 <= p_order <= self.P:
            raise ValueError(f"P = {p_order} outside 0..{self.P}")
        q = min(p_order, self.k.shape[1] - 1)
        k_p = 2.0 * np.pi * np.einsum("lpqc,pqo->lqoc", self.rho[:, : p_order + 1, : q + 1],
                                      self.f_o[: p_order + 1, : q + 1])
        if window is not None:
            w = np.zeros(self.F + 1)
            n = min(self.F + 1, len(window))
            w[:n] = np.asarray(window, dtype=np.float64)[:n]
            k_p = k_p * w[:, None, None, None]
        diff = self.k.copy()
        diff[:, : q + 1] -= k_p
        u = np.where(np.arange(self.k.shape[1]) == 0, 1.0, 2.0)
        return np.asarray(np.einsum("lqoc,q->loc", diff**2, u) / (4.0 * np.pi**2), dtype=np.float64)

    def band_sum(self, per_view: FloatArray) -> FloatArray:
        """``sum_{o in band} w_o x[..., o, c]`` per band: (..., n_bands, C) from (..., n_o, C)."""
        onehot = (self.band[:, None] == np.arange(self.n_bands)[None, :]).astype(np.float64) * self.w_o[:, None]
        return np.asarray(np.einsum("...oc,ob->...bc", per_view, onehot), dtype=np.float64)

    def truncate(self, f_order: int, p_order: int) -> ViewSpectrum:
        """The spectrum up to (F', P') (same nodes, energies and totals)."""
        if not (0 <= f_order <= self.F and 0 <= p_order <= self.P):
            raise ValueError(f"cannot truncate orders ({self.F}, {self.P}) to ({f_order}, {p_order})")
        q = min(self.k.shape[1] - 1, p_order)
        return ViewSpectrum(
            center=self.center, edges=self.edges, theta_o=self.theta_o, w_o=self.w_o, band=self.band,
            k=np.ascontiguousarray(self.k[: f_order + 1, : q + 1]), k_tot=self.k_tot,
            rho=np.ascontiguousarray(self.rho[: f_order + 1, : p_order + 1, : q + 1]),
            f_o=np.ascontiguousarray(self.f_o[: p_order + 1, : q + 1]), total_energy=self.total_energy,
            grid_shape=self.grid_shape, meta=dict(self.meta),
        )


def _as_channels(val: NDArray[Any], shape: tuple[int, ...]) -> FloatArray:
    a = np.asarray(val, dtype=np.float64)
    if a.shape == shape:
        a = a[..., None]
    if a.shape[:-1] != shape:
        raise ValueError(f"rho_hat returned shape {a.shape}, expected {shape} + (channels,)")
    return a


def theta_i_count(f_order: int, oversample: float = 1.0) -> int:
    """Gauss–Legendre nodes in ``cos theta_i`` for order F (:data:`SAMPLES_PER_ORDER` per order, at least 64)."""
    return math.ceil(oversample * max(SAMPLES_PER_ORDER * (f_order + 1), MIN_THETA_I))


def phi_count(q_order: int, oversample: float = 1.0) -> int:
    """phi midpoints on [0, pi] for azimuthal orders q <= Q (1 for lobes without phi dependence)."""
    return math.ceil(oversample * max(2 * q_order + 16, MIN_PHI))


def view_spectrum(
    lobe: Lobe,
    f_order: int,
    p_order: int,
    *,
    edges: tuple[float, ...] = FINE_EDGES,
    per_band: int = NODES_PER_BAND,
    oversample: float = 1.0,
) -> ViewSpectrum:
    """Tabulate ``rho_hat`` once and return ``k_lq(theta_o)``, ``K(theta_o)`` and ``rho_hat_lpq`` for l <= F, p <= P.

    Radially symmetric lobes do not depend on the view: ``k_l0 = 2 pi sqrt(4 pi) rho_l f_00`` at every node from
    the radial quadrature (``relight.brdf.lpq``'s exact path). Lobes without phi dependence get q = 0 only.
    Cost: ``theta_i_count(F) * n_o * phi_count(Q)`` lobe evaluations (``n_o = per_band`` per band interval).
    """
    if f_order < 0 or p_order < 0:
        raise ValueError(f"orders must be >= 0, got F={f_order}, P={p_order}")
    center = str(lobe.center)
    theta_o, w_o, band = view_nodes(center, edges, per_band)
    n_o = theta_o.size
    if lobe.radially_symmetric:
        coeffs = lpq.brdf_coefficients(lobe, f_order, p_order)
        rho = coeffs.rho
        k0 = 2.0 * np.pi * rho[:, 0, 0, :] / math.sqrt(4.0 * np.pi)  # f_00 = 1 / sqrt(4 pi)
        k = np.broadcast_to(k0[:, None, None, :], (f_order + 1, 1, n_o, rho.shape[-1])).copy()
        k_tot = np.broadcast_to(coeffs.total_energy / (4.0 * np.pi), (n_o, rho.shape[-1])).copy()
        f_o = lpq.f_table(p_order, 0, theta_o)
        return ViewSpectrum(center=center, edges=edges, theta_o=theta_o, w_o=w_o, band=band, k=k, k_tot=k_tot,
                            rho=rho, f_o=f_o, total_energy=coeffs.total_energy, grid_shape=coeffs.grid_shape,
                            meta={"radial": True, "azimuthal": True})
    qmax = 0 if lobe.azimuthally_symmetric else p_order
    n_i = theta_i_count(f_order, oversample)
    n_phi = 1 if lobe.azimuthally_symmetric else phi_count(qmax, oversample)
    theta_i, w_i = lpq._gauss_cos(n_i)
    phi = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    w_phi = np.full(n_phi, 2.0 * np.pi / n_phi)
    cos_q = np.cos(np.outer(phi, np.arange(qmax + 1))) * w_phi[:, None]  # (n_phi, Q+1)

    rho_q: FloatArray | None = None  # (n_i, Q+1, n_o, C)
    e_o: FloatArray | None = None  # (n_o, C): int rho_hat^2 dw_i
    block = max(1, _CHUNK // max(1, n_o * n_phi))
    for i0 in range(0, n_i, block):
        ti = theta_i[i0 : i0 + block]
        shape = (ti.size, n_o, n_phi)
        vals = _as_channels(lobe.rho_hat(ti[:, None, None], theta_o[None, :, None], phi[None, None, :]), shape)
        if rho_q is None:
            rho_q = np.zeros((n_i, qmax + 1, n_o, vals.shape[-1]))
            e_o = np.zeros((n_o, vals.shape[-1]))
        assert e_o is not None
        rho_q[i0 : i0 + ti.size] = 2.0 * np.pi * np.einsum("iokc,kq->iqoc", vals, cos_q)  # App. C step 1
        e_o += np.einsum("iokc,k,i->oc", vals * vals, w_phi, w_i[i0 : i0 + ti.size])
    assert rho_q is not None and e_o is not None
    weighted = rho_q * w_i[:, None, None, None]
    k = np.zeros((f_order + 1, qmax + 1, n_o, rho_q.shape[-1]))
    for l, row in enumerate(sh.legendre_rows(f_order, theta_i, mmax=qmax)):  # App. C step 3, per view
        nq = row.shape[0]
        k[l, :nq] = np.einsum("qi,iqoc->qoc", row, weighted[:, :nq])
    f_o = lpq.f_table(p_order, qmax, theta_o)  # (P+1, Q+1, n_o)
    rho = np.einsum("lqoc,pqo,o->lpqc", k, f_o, w_o)  # App. C step 2 as a quadrature over the view nodes
    rho *= (np.arange(qmax + 1)[None, None, :] <= np.arange(p_order + 1)[None, :, None])[..., None]
    total = np.asarray(2.0 * np.pi * (w_o @ e_o), dtype=np.float64)
    return ViewSpectrum(
        center=center, edges=edges, theta_o=theta_o, w_o=w_o, band=band, k=k, k_tot=e_o, rho=rho, f_o=f_o,
        total_energy=total, grid_shape=(n_i, n_o, n_phi),
        meta={"radial": False, "azimuthal": bool(lobe.azimuthally_symmetric)},
    )
