"""BRDF coefficients ``rho_hat_lpq`` of a lobe (seed 000 App. A, App. C step 1).

Seed 000 (Ramamoorthi & Hanrahan 2002) expands the reparameterised BRDF ``rho_hat(theta_i, theta_o, phi)``
(``rho_hat = rho cos(theta_i)``; angles about the lobe's centre C, §3.1) as (App. A, eq. 13)::

    rho_hat(theta_i, theta_o, phi) = sum_{l,p} sum_{q=0..min(l,p)} U_q rho_hat_lpq f_lq(theta_i) f_pq(theta_o) cos q phi
    rho_hat_lpq = 2 pi int_0^pi int_0^pi int_0^{2 pi} f_lq(theta_i) f_pq(theta_o) sin(theta_i) sin(theta_o) cos(q phi)
                  rho_hat(theta_i, theta_o, phi) dphi dtheta_o dtheta_i

with ``U_0 = 1``, ``U_q = 2`` otherwise, and ``f_lq`` the normalised theta part of ``Y_lq = f_lq(theta) e^{i q phi}``
(orthonormal, Condon–Shortley phase: ``relight.sh.legendre_rows``). Equivalently ``rho_hat = sum_{l,p} sum_{|q| <=
min(l,p)} rho_hat_lpq Y*_lq(theta_i, phi_i) Y_pq(theta_o, phi_o)`` with ``rho_hat_{l,p,-q} = rho_hat_lpq``, so by
Parseval the lobe's energy ``int int rho_hat^2 dw_i dw_o`` splits over (l, p) as
``E_lp = sum_q U_q rho_hat_lpq^2`` (§5.1 "a similar method may be used for analyzing the BRDF").

Algorithm (App. C step 1, the three-step separable evaluation of eq. 13)::

    rho_q(theta_i, theta_o) = 2 pi int_0^{2 pi} rho_hat(theta_i, theta_o, phi) cos(q phi) dphi        (cosine transform)
    rho_pq(theta_i)         = int_0^pi rho_q(theta_i, theta_o) f_pq(theta_o) sin(theta_o) dtheta_o    (Legendre sum)
    rho_hat_lpq             = int_0^pi rho_pq(theta_i) f_lq(theta_i) sin(theta_i) dtheta_i           (Legendre sum)

Tabulation grid (the paper's S_rho x T_rho x T_rho, §5 and §5.2 "S ~ 10 F, T ~ 10 P"):

* ``theta_i``: ``S_rho = max(10 (F + 1), 64)`` Gauss–Legendre nodes in ``cos(theta_i)`` on [-1, 1]. Gauss–Legendre
  integrates ``f_lq f_l'q`` exactly (degree < 2 S_rho) and converges spectrally for smooth lobes; the paper's
  equally spaced lat-long grid (its §5) needs more samples for the same accuracy, hence the choice.
* ``theta_o``: ``T_rho = max(10 P, 24)`` Gauss–Legendre nodes in ``cos(theta_o)`` (a single node for radially
  symmetric lobes, which do not depend on theta_o: exact).
* ``phi``: ``rho_hat`` is even in phi (isotropy), so the cosine transform runs over the midpoints
  ``phi_k = (k + 1/2) pi / N_phi`` of [0, pi] — the periodic trapezoid rule on the ``2 N_phi`` points of the
  circle, spectrally accurate — with ``N_phi = max(5 P, 16)``, i.e. ``T_rho ~ 10 P`` samples of the full circle
  (a single sample for lobes without azimuthal dependence, q = 0 only: exact).

Measured accuracy of this grid (microfacet sigma = 0.1 and 0.3 against a 3x oversampled grid, and against the
brute-force :func:`rho_lpq_direct`; ``tests/relight/test_lpq.py``): about 1e-4 of the largest coefficient, and epsilon
within 2e-4. The floor comes from the jump of rho_hat at the horizon ``N . L = 0`` (e.g. eq. 11 does not vanish
there), which makes every product rule first order; smooth radial lobes (Phong) reach 1e-13.

The order search over these coefficients (App. C) is ``relight.brdf.lpq_search``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from cachetools import LRUCache
from numpy.typing import NDArray

from relight import sh, validate
from relight.brdf.base import Lobe, RadialLobe
from relight.brdf.coefficients import lambda_l, radial_transfer
from relight.brdf.lobe_cache import lobe_cache, lobe_cache_key

FloatArray = NDArray[np.float64]

#: Grid rules (module docstring): samples per order in theta_i (S_rho ~ 10 F) and theta_o / phi (T_rho ~ 10 P).
SAMPLES_PER_ORDER = 10
MIN_THETA_I, MIN_THETA_O, MIN_PHI = 64, 24, 16
#: Lobe evaluations per block (about 100 doubles each inside rho_hat: a few MB, cache friendly).
_CHUNK = 50_000


@dataclass(frozen=True)
class LpqGrid:
    """Tabulation grid of ``rho_hat(theta_i, theta_o, phi)`` with quadrature weights (module docstring).

    ``w_i``, ``w_o`` are Gauss–Legendre weights in ``cos(theta)`` (sum 2); ``w_phi`` integrates over the full
    circle [0, 2 pi) from the half-circle samples of an even function (sum 2 pi).
    """

    theta_i: FloatArray
    w_i: FloatArray
    theta_o: FloatArray
    w_o: FloatArray
    phi: FloatArray
    w_phi: FloatArray

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.theta_i.size, self.theta_o.size, self.phi.size)


@functools.lru_cache(maxsize=64)
def _gauss_cos(n: int) -> tuple[FloatArray, FloatArray]:
    """Gauss–Legendre nodes in cos(theta) as angles (ascending theta) and weights (sum 2); cached (read-only).

    ``scipy.special.roots_legendre`` (asymptotic formulas for large n: O(n), unlike numpy's O(n^3) eigenvalues).
    """
    if n == 1:
        theta, w = np.array([np.pi / 2]), np.array([2.0])
    else:
        from scipy.special import roots_legendre

        x, wx = roots_legendre(n)
        theta, w = np.arccos(x[::-1]), np.asarray(wx[::-1], dtype=np.float64)
    theta.setflags(write=False)
    w.setflags(write=False)
    return theta, w


def tabulation_grid(
    f_order: int,
    p_order: int,
    *,
    radial: bool = False,
    azimuthal: bool = False,
    oversample: float = 1.0,
) -> LpqGrid:
    """The grid for orders (F, P) by the rules of the module docstring (``oversample`` scales every count).

    ``radial``: rho_hat depends on theta_i only (one theta_o node, one phi sample: exact). ``azimuthal``: no phi
    dependence (one phi sample: exact).
    """
    if f_order < 0 or p_order < 0:
        raise ValueError(f"orders must be >= 0, got F={f_order}, P={p_order}")
    validate.positive("oversample", oversample)
    n_i = math.ceil(oversample * max(SAMPLES_PER_ORDER * (f_order + 1), MIN_THETA_I))
    n_o = 1 if radial else math.ceil(oversample * max(SAMPLES_PER_ORDER * p_order, MIN_THETA_O))
    n_phi = 1 if (radial or azimuthal) else math.ceil(oversample * max(SAMPLES_PER_ORDER * p_order // 2, MIN_PHI))
    ti, wi = _gauss_cos(n_i)
    to, wo = _gauss_cos(n_o)
    phi = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    w_phi = np.full(n_phi, 2.0 * np.pi / n_phi)
    return LpqGrid(theta_i=ti, w_i=wi, theta_o=to, w_o=wo, phi=phi, w_phi=w_phi)


def f_table(lmax: int, qmax: int, theta: FloatArray) -> FloatArray:
    """``f_lq(theta)`` (= ``Pbar_lq(cos theta)``, orthonormal, CS phase) as (lmax+1, qmax+1, ntheta); 0 for q > l.

    From the scaled, underflow-free recursion of :func:`relight.sh.legendre_rows` (stable to l ~ 4000).
    """
    out = np.zeros((lmax + 1, qmax + 1, np.size(theta)))
    for l, row in enumerate(sh.legendre_rows(lmax, np.asarray(theta, dtype=np.float64), mmax=qmax)):
        out[l, : row.shape[0]] = row
    return out


@dataclass(frozen=True)
class BRDFCoefficients:
    """``rho_hat_lpq`` of one lobe with its energies (seed 000 eq. 13, §5.1).

    ``rho[l, p, q, c]`` for ``0 <= l <= F``, ``0 <= p <= P``, ``0 <= q <= Q`` (``Q = P``, or 0 for lobes without
    azimuthal dependence), colour channel c; zero where ``q > min(l, p)``. ``total_energy[c] = int int rho_hat^2
    dw_i dw_o`` integrated directly on the tabulation grid.
    """

    rho: FloatArray
    total_energy: FloatArray
    grid_shape: tuple[int, int, int]
    center: str = "R"
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def F(self) -> int:
        return int(self.rho.shape[0] - 1)

    @property
    def P(self) -> int:
        return int(self.rho.shape[1] - 1)

    @property
    def Q(self) -> int:
        return int(self.rho.shape[2] - 1)

    @property
    def channels(self) -> int:
        return int(self.rho.shape[3])

    def band_energy(self) -> FloatArray:
        """``E_lp[c] = sum_q U_q rho_hat_lpq^2`` (Parseval, module docstring), shape (F+1, P+1, C)."""
        u = np.where(np.arange(self.Q + 1) == 0, 1.0, 2.0)
        return np.asarray(np.einsum("lpqc,q->lpc", self.rho**2, u), dtype=np.float64)

    def epsilon_table(self) -> FloatArray:
        """Uncaptured energy fraction ``epsilon(F', P')`` for every F' <= F, P' <= P, max over channels (§5.1)."""
        cum = np.cumsum(np.cumsum(self.band_energy(), axis=0), axis=1)
        tot = self.total_energy[None, None, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = np.where(tot > 0.0, 1.0 - cum / tot, 0.0)
        return np.asarray(np.clip(eps, 0.0, 1.0).max(axis=2), dtype=np.float64)

    def epsilon(self, f_order: int | None = None, p_order: int | None = None) -> float:
        """``epsilon(F', P')`` (defaults: this object's F, P)."""
        f = self.F if f_order is None else f_order
        p = self.P if p_order is None else p_order
        if not (0 <= f <= self.F and 0 <= p <= self.P):
            raise ValueError(f"orders ({f}, {p}) outside the computed range (0..{self.F}, 0..{self.P})")
        return float(self.epsilon_table()[f, p])

    def truncate(self, f_order: int, p_order: int) -> BRDFCoefficients:
        """The coefficients up to (F', P') (same total energy: epsilon keeps its meaning)."""
        if not (0 <= f_order <= self.F and 0 <= p_order <= self.P):
            raise ValueError(f"cannot truncate orders ({self.F}, {self.P}) to ({f_order}, {p_order})")
        q = min(self.Q, p_order)
        return BRDFCoefficients(
            rho=np.ascontiguousarray(self.rho[: f_order + 1, : p_order + 1, : q + 1]),
            total_energy=self.total_energy,
            grid_shape=self.grid_shape,
            center=self.center,
            meta=dict(self.meta),
        )


def as_channels(val: NDArray[Any], shape: tuple[int, ...]) -> FloatArray:
    """rho_hat output as (*shape, C) float64 (grey lobes may return (*shape,) or (*shape, 1))."""
    a = np.asarray(val, dtype=np.float64)
    if a.shape == shape:
        a = a[..., None]
    if a.shape[:-1] != shape:
        raise ValueError(f"rho_hat returned shape {a.shape}, expected {shape} + (channels,)")
    return a


def brdf_coefficients(
    lobe: Lobe,
    f_order: int,
    p_order: int,
    *,
    grid: LpqGrid | None = None,
    oversample: float = 1.0,
    use_symmetry: bool = True,
) -> BRDFCoefficients:
    """``rho_hat_lpq`` for ``l <= F``, ``p <= P`` by the three-step algorithm of seed 000 App. C (eq. 13).

    ``use_symmetry`` honours the lobe's flags: a radially symmetric lobe gets ``rho_hat_l00 = sqrt(4 pi) rho_l``
    from the project's radial quadrature (:func:`_radial_coefficients`; or, with an explicit ``grid``, is tabulated
    over theta_i only) and an azimuthally symmetric one gets q = 0 only (both exact). With ``use_symmetry=False``
    every lobe is treated as a general 3-D BRDF (used by the tests to check the flags). Cost O(S T^2 P) for the
    tabulation and cosine transform, O(P^2 S T) and O(F P^2 S) for the two Legendre sums (App. C).
    """
    if f_order < 0 or p_order < 0:
        raise ValueError(f"orders must be >= 0, got F={f_order}, P={p_order}")
    radial = use_symmetry and bool(lobe.radially_symmetric)
    azimuthal = use_symmetry and bool(lobe.azimuthally_symmetric)
    p_req = p_order
    if radial and isinstance(lobe, RadialLobe) and grid is None:
        return _radial_coefficients(lobe, f_order, p_req)
    if radial:
        p_order = 0  # rho_hat does not depend on theta_o: every p > 0 coefficient is exactly 0 (padded below)
    if grid is None:
        grid = tabulation_grid(f_order, p_order, radial=radial, azimuthal=azimuthal, oversample=oversample)
    qmax = 0 if (radial or azimuthal) else p_order
    n_i, n_o, n_phi = grid.shape
    cos_q = np.cos(np.outer(grid.phi, np.arange(qmax + 1))) * grid.w_phi[:, None]  # (n_phi, Q+1)
    f_o = f_table(p_order, qmax, grid.theta_o)  # (P+1, Q+1, n_o)

    # Steps 1 and 2 by blocks of theta_i: rho_q(theta_i, theta_o), then rho_pq(theta_i); energy alongside.
    rho_pq: FloatArray | None = None
    e_i: FloatArray | None = None
    block = max(1, _CHUNK // max(1, n_o * n_phi))
    for i0 in range(0, n_i, block):
        ti = grid.theta_i[i0 : i0 + block]
        shape = (ti.size, n_o, n_phi)
        vals = as_channels(
            lobe.rho_hat(ti[:, None, None], grid.theta_o[None, :, None], grid.phi[None, None, :]), shape
        )
        if rho_pq is None:
            rho_pq = np.zeros((n_i, p_order + 1, qmax + 1, vals.shape[-1]))
            e_i = np.zeros((n_i, vals.shape[-1]))
        assert e_i is not None
        rho_q = 2.0 * np.pi * np.einsum("iokc,kq->ioqc", vals, cos_q)  # step 1
        rho_pq[i0 : i0 + ti.size] = np.einsum("ioqc,pqo,o->ipqc", rho_q, f_o, grid.w_o)  # step 2
        e_i[i0 : i0 + ti.size] = 2.0 * np.pi * np.einsum("iokc,k,o->ic", vals * vals, grid.w_phi, grid.w_o)
    assert rho_pq is not None and e_i is not None
    total = np.asarray(grid.w_i @ e_i, dtype=np.float64)

    # Step 3: rho_lpq = sum_i w_i f_lq(theta_i) rho_pq(theta_i), one degree at a time (memory O(P^2 S_rho)).
    weighted = rho_pq * grid.w_i[:, None, None, None]
    rho = np.zeros((f_order + 1, p_order + 1, qmax + 1, rho_pq.shape[-1]))
    for l, row in enumerate(sh.legendre_rows(f_order, grid.theta_i, mmax=qmax)):
        nq = row.shape[0]
        rho[l, :, :nq] = np.einsum("qi,ipqc->pqc", row, weighted[:, :, :nq])
    # Exact zeros where q > min(l, p) (f_pq = 0 for q > p already; f_lq = 0 for q > l by construction).
    q_idx = np.arange(qmax + 1)
    rho[:, :, :, :] *= (q_idx[None, None, :] <= np.arange(p_order + 1)[None, :, None])[..., None]
    if p_req > p_order:
        rho = np.concatenate([rho, np.zeros((f_order + 1, p_req - p_order) + rho.shape[2:])], axis=1)
    return BRDFCoefficients(
        rho=rho,
        total_energy=total,
        grid_shape=grid.shape,
        center=str(lobe.center),
        meta={"radial": radial, "azimuthal": azimuthal},
    )


def _radial_coefficients(lobe: RadialLobe, f_order: int, p_order: int) -> BRDFCoefficients:
    """Radially symmetric lobes: ``rho_hat_l00 = sqrt(4 pi) rho_l`` from ``relight.brdf.coefficients``.

    Notes
    -----
    For ``rho_hat = u(cos theta_i)`` eq. 13 factorises: the phi integral gives 2 pi, the theta_o integral
    ``int f_00 sin = 2 / sqrt(4 pi)``, so ``rho_hat_l00 = 2 pi * 2 pi * 2 / sqrt(4 pi) int u f_l0 sin dtheta_i =
    sqrt(4 pi) rho_l`` with ``rho_l = 2 pi int u Ybar_l0`` the radial coefficient, ``Lambda_l rho_l`` its transfer
    factor (``radial_transfer``, composite Gauss–Legendre graded into the clamp at theta = pi/2, where a kink like
    Lambert's max(t, 0) defeats a global rule). Energies: ``int int rho_hat^2 = 4 pi int u^2 dOmega``.
    """
    spec = radial_transfer(lobe, f_order)
    rho = np.zeros((f_order + 1, p_order + 1, 1, spec.transfer.shape[1]))
    rho[:, 0, 0, :] = np.sqrt(4.0 * np.pi) * spec.transfer / lambda_l(f_order)[:, None]
    return BRDFCoefficients(
        rho=rho,
        total_energy=np.asarray(4.0 * np.pi * spec.total_energy, dtype=np.float64),
        grid_shape=(0, 1, 1),
        center=str(lobe.center),
        meta={"radial": True, "azimuthal": True, "source": "relight.brdf.coefficients.radial_transfer"},
    )


def rho_lpq_direct(lobe: Lobe, indices: list[tuple[int, int, int]], *, n: int = 100) -> FloatArray:
    """Plain reference: eq. 13 summed literally for the given (l, p, q) (seed 000 App. A), shape (len, channels).

    Midpoint rule with ``n`` points in theta_i and theta_o on [0, pi] and ``2 n`` in phi on [0, 2 pi), and
    ``f_lq(theta) = Y_lq(theta, 0)`` from ``scipy.special.sph_harm_y`` — independent of the grid, the Legendre
    recursion and the cosine transform of :func:`brdf_coefficients`. O(n^3) lobe evaluations: for tests at low
    orders. (Both rules converge only as O(1/n) for lobes cut off at the horizon N.L = 0, a jump in rho_hat.)
    """
    from scipy.special import sph_harm_y

    for l, p, q in indices:
        if not (0 <= q <= min(l, p)):
            raise ValueError(f"need 0 <= q <= min(l, p), got l={l}, p={p}, q={q}")
    t = (np.arange(n) + 0.5) * np.pi / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    sin_dt = np.sin(t) * (np.pi / n)
    vals = np.stack(
        [as_channels(lobe.rho_hat(np.full((n, 2 * n), ti), t[:, None], ph[None, :]), (n, 2 * n)) for ti in t]
    )  # (n_i, n_o, n_phi, C)
    out = []
    for l, p, q in indices:
        ki = np.real(sph_harm_y(l, q, t, 0.0)) * sin_dt
        ko = np.real(sph_harm_y(p, q, t, 0.0)) * sin_dt
        kp = np.cos(q * ph) * (np.pi / n)
        out.append(2.0 * np.pi * np.einsum("iokc,i,o,k->c", vals, ki, ko, kp))
    return np.asarray(out, dtype=np.float64)


# ------------------------------------------------------------------------------------------------- caching
#: BRDF coefficients depend on the lobe only, not on the lighting (App. C: "not the dominant cost"); a small
#: in-process cache keyed by the lobe's canonical spec lets repeated prefilters skip step 1.
_coeff_cache: LRUCache[str, BRDFCoefficients] = lobe_cache()


def cached_coefficients(lobe: Lobe, f_order: int, p_order: int) -> tuple[BRDFCoefficients, bool]:
    """:func:`brdf_coefficients` through the cache; returns (coefficients, whether it was a cache hit)."""
    key = lobe_cache_key(lobe, f_order, p_order)
    if key is not None and key in _coeff_cache:
        return _coeff_cache[key], True
    coeffs = brdf_coefficients(lobe, f_order, p_order)
    if key is not None:
        _coeff_cache[key] = coeffs
    return coeffs, False
