"""The normalised spherical Gaussian (von Mises–Fisher lobe) of seed 002 (Green, Kautz & Durand 2007, eq. 3).

The paper's "isotropic Gaussian of standard deviation sigma" is not defined there; relight's definition
(``docs/conventions.md``, "Gaussian lobes") is the normalised von Mises–Fisher density on the sphere

    G_sigma(t) = kappa / (2 pi (1 - exp(-2 kappa))) exp(kappa (t - 1)),   kappa = 1 / sigma^2,   t = cos(gamma),

with ``int G dOmega = 1`` for every sigma; for small sigma it is the planar Gaussian of standard deviation sigma per
axis (``exp(-gamma^2 / (2 sigma^2)) / (2 pi sigma^2)``). Its Legendre (SH transfer) coefficients are closed form:

    Lambda_l rho_l = 2 pi int G P_l dt = I_{l+1/2}(kappa) / I_{1/2}(kappa)

(the Funk–Hecke / Rayleigh expansion of ``exp(kappa t)``; ``I`` the modified Bessel function of the first kind).
Computed with ``scipy.special.ive`` (``I_nu(x) e^{-x}``), whose scaling cancels in the ratio, so neither
overflows for any kappa nor l (from kappa ~ 1e10 on, where ive returns NaN, the asymptote below is exact to
float64) (checked against quadrature and the large-kappa asymptote
``exp(-l (l + 1) / (2 kappa))`` in ``tests/relight/test_vmf.py``). ``VonMisesFisher`` is a ``RadialLobe`` about
R: every radial pipeline (``prefilter_radial``, ``reference_radial``, the planner) accepts it, and
``relight.brdf.coefficients.radial_transfer`` uses the closed form instead of quadrature.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from relight.brdf.base import Center, FloatArray, RadialLobe
from relight.errors import InputError

#: Accepted sigma range in radians: 1e-6 rad (kappa = 1e12, far below any map's pixel) to pi (nearly uniform).
SIGMA_MIN, SIGMA_MAX = 1e-6, math.pi


def check_sigma(sigma: Any, name: str = "sigma") -> float:
    """A finite sigma (radians) in [SIGMA_MIN, SIGMA_MAX]; InputError naming the value otherwise."""
    try:
        s = float(sigma)
    except (TypeError, ValueError):
        raise InputError(f"vmf: {name} must be a number (radians), got {sigma!r}") from None
    if not math.isfinite(s) or not SIGMA_MIN <= s <= SIGMA_MAX:
        raise InputError(f"vmf: {name} must lie in [{SIGMA_MIN:g}, {SIGMA_MAX:.6g}] radians, got {sigma!r}")
    return s


def vmf_norm(kappa: NDArray[np.floating] | float) -> FloatArray:
    """``kappa / (2 pi (1 - exp(-2 kappa)))``; ``1 / (4 pi)`` in the limit kappa -> 0."""
    k = np.asarray(kappa, dtype=np.float64)
    den = -np.expm1(-2.0 * k)
    safe = np.where(k > 0.0, k, 1.0)
    return np.asarray(np.where(k > 0.0, safe / (2.0 * np.pi * np.where(den > 0.0, den, 1.0)), 1.0 / (4.0 * np.pi)))


def vmf(t: NDArray[np.floating], kappa: NDArray[np.floating] | float) -> FloatArray:
    """The normalised lobe ``G(t)`` at ``t = cos(gamma)`` (broadcasts over ``kappa``)."""
    t = np.asarray(t, dtype=np.float64)
    k = np.asarray(kappa, dtype=np.float64)
    with np.errstate(under="ignore"):
        return np.asarray(vmf_norm(k) * np.exp(k * (np.clip(t, -1.0, 1.0) - 1.0)), dtype=np.float64)


def vmf_transfer(kappa: float, lmax: int) -> FloatArray:
    """``Lambda_l rho_l = I_{l+1/2}(kappa) / I_{1/2}(kappa)`` for l = 0..lmax (1 at l = 0), shape (lmax+1,)."""
    from scipy import special  # here, not at the top: parse_brdf loads this module for every CLI run

    if lmax < 0:
        raise ValueError(f"lmax must be >= 0, got {lmax}")
    k = float(kappa)
    l = np.arange(lmax + 1, dtype=np.float64)
    if k < 1e-300:  # the uniform density: only l = 0
        out = np.zeros(lmax + 1)
        out[0] = 1.0
        return out
    with np.errstate(under="ignore"):
        num = special.ive(l + 0.5, k)
        den = special.ive(0.5, k)
    if not (np.isfinite(den) and den > 0.0):
        # scipy's ive returns NaN from kappa ~ 1e10 on: the large-kappa asymptote
        # I_{l+1/2}(k) / I_{1/2}(k) = exp(-l (l + 1) / (2 k)) (1 + O(l^2 / k^2)) agrees to better than 1e-9 there
        return np.asarray(np.exp(-l * (l + 1.0) / (2.0 * k)), dtype=np.float64)
    out = np.asarray(num / den, dtype=np.float64)
    # ive underflows to 0 far beyond the lobe's bandwidth (the true value is below 1e-300 there): keep 0
    return np.where(np.isfinite(out), np.clip(out, 0.0, 1.0), 0.0)


def vmf_energy(kappa: float) -> float:
    """``int G^2 dOmega = 2 pi c^2 (1 - exp(-4 kappa)) / (2 kappa)`` (c = :func:`vmf_norm`); 1/(4 pi) at kappa 0."""
    k = float(kappa)
    if k <= 0.0:
        return 1.0 / (4.0 * np.pi)
    c = float(vmf_norm(k))
    return float(2.0 * np.pi * c * c * (-np.expm1(-4.0 * k)) / (2.0 * k))


def vmf_inner(kappa_a: NDArray[np.floating] | float, kappa_b: NDArray[np.floating] | float) -> FloatArray:
    """``<G_a, G_b> = int G_a G_b dOmega`` for two lobes with the *same* centre (closed form, broadcasts)."""
    ka = np.asarray(kappa_a, dtype=np.float64)
    kb = np.asarray(kappa_b, dtype=np.float64)
    s = ka + kb
    return np.asarray(vmf_norm(ka) * vmf_norm(kb) * 2.0 * np.pi * (-np.expm1(-2.0 * s)) / s, dtype=np.float64)


def sigma_to_kappa(sigma: NDArray[np.floating] | float) -> FloatArray:
    """relight's convention ``kappa = 1 / sigma^2`` (sigma in radians)."""
    s = np.asarray(sigma, dtype=np.float64)
    return np.asarray(1.0 / (s * s), dtype=np.float64)


class VonMisesFisher(RadialLobe):
    """A normalised spherical Gaussian about R: ``weight * G_sigma(R . L)`` (module docstring).

    ``sigma`` in radians (spec ``vmf:sigma=0.1``), ``weight`` the lobe's integral (grey or RGB, >= 0; default 1).
    """

    kind: ClassVar[str] = "vmf"

    def __init__(self, sigma: float, weight: float | list[float] | tuple[float, ...] = 1.0) -> None:
        self.sigma = check_sigma(sigma)
        self.kappa = float(sigma_to_kappa(self.sigma))
        vals = [weight] if isinstance(weight, int | float) else list(weight)
        if len(vals) not in (1, 3):
            raise InputError(f"vmf: weight must be one number or three (RGB), got {len(vals)} values")
        ws = []
        for i, v in enumerate(vals):
            try:
                x = float(v)
            except (TypeError, ValueError):
                raise InputError(f"vmf: weight[{i}] must be a number, got {v!r}") from None
            if not math.isfinite(x) or x < 0.0:
                raise InputError(f"vmf: weight[{i}] must be finite and >= 0, got {v!r}")
            ws.append(x)
        self.weight = np.asarray(ws, dtype=np.float64)
        self.center: Center = "R"
        self.channels = len(ws)

    def u(self, t: FloatArray) -> FloatArray:
        return np.asarray(vmf(np.asarray(t, dtype=np.float64), self.kappa)[..., None] * self.weight, np.float64)

    def transfer(self, lmax: int) -> FloatArray:
        """Closed-form ``Lambda_l rho_l`` per channel, shape (lmax+1, channels)."""
        return np.asarray(vmf_transfer(self.kappa, lmax)[:, None] * self.weight[None, :], dtype=np.float64)

    #: what ``relight.brdf.coefficients.radial_transfer`` calls instead of its quadrature
    closed_form_transfer = transfer

    def total_energy(self) -> FloatArray:
        """``int u^2 dOmega`` per channel (closed form)."""
        return np.asarray(vmf_energy(self.kappa) * self.weight**2, dtype=np.float64)

    def params(self) -> dict[str, Any]:
        w = self.weight.tolist()
        return {"sigma": self.sigma, "weight": w[0] if len(w) == 1 else w}
