"""One elevation of the Gaussian-lobe fit (``relight.sgfit``) as a variable-projection problem (Golub & Pereyra
1973): for fixed (mu, sigma) the weights solve a non-negative least-squares problem (:func:`nnls_gram`); the 2K
nonlinear unknowns (mu_k, log sigma_k) go to ``scipy.optimize.least_squares`` (TRF, bounds) with Kaufman's (1975)
analytic Jacobian ``J = -(I - Q Q^T) (dPhi/dp) w`` (Q: orthonormal basis of the active columns). Lobes are vMF
lobes ``G_sigma(c(mu) . w)`` in the plane of incidence (``docs/conventions.md``; Green et al. 2007 eq. 8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from relight.brdf.vmf import vmf_norm
from relight.conventions import LUMINANCE_WEIGHTS

FloatArray = NDArray[np.float64]

#: Bounds: sigma from 1e-3 rad (0.06 degrees; sharper than any map's pixel) to 1.5 rad; mu within +-pi/2.
SIGMA_LO, SIGMA_HI = 1e-3, 1.5


def basis(local: FloatArray, mu: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """vMF lobes at the nodes (M, K) and their derivatives by mu and by s = log sigma."""
    a, b = local[:, 0:1], local[:, 1:2]
    cm, sm = np.cos(mu)[None, :], np.sin(mu)[None, :]
    t = a * cm + b * sm
    kappa = np.exp(-2.0 * s)[None, :]
    with np.errstate(under="ignore", over="ignore"):
        g = vmf_norm(kappa) * np.exp(kappa * (t - 1.0))
        dlogc = 1.0 / kappa - 2.0 / np.expm1(2.0 * kappa)
    dmu = g * kappa * (b * cm - a * sm)
    ds = g * (dlogc + t - 1.0) * (-2.0 * kappa)
    return g, dmu, ds


def nnls_gram(gram: FloatArray, b: FloatArray) -> FloatArray:
    """Non-negative least squares ``min ||Phi w - y||, w >= 0`` from ``gram = Phi^T Phi`` and ``b = Phi^T y``.

    The optimum is the unconstrained solution on its own support (KKT), so for K <= 6 every support is tried and the
    best feasible one kept (at most 63 K x K solves: far cheaper than an active-set NNLS on the M x K matrix);
    larger K uses ``scipy.optimize.nnls`` on the Cholesky factor.
    """
    k = gram.shape[0]
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    g = gram / np.outer(scale, scale)
    bb = b / scale
    if k > 6:
        ch = np.linalg.cholesky(g + 1e-12 * np.eye(k))
        w, _ = optimize.nnls(ch.T, np.linalg.solve(ch, bb))
        return np.asarray(w / scale, dtype=np.float64)
    best_w, best_c = np.zeros(k), 0.0
    for mask in range(1, 1 << k):
        idx = [j for j in range(k) if mask >> j & 1]
        sub = g[np.ix_(idx, idx)]
        try:
            ws = np.linalg.solve(sub + 1e-13 * np.eye(len(idx)), bb[idx])
        except np.linalg.LinAlgError:
            continue
        if np.any(ws < 0.0):
            continue
        c = -float(ws @ bb[idx])  # cost - y^T y = w^T G w - 2 w^T b = -w^T b at the unconstrained optimum
        if c < best_c:
            best_c, best_w = c, np.zeros(k)
            best_w[idx] = ws
    return np.asarray(best_w / scale, dtype=np.float64)


class VarPro:
    """Residual and Kaufman Jacobian of the variable-projection problem for one elevation (module docstring)."""

    def __init__(self, local: FloatArray, sq: FloatArray, y: FloatArray, k: int, fix_mu: bool) -> None:
        self.local, self.sq, self.y, self.k, self.fix_mu = local, sq, y, k, fix_mu
        self._x: FloatArray | None = None

    def split(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        if self.fix_mu:
            return np.zeros(self.k), x
        return x[: self.k], x[self.k :]

    def _eval(self, x: FloatArray) -> None:
        if self._x is not None and np.array_equal(x, self._x):
            return
        mu, s = self.split(x)
        g, dmu, ds = basis(self.local, mu, s)
        phi = g * self.sq[:, None]
        gram = phi.T @ phi
        w = nnls_gram(gram, phi.T @ self.y)
        self._x = x.copy()
        self.phi, self.gram, self.dmu, self.ds, self.w = phi, gram, dmu, ds, w
        self.res = phi @ w - self.y

    def fun(self, x: FloatArray) -> FloatArray:
        self._eval(x)
        return self.res

    def jac(self, x: FloatArray) -> FloatArray:
        self._eval(x)
        act = self.w > 0.0
        cols = []
        if not self.fix_mu:
            cols.append(self.dmu * (self.w * 1.0)[None, :])
        cols.append(self.ds * self.w[None, :])
        d = np.concatenate(cols, axis=1) * self.sq[:, None]
        if act.any():  # d - Phi_F (Phi_F^T Phi_F)^-1 Phi_F^T d: the projection onto the active columns' complement
            pf = self.phi[:, act]
            coef = np.linalg.lstsq(self.gram[np.ix_(act, act)], pf.T @ d, rcond=None)[0]
            d = d - pf @ coef
        return d


@dataclass
class Solution:
    mu: FloatArray
    s: FloatArray
    w: FloatArray  # luminance weights (K,)
    cost: float


def solve(prob: VarPro, mu0: FloatArray, s0: FloatArray, max_nfev: int) -> Solution:
    lo_s, hi_s = math.log(SIGMA_LO), math.log(SIGMA_HI)
    s0 = np.clip(s0, lo_s + 1e-9, hi_s - 1e-9)
    mu0 = np.clip(mu0, -math.pi / 2 + 1e-9, math.pi / 2 - 1e-9)
    k = prob.k
    if prob.fix_mu:
        x0, lo, hi = s0, np.full(k, lo_s), np.full(k, hi_s)
    else:
        x0 = np.concatenate([mu0, s0])
        lo = np.concatenate([np.full(k, -math.pi / 2), np.full(k, lo_s)])
        hi = np.concatenate([np.full(k, math.pi / 2), np.full(k, hi_s)])
    res = optimize.least_squares(prob.fun, x0, jac=prob.jac, bounds=(lo, hi), method="trf", x_scale="jac",
                                 max_nfev=max_nfev, xtol=1e-8, ftol=1e-9, gtol=1e-9)
    mu, s = prob.split(res.x)
    prob._eval(res.x)
    return Solution(mu=mu.copy(), s=s.copy(), w=prob.w.copy(), cost=float(prob.res @ prob.res))


def peak(local: FloatArray, y: FloatArray, sq: FloatArray) -> tuple[float, float]:
    """In-plane angle (mu) of the largest sample of ``y / sq`` and the width sigma of the mass around it."""
    val = np.where(sq > 0.0, y / np.where(sq > 0.0, sq, 1.0), 0.0)
    j = int(np.argmax(val))
    mu = math.atan2(local[j, 1], local[j, 0])
    mu = float(np.clip(mu, -math.pi / 2 + 1e-6, math.pi / 2 - 1e-6))
    t = local[:, 0] * math.cos(mu) + local[:, 1] * math.sin(mu)
    wt = np.maximum(y, 0.0) * sq
    m = float(wt.sum())
    sig2 = float((wt * (1.0 - t)).sum() / m) if m > 0.0 else 0.1
    return mu, float(np.clip(math.sqrt(max(sig2, SIGMA_LO**2)), SIGMA_LO, SIGMA_HI))


def channel_weights(phi_shape: FloatArray, sq: FloatArray, t: FloatArray) -> FloatArray:
    """Per-channel NNLS weights (K, C) for the fixed shapes phi (M, K) (already scaled by sq)."""
    out = np.zeros((phi_shape.shape[1], t.shape[1]))
    gram = phi_shape.T @ phi_shape
    for c in range(t.shape[1]):
        out[:, c] = nnls_gram(gram, phi_shape.T @ (sq * t[:, c]))
    return out


def relative_error(local: FloatArray, sq: FloatArray, t: FloatArray, mu: FloatArray, s: FloatArray,
                   w: FloatArray) -> float:
    """Relative L2 error over all channels: sqrt(sum_c ||T_c - T~_c||^2 / sum_c ||T_c||^2)."""
    g, _, _ = basis(local, mu, s)
    approx = g @ w  # (M, C)
    num = float(np.sum(((approx - t) * sq[:, None]) ** 2))
    den = float(np.sum((t * sq[:, None]) ** 2))
    return math.sqrt(num / den) if den > 0.0 else (0.0 if num == 0.0 else math.inf)


def luminance(t: FloatArray) -> FloatArray:
    return t[:, 0] if t.shape[1] == 1 else np.asarray(t @ LUMINANCE_WEIGHTS, dtype=np.float64)
