"""In-out BRDF factors as functions for rendering (Mahajan, Tseng & Ramamoorthi 2008, eq. 2) on the hemisphere.

``rho(w_i, w_o) ~ sum_k sigma_k h_k(w_o) g_k(w_i)`` for an isotropic BRDF, from the block SVD of
``relight.factorization`` (docs/conventions.md, "In-out factorization"): the azimuthal block ``B_m`` of the kernel
on Gauss–Legendre nodes ``mu_a`` (weights ``w_a``) has the SVD ``B_m = U S V^T``; each (m, j) gives

    g(mu, phi) = v_j(mu) a_m(phi),   h(mu, phi) = u_j(mu) a_m(phi),   sigma = s_j,
    a_0 = 1 / sqrt(2 pi),  a_m = cos(m phi) / sqrt(pi) and sin(m phi) / sqrt(pi)  (m > 0: two real terms)

with ``v_j(mu_b) = V[b, j] / sqrt(w_b)`` on the nodes. The radial profiles are extended off the nodes by the
Nyström formula (exact for the discretised operator, spectrally accurate in the kernel's smoothness):

    u_j(mu) = (1 / s_j) sum_b C_m(mu, mu_b) sqrt(w_b) V[b, j]
    v_j(mu) = (1 / s_j) sum_a C_m(mu_a, mu) sqrt(w_a) U[a, j]

with ``C_m(mu_o, mu_i) = (2 pi / n_phi) sum_l rho(mu_o, mu_i, phi_l) cos(m phi_l)`` (real: relight's isotropic kernels
are even in phi_i - phi_o), and tabulated at ``N_TABLE`` elevations uniform in theta on [0, pi/2] (uniform in theta
rather than mu: the profiles of m > 0 vary like sin^m theta at the normal, where a uniform mu grid is coarse). The
renderer interpolates linearly in theta, on the CPU (:meth:`InOutFactors.profiles`) and in GLSL
(``web/shaders/inout.vert.glsl``) alike.

Terms are kept in whole pairs (both the cos and the sin term of an (m, j)): the sum over a pair depends on
``phi_i - phi_o`` only, so a truncation to whole pairs is independent of the tangent chosen at each vertex (design
notes §4.5 item 8); the frame used for the transport and the one used for the view need only share the normal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError
from relight.factor_kernel import Kernel, make_grid, make_kernel
from relight.factorization import terms_for

FloatArray = NDArray[np.float64]

#: Samples of each radial profile, uniform in theta on [0, pi/2] (0.35 degree steps: linear interpolation errs by
#: < 1e-4 of a profile's range for the lobes up to Phong s ~ 100 that in-out PRT is meant for, bench/inout_prt.py).
N_TABLE = 257
#: Default quadrature of the factorization (Gauss–Legendre nodes in mu; azimuths n_phi = 2 n_theta).
DEFAULT_N_THETA = 48
#: Most terms a factorization for rendering may keep (per-vertex storage is K x (F+1)^2 numbers).
MAX_TERMS = 256


@dataclass(frozen=True)
class InOutFactors:
    """K real terms of eq. 2 (module docstring): ``sigma`` (K,) descending, azimuthal frequency ``m`` (K,),
    ``parity`` (K,) (0: cos(m phi) or m = 0, 1: sin(m phi)), radial profiles ``g``, ``h`` (K, N_TABLE) on the
    ``theta`` table (azimuthal normalisation included), and what was factored."""

    sigma: FloatArray
    m: NDArray[np.int64]
    parity: NDArray[np.int64]
    g: FloatArray
    h: FloatArray
    theta: FloatArray
    include_cosine: bool
    captured: float  # energy fraction sum_{k<=K} sigma^2 / total of the kernel on the grid
    description: str
    grid: tuple[int, int] = (DEFAULT_N_THETA, 2 * DEFAULT_N_THETA)
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def terms(self) -> int:
        return int(self.sigma.size)

    @property
    def predicted_error(self) -> float:
        """sqrt of the uncaptured kernel energy: the relative L2 error of the K-term BRDF over the hemispheres."""
        return math.sqrt(max(0.0, 1.0 - self.captured))

    def truncated(self, terms: int) -> InOutFactors:
        """The leading ``terms`` terms, rounded up to whole (cos, sin) pairs."""
        k = whole_pairs(self.m, self.parity, terms)
        total = self.meta.get("total_energy", 0.0)
        captured = float(np.sum(self.sigma[:k] ** 2) / total) if total > 0 else 1.0
        return InOutFactors(self.sigma[:k], self.m[:k], self.parity[:k], self.g[:k], self.h[:k], self.theta,
                            self.include_cosine, captured, self.description, self.grid, dict(self.meta))

    def profiles(self, which: str, mu: FloatArray) -> FloatArray:
        """Radial profiles of ``g`` or ``h`` at mu (...), linear in theta on the table; 0 for mu <= 0: (..., K)."""
        prof = self.g if which == "g" else self.h
        mu = np.asarray(mu, dtype=np.float64)
        x = np.arccos(np.clip(mu, 0.0, 1.0)) * ((self.theta.size - 1) / (0.5 * np.pi))
        i0 = np.clip(np.floor(x).astype(np.int64), 0, self.theta.size - 2)
        f = np.where(mu > 0.0, x - i0, np.nan)[..., None]  # below the horizon: masked below
        lo, step = prof.T[i0], (prof.T[1:] - prof.T[:-1])[i0]
        out = lo + step * f
        return np.asarray(np.nan_to_num(out, nan=0.0), dtype=np.float64)

    def azimuthal(self, local: FloatArray) -> FloatArray:
        """``a_m(phi)`` of local directions (..., 3): (..., K) (cos and sin of each distinct m evaluated once)."""
        phi = np.arctan2(local[..., 1], local[..., 0])
        ms, inv = np.unique(self.m, return_inverse=True)
        arg = phi[..., None] * ms
        both = np.concatenate([np.cos(arg), np.sin(arg)], axis=-1)
        return np.asarray(both[..., inv + ms.size * self.parity], dtype=np.float64)

    def evaluate(self, which: str, local: FloatArray) -> FloatArray:
        """``g_k`` or ``h_k`` (without sigma) at local directions (..., 3) (normal +z), 0 below the horizon."""
        loc = np.asarray(local, dtype=np.float64)
        return np.asarray(self.profiles(which, loc[..., 2]) * self.azimuthal(loc), dtype=np.float64)

    def kernel(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        """The K-term kernel ``sum_k sigma_k h_k(w_o) g_k(w_i)`` at local directions (..., 3)."""
        return np.asarray(np.sum(self.sigma * self.evaluate("h", wo) * self.evaluate("g", wi), axis=-1))

    def manifest(self) -> dict[str, Any]:
        return {"terms": self.terms, "captured": self.captured, "predicted_error": self.predicted_error,
                "include_cosine": self.include_cosine,
                "quantity": "f_r cos(theta_i)" if self.include_cosine else "f_r",
                "transport": "SH(V g_k)" if self.include_cosine else "SH(V g_k cos theta_i)",
                "grid": list(self.grid), "table": {"samples": int(self.theta.size), "spacing": "uniform theta"},
                "brdf": self.description, "sigma": [float(s) for s in self.sigma],
                "m": [int(x) for x in self.m], "parity": [int(x) for x in self.parity]}


def whole_pairs(m: NDArray[np.int64], parity: NDArray[np.int64], terms: int) -> int:
    """``terms`` rounded up so that no (cos, sin) pair is split (pairs are adjacent, cos first)."""
    k = max(0, min(int(terms), int(m.size)))
    if 0 < k < m.size and m[k - 1] > 0 and parity[k - 1] == 0:
        k += 1
    return k


def _fourier(kernel: Kernel, mu_o: FloatArray, mu_i: FloatArray, phi: FloatArray, ms: list[int]) -> FloatArray:
    """``C_m(mu_o, mu_i)`` for m in ms: (len(ms), n_o, n_i)."""
    assert kernel.iso is not None
    vals = kernel.iso(mu_o[:, None, None], mu_i[None, :, None], phi[None, None, :])
    spec = np.fft.rfft(np.broadcast_to(vals, (mu_o.size, mu_i.size, phi.size)), axis=-1).real
    return np.asarray(np.moveaxis(spec[..., ms], -1, 0) * (2.0 * np.pi / phi.size), dtype=np.float64)


def build_factors(brdf: Any, *, terms: int | None = None, energy: float = 0.99, include_cosine: bool = True,
                  n_theta: int = DEFAULT_N_THETA, n_phi: int | None = None) -> InOutFactors:
    """The leading in-out factors of an isotropic ``brdf`` (any relight BRDF the block SVD accepts) over the
    hemisphere: ``terms`` of them (rounded up to whole pairs; 0: every term of the grid), or as many as capture
    ``energy`` of the kernel's energy (the paper's 99 % by default; refused above :data:`MAX_TERMS`)."""
    validate.in_range("energy", energy, 0.0, 1.0, lo_open=True, hi_open=True)
    if terms is not None and (isinstance(terms, bool) or not isinstance(terms, int) or terms < 0):
        raise InputError(f"terms must be a non-negative integer, got {terms!r}")
    n_p = 2 * n_theta if n_phi is None else n_phi
    kernel = make_kernel(brdf, domain="hemisphere", include_cosine=include_cosine)
    if not kernel.isotropic:
        raise InputError(f"{kernel.description}: in-out PRT factors isotropic BRDFs (the block SVD); "
                         "anisotropic ones are the SH-table representation's")
    grid = make_grid("hemisphere", n_theta, n_p, "gauss")
    if not kernel.is_even():
        raise InputError(f"{kernel.description}: the kernel is not even in phi_i - phi_o (not reciprocal-isotropic)")
    ms = list(range(n_p // 2 + (0 if n_p % 2 == 0 else 1)))  # m = n_phi / 2 (a lone Nyquist term) left out
    sw = np.sqrt(grid.w_mu)
    blocks = _fourier(kernel, grid.mu, grid.mu, grid.phi, ms) * sw[None, :, None] * sw[None, None, :]
    u, s, vt = np.linalg.svd(blocks)  # (M, n, n), (M, n), (M, n, n)
    total = float(np.sum(s[0] ** 2) + 2.0 * np.sum(s[1:] ** 2))
    order = np.argsort(-s, axis=None, kind="stable")
    mm, jj = np.unravel_index(order, s.shape)
    # real terms: one per m = 0 value, two (cos, sin) per m > 0 value, in descending sigma
    m_terms = np.concatenate([[m] if m == 0 else [m, m] for m in mm]).astype(np.int64)
    j_terms = np.concatenate([[j] if m == 0 else [j, j] for m, j in zip(mm, jj, strict=True)]).astype(np.int64)
    p_terms = np.concatenate([[0] if m == 0 else [0, 1] for m in mm]).astype(np.int64)
    sig = s[m_terms, j_terms]
    if terms is None:
        k = terms_for(sig, total, (energy,))[energy]
    else:
        k = sig.size if terms == 0 else terms
    k = whole_pairs(m_terms, p_terms, min(k, sig.size))
    if terms is None and k > MAX_TERMS:
        raise InputError(f"{kernel.description} needs {k} terms at this energy, more than {MAX_TERMS}: too glossy "
                         "for in-out PRT (the paper's K ~ 2.5 s for Phong); lower the energy or the terms")
    m_terms, j_terms, p_terms, sig = m_terms[:k], j_terms[:k], p_terms[:k], sig[:k]
    theta = np.linspace(0.0, 0.5 * np.pi, N_TABLE)
    mu_t = np.cos(theta)
    used = sorted(set(int(m) for m in m_terms))
    c_out = dict(zip(used, _fourier(kernel, mu_t, grid.mu, grid.phi, used), strict=True))  # C_m(mu_table, mu_b)
    c_in = dict(zip(used, _fourier(kernel, grid.mu, mu_t, grid.phi, used), strict=True))  # C_m(mu_a, mu_table)
    g = np.empty((k, N_TABLE))
    h = np.empty((k, N_TABLE))
    for t in range(k):
        m, j = int(m_terms[t]), int(j_terms[t])
        norm = 1.0 / math.sqrt(2.0 * math.pi) if m == 0 else 1.0 / math.sqrt(math.pi)
        h[t] = norm * (c_out[m] @ (sw * vt[m, j])) / s[m, j]
        g[t] = norm * ((sw * u[m, :, j]) @ c_in[m]) / s[m, j]
    captured = float(np.sum(sig**2) / total) if total > 0 else 1.0
    return InOutFactors(sig, m_terms, p_terms, g, h, theta, include_cosine, captured, kernel.description,
                        (n_theta, n_p), {"total_energy": total, "all_terms": int(s[0].size + 2 * s[1:].size)})
