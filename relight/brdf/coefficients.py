"""Spherical-harmonic coefficients of radially symmetric lobes (seed 000 §3.1, §6.3, App. A, App. D).

For a lobe ``rho_hat = u(C . L)`` the reflected radiance is the spherical convolution
``B(C) = int L(w) u(C . w) dw``, and in frequency space (seed 000 eq. 5 with P = 0)

    B_lm = Lambda_l rho_l L_lm,    Lambda_l = sqrt(4 pi / (2l + 1)),

where ``rho_l`` is the coefficient of ``Y_l0`` in the expansion of u about +z:
``rho_l = 2 pi int_{-1}^{1} u(t) Ybar_l0(t) dt`` with ``Ybar_l0 = sqrt((2l+1)/(4 pi)) P_l``. Hence the transfer
factor actually used is

    Lambda_l rho_l = 2 pi int_{-1}^{1} u(t) P_l(t) dt.

``radial_transfer`` computes it by composite Gauss–Legendre quadrature in theta (panels sized to both the lobe width
and the oscillation of P_l, split at the clamp theta = pi/2); ``phong_transfer`` and ``lambert_transfer`` are the
closed forms used to check it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import RadialLobe
from relight.errors import InputError

FloatArray = NDArray[np.float64]

_GL_NODES = 16  # Gauss–Legendre points per panel
#: Most (order + 1) x node products one radial transfer may take: 2^31 multiply-adds of Bonnet's recursion, about a
#: minute of one core. A lobe1d table with a 1e-5 rad peak at order 4096 asks for 2.5e10 (and, computed whole, a
#: 190 GiB Legendre table); such a request is refused before anything is allocated.
MAX_QUADRATURE_WORK = 1 << 31
#: Nodes per block when the Legendre table is built block by block: (order + 1) x this many float64 at a time
#: (32 MiB at order 1023), whatever the node count.
_NODE_BLOCK = 4096


def legendre_p(lmax: int, t: FloatArray) -> FloatArray:
    """Unnormalised Legendre polynomials P_0..P_lmax at t, shape (lmax+1,) + t.shape.

    Bonnet's recursion ``l P_l = (2l - 1) t P_{l-1} - (l - 1) P_{l-2}`` is stable for |t| <= 1.
    """
    t = np.asarray(t, dtype=np.float64)
    out = np.empty((lmax + 1,) + t.shape)
    out[0] = 1.0
    if lmax >= 1:
        out[1] = t
    for l in range(2, lmax + 1):
        out[l] = ((2 * l - 1) * t * out[l - 1] - (l - 1) * out[l - 2]) / l
    return out


def lambda_l(lmax: int) -> FloatArray:
    """``Lambda_l = sqrt(4 pi / (2l + 1))`` (seed 000, Table 1)."""
    l = np.arange(lmax + 1)
    return np.asarray(np.sqrt(4.0 * np.pi / (2.0 * l + 1.0)), dtype=np.float64)


def lobe_width(lobe: RadialLobe) -> float:
    """Angle (radians) from the centre at which the lobe's peak-normalised magnitude first drops below 1e-2.

    Used only to size quadrature panels; computed on a grid dense near theta = 0.
    """
    theta = np.concatenate([np.geomspace(1e-5, 0.05, 200), np.linspace(0.05, np.pi, 600)])
    mag = np.abs(lobe.u(np.cos(theta))).max(axis=-1)
    peak = mag.max()
    if not np.isfinite(peak) or peak <= 0.0:
        return float(np.pi)
    above = np.nonzero(mag >= 1e-2 * peak)[0]
    return float(theta[above[-1]]) if above.size else float(np.pi)


def _theta_nodes(lmax: int, width: float) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss–Legendre nodes and weights on [0, pi] (integrand in theta, weight includes sin theta)."""
    h = min(np.pi / (2.0 * (lmax + 2)), max(width, 1e-4) / 12.0, np.pi / 64)
    n_half = int(np.ceil((np.pi / 2) / h))
    upper = np.linspace(0.0, np.pi / 2, n_half + 1)
    # Geometric grading into the clamp at theta = pi/2 from both sides, where max(t, 0)^s has an endpoint
    # singularity for non-integer s (t^s ~ (pi/2 - theta)^s): 40 halvings reach 1e-12 of a panel.
    graded = np.pi / 2 - (upper[-1] - upper[-2]) * 0.5 ** np.arange(1, 41)
    lower_half = np.pi - upper[::-1]
    edges = np.unique(np.concatenate([upper, graded, np.pi - graded, lower_half]))
    x, w = np.polynomial.legendre.leggauss(_GL_NODES)
    a, b = edges[:-1, None], edges[1:, None]
    nodes = 0.5 * (b - a) * x[None, :] + 0.5 * (b + a)
    weights = 0.5 * (b - a) * w[None, :] * np.sin(nodes)
    return nodes.ravel(), weights.ravel()


def quadrature_nodes(lmax: int, width: float) -> int:
    """How many nodes :func:`_theta_nodes` makes for this order and lobe width, computed without making them."""
    h = min(np.pi / (2.0 * (lmax + 2)), max(width, 1e-4) / 12.0, np.pi / 64)
    n_half = int(np.ceil((np.pi / 2) / h))
    return (2 * (n_half + 40)) * _GL_NODES  # two halves of n_half panels and 40 graded ones each (upper bound)


@dataclass(frozen=True)
class RadialSpectrum:
    """Transfer factors and energies of a radial lobe.

    ``transfer[l, c] = Lambda_l rho_l`` (what multiplies L_lm); ``band_energy[l, c] = rho_l^2`` (the lobe's energy
    in band l, Parseval); ``total_energy[c] = int u^2 dOmega``.
    """

    transfer: FloatArray
    band_energy: FloatArray
    total_energy: FloatArray

    @property
    def lmax(self) -> int:
        return int(self.transfer.shape[0] - 1)

    def epsilon(self) -> FloatArray:
        """Energy fraction not captured by orders 0..F, for every F (max over channels), shape (lmax+1,)."""
        cum = np.cumsum(self.band_energy, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = 1.0 - cum / self.total_energy[None, :]
        eps = np.where(self.total_energy[None, :] > 0.0, eps, 0.0)
        return np.asarray(np.clip(eps, 0.0, 1.0).max(axis=1), dtype=np.float64)


def radial_transfer(lobe: RadialLobe, lmax: int) -> RadialSpectrum:
    """``Lambda_l rho_l`` for l = 0..lmax by quadrature, with the lobe's band and total energies."""
    validate.at_least("lmax", lmax, 0)
    closed = getattr(lobe, "closed_form_transfer", None)  # closed forms (relight.brdf.vmf) skip the quadrature
    if callable(closed):
        tr = np.asarray(closed(lmax), dtype=np.float64)
        rho_c = tr / lambda_l(lmax)[:, None]
        return RadialSpectrum(transfer=tr, band_energy=rho_c * rho_c,
                              total_energy=np.asarray(lobe.total_energy(), dtype=np.float64))  # type: ignore[attr-defined]
    width = lobe_width(lobe)
    n_nodes = quadrature_nodes(lmax, width)
    if (lmax + 1) * n_nodes > MAX_QUADRATURE_WORK:
        raise InputError(f"the lobe is too narrow for order {lmax}: its width {width:.3g} rad needs {n_nodes} "
                         f"quadrature nodes, {(lmax + 1) * n_nodes:.3g} Legendre values in all (the limit is "
                         f"{MAX_QUADRATURE_WORK:.3g}); widen the lobe or lower the order")
    theta, w = _theta_nodes(lmax, width)
    t = np.cos(theta)
    u = np.asarray(lobe.u(t), dtype=np.float64)  # (N, C)
    if u.ndim == 1:
        u = u[:, None]
    transfer = np.zeros((lmax + 1, u.shape[1]))
    for start in range(0, t.size, _NODE_BLOCK):  # the (lmax+1, N) table block by block: bounded memory
        block = slice(start, start + _NODE_BLOCK)
        transfer += (legendre_p(lmax, t[block]) * w[None, block]) @ u[block]
    transfer *= 2.0 * np.pi
    lam = lambda_l(lmax)[:, None]
    rho = transfer / lam
    total = 2.0 * np.pi * (w @ (u * u))
    return RadialSpectrum(transfer=transfer, band_energy=rho * rho, total_energy=np.asarray(total, dtype=np.float64))


def spectrum_for_tolerance(lobe: RadialLobe, epsilon: float, *, lmax_cap: int = 4096) -> tuple[RadialSpectrum, int]:
    """Smallest order F with the lobe's uncaptured energy <= epsilon (seed 000 §5.1), and a spectrum reaching F.

    The probe order doubles until the tolerance is met or ``lmax_cap`` is reached (then F = lmax_cap).
    """
    validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    probe = max(16, int(np.ceil(4.0 / max(lobe_width(lobe), 1e-3))))
    while True:
        probe = min(probe, lmax_cap)
        spec = radial_transfer(lobe, probe)
        ok = np.nonzero(spec.epsilon() <= epsilon)[0]
        if ok.size:
            return spec, int(ok[0])
        if probe >= lmax_cap:
            return spec, lmax_cap
        probe *= 2


def phong_transfer(s: float, lmax: int) -> FloatArray:
    """Closed form of ``Lambda_l rho_l`` for normalised Phong ``(s+1)/(2 pi) max(t,0)^s``.

    Notes
    -----
    ``Lambda_l rho_l = (s + 1) I_l`` with ``I_l = int_0^1 t^s P_l(t) dt``; ``I_0 = 1/(s+1)``, ``I_1 = 1/(s+2)``,
    and ``I_l = (s - l + 2) / (s + l + 1) I_{l-2}`` (from Bonnet's recursion and integration by parts;
    Ramamoorthi & Hanrahan 2001, "A signal-processing framework for inverse rendering", App.).
    """
    out = np.empty(lmax + 1)
    out[0] = 1.0
    if lmax >= 1:
        out[1] = (s + 1.0) / (s + 2.0)
    for l in range(2, lmax + 1):
        out[l] = out[l - 2] * (s - l + 2.0) / (s + l + 1.0)
    return out


def lambert_transfer(lmax: int) -> FloatArray:
    """Closed form ``A_l / pi`` for the albedo-1 Lambertian lobe ``max(t, 0) / pi`` (Ramamoorthi & Hanrahan 2001a).

    ``A_0 = pi``, ``A_1 = 2 pi / 3``, ``A_l = 0`` for odd l > 1, and for even l
    ``A_l = 2 pi (-1)^{l/2 - 1} / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2)``.
    """
    from math import lgamma

    out = np.zeros(lmax + 1)
    out[0] = 1.0
    if lmax >= 1:
        out[1] = 2.0 / 3.0
    for l in range(2, lmax + 1, 2):
        log_binom = lgamma(l + 1) - l * np.log(2.0) - 2.0 * lgamma(l // 2 + 1)
        out[l] = 2.0 * (-1.0) ** (l // 2 - 1) / ((l + 2.0) * (l - 1.0)) * np.exp(log_binom)
    return out


def window_factors(lmax: int, kind: str) -> FloatArray:
    """Optional ringing-control window sigma_l over l = 0..lmax (multiplies the transfer factors).

    ``none``: 1. ``hann``: ``0.5 (1 + cos(pi l / (lmax + 1)))``. ``lanczos``: Lanczos sigma factors
    ``sinc(l / (lmax + 1))`` (Lanczos 1956; the classical Gibbs-damping choice).
    """
    l = np.arange(lmax + 1, dtype=np.float64)
    if kind == "none":
        return np.ones(lmax + 1)
    if kind == "hann":
        return np.asarray(0.5 * (1.0 + np.cos(np.pi * l / (lmax + 1))), dtype=np.float64)
    if kind == "lanczos":
        return np.asarray(np.sinc(l / (lmax + 1)), dtype=np.float64)
    raise ValueError(f"unknown window {kind!r}; use 'none', 'hann' or 'lanczos'")


def kernel_on_grid(transfer: FloatArray, t: FloatArray) -> FloatArray:
    """The band-limited lobe ``u_F(t) = sum_l (2l+1)/(4 pi) (Lambda_l rho_l) P_l(t)``, shape t.shape + (C,).

    ``B(C) = int L(w) u_F(C . w) dw`` is what an order-F prefilter computes (addition theorem).
    """
    lmax = transfer.shape[0] - 1
    p = legendre_p(lmax, t)
    l = np.arange(lmax + 1)
    coef = (2.0 * l + 1.0)[:, None] / (4.0 * np.pi) * transfer
    return np.asarray(np.tensordot(p, coef, axes=(0, 0)), dtype=np.float64)


def ringing_minimum(transfer: FloatArray) -> FloatArray:
    """Most negative value of the band-limited lobe u_F (0 if it stays non-negative), per channel.

    For a non-negative environment and positive quadrature weights, every output texel satisfies
    ``B >= min(u_F, 0) * int L dOmega`` (Gibbs ringing bound).
    """
    lmax = transfer.shape[0] - 1
    n = 16 * (lmax + 1) + 256  # >= 16 samples per oscillation of P_lmax
    theta = np.linspace(0.0, np.pi, n)
    vals = kernel_on_grid(transfer, np.cos(theta))
    out = np.zeros(transfer.shape[1])
    for c in range(transfer.shape[1]):
        k = int(np.argmin(vals[:, c]))
        best = float(vals[k, c])
        lo, hi = theta[max(k - 1, 0)], theta[min(k + 1, n - 1)]
        for _ in range(3):  # zoom into the bracket of the sampled minimum: the error shrinks ~ 1/400 each pass
            fine = np.linspace(lo, hi, 201)
            fv = kernel_on_grid(transfer[:, c : c + 1], np.cos(fine))[:, 0]
            j = int(np.argmin(fv))
            best = min(best, float(fv[j]))
            lo, hi = fine[max(j - 1, 0)], fine[min(j + 1, fine.size - 1)]
        out[c] = min(best, 0.0)
    return out
