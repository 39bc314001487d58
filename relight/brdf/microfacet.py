"""Microfacet BRDFs (seed 000 eq. 11, §6.3; Torrance & Sparrow 1967, Cook & Torrance 1982, Walter et al. 2007)
and their term functions: normal distributions (Beckmann, GGX, Blinn–Phong, seed 000's simple form), Smith masking,
Fresnel (Schlick, conductor), and the models built from them (:class:`Microfacet`, :class:`TorranceSparrow`,
:class:`GGX`, :class:`BlinnPhong`). The term functions take cosines and carry the names of their GLSL twins so
that shaders can be checked term by term; conventions as in :mod:`relight.brdf.models`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike

from relight.brdf.base import FloatArray, IsotropicBRDF, dot, reflection_frame
from relight.brdf.params import Color, check_color, check_number
from relight.brdf.params import as_vectors as _as_vectors
from relight.brdf.params import channels as _channels
from relight.brdf.params import unit as _unit
from relight.errors import InputError

# ----------------------------------------------------------------------------------------------- terms


def D_beckmann(cos_h: ArrayLike, alpha: float) -> FloatArray:
    """Beckmann distribution ``exp(-tan^2 th / a^2) / (pi a^2 cos^4 th)``, a = RMS slope (docs/facts.md; Mitsuba 3).

    Walter et al. 2007 eq. 25 (normalised so that ``int D cos(th) dw = 1``); 0 for ``cos_h <= 0``.
    """
    c = np.asarray(cos_h, dtype=np.float64)
    a2 = alpha * alpha
    ok = c > 0.0
    c2 = np.where(ok, c * c, 1.0)
    tan2 = (1.0 - c2) / c2
    return np.where(ok, np.exp(-tan2 / a2) / (np.pi * a2 * c2 * c2), 0.0)


def D_ggx(cos_h: ArrayLike, alpha: float) -> FloatArray:
    """GGX / Trowbridge-Reitz ``a^2 / (pi (cos^2 th (a^2 - 1) + 1)^2)`` (Walter et al. 2007 eq. 33); 0 if cos <= 0."""
    c = np.asarray(cos_h, dtype=np.float64)
    a2 = alpha * alpha
    den = (c * c) * (a2 - 1.0) + 1.0
    return np.where(c > 0.0, a2 / (np.pi * den * den), 0.0)


def _tan_theta(cos_v: FloatArray) -> FloatArray:
    c = np.clip(cos_v, 1e-150, 1.0)  # tan <= 1e150 keeps tan^2 finite
    return np.asarray(np.sqrt(np.maximum(1.0 - c * c, 0.0)) / c, dtype=np.float64)


def G1_smith_beckmann(cos_v: ArrayLike, alpha: float) -> FloatArray:
    """Smith masking for Beckmann, Walter et al. 2007 eq. 27 rational approximation (Mitsuba 3, docs/facts.md).

    With ``a' = 1 / (alpha tan theta)``: 1 if ``a' >= 1.6``, else
    ``(3.535 a' + 2.181 a'^2) / (1 + 2.276 a' + 2.577 a'^2)``; 0 for ``cos_v <= 0``.
    """
    c = np.asarray(cos_v, dtype=np.float64)
    tan = _tan_theta(c)
    with np.errstate(divide="ignore"):
        a = np.where(tan > 0.0, 1.0 / (alpha * np.where(tan > 0.0, tan, 1.0)), np.inf)
    a_f = np.where(np.isfinite(a), a, 0.0)
    rational = (3.535 * a_f + 2.181 * a_f * a_f) / (1.0 + 2.276 * a_f + 2.577 * a_f * a_f)
    return np.where(c > 0.0, np.where(a >= 1.6, 1.0, rational), 0.0)


def G1_smith_ggx(cos_v: ArrayLike, alpha: float) -> FloatArray:
    """Exact Smith masking for GGX ``2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` (Walter et al. 2007 eq. 34)."""
    c = np.asarray(cos_v, dtype=np.float64)
    tan = _tan_theta(c)
    return np.where(c > 0.0, 2.0 / (1.0 + np.sqrt(1.0 + (alpha * tan) ** 2)), 0.0)


def F_schlick(cos_d: ArrayLike, f0: ArrayLike) -> FloatArray:
    """Schlick 1994: ``F0 + (1 - F0)(1 - cos)^5``; shape ``cos_d.shape + shape(f0)``."""
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)
    f = np.asarray(f0, dtype=np.float64)
    w = (1.0 - c) ** 5
    w = w.reshape(w.shape + (1,) * f.ndim)
    return np.asarray(f + (1.0 - f) * w, dtype=np.float64)


def F_conductor(cos_d: ArrayLike, eta: ArrayLike, k: ArrayLike) -> FloatArray:
    """Exact unpolarised Fresnel reflectance of a conductor with complex IOR ``eta + i k`` (per channel).

    Born & Wolf §14.2; as pbrt-v4 ``FrComplex``: with ``sin^2 t = (1 - cos^2 i) / (eta + ik)^2`` and the principal
    ``cos t = sqrt(1 - sin^2 t)``, ``r_s = (cos i - n cos t) / (cos i + n cos t)``,
    ``r_p = (n cos i - cos t) / (n cos i + cos t)``, ``F = (|r_s|^2 + |r_p|^2) / 2``.
    Shape ``cos_d.shape + broadcast(eta, k).shape``.
    """
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)
    n = np.asarray(eta, dtype=np.float64) + 1j * np.asarray(k, dtype=np.float64)
    cc = c.reshape(c.shape + (1,) * n.ndim)
    sin2_t = (1.0 - cc * cc) / (n * n)
    cos_t = np.sqrt(1.0 - sin2_t)
    r_s = (cc - n * cos_t) / (cc + n * cos_t)
    r_p = (n * cc - cos_t) / (n * cc + cos_t)
    return np.asarray(0.5 * (np.abs(r_s) ** 2 + np.abs(r_p) ** 2), dtype=np.float64)


def D_microfacet_simple(theta_h: ArrayLike, sigma: float) -> FloatArray:
    """Seed 000 eq. 11: ``exp(-(theta_h / sigma)^2) / (4 pi sigma^2)`` (already includes the cosine: a rho_hat)."""
    t = np.asarray(theta_h, dtype=np.float64)
    return np.asarray(np.exp(-((t / sigma) ** 2)) / (4.0 * np.pi * sigma * sigma), dtype=np.float64)


def blinn_phong_norm(s: float) -> float:
    """Exact normalisation of ``K cos^s(theta_h)`` for unit albedo at normal incidence (Giesen 2009).

    ``K = (s+2)(s+4) / (8 pi (2^(-s/2) + s))``: at V = N, ``theta_h = theta_L / 2`` and
    ``2 pi K int_0^1 ((1+x)/2)^(s/2) x dx = 1``. RTR 3rd ed. §7.6's ``(s+8)/(8 pi)`` approximates it.
    """
    return float((s + 2.0) * (s + 4.0) / (8.0 * np.pi * (2.0 ** (-s / 2.0) + s)))


def D_blinn_phong(cos_h: ArrayLike, s: float) -> FloatArray:
    """Normalised Blinn-Phong lobe ``K(s) cos^s(theta_h)`` (:func:`blinn_phong_norm`); 0 for ``cos_h <= 0``."""
    c = np.asarray(cos_h, dtype=np.float64)
    return np.where(c > 0.0, blinn_phong_norm(s) * np.maximum(c, 0.0) ** s, 0.0)


# ----------------------------------------------------------------------------------------------- general lobes


class Microfacet(IsotropicBRDF):
    """Seed 000's simplified microfacet model, eq. 11: ``rho_hat = exp(-(theta_h/sigma)^2) / (4 pi sigma^2)``.

    ``theta_h`` is the angle between N and H = normalize(L + V). Eq. 11 is already ``rho_hat`` (BRDF times
    cos(theta_i)), so :meth:`rho_hat` evaluates it directly in the reflection frame (``base.reflection_frame``) with
    the hemisphere restriction N.L > 0 (N.V > 0 holds there by construction); :meth:`f` is ``rho_hat / (N.L)``.
    For small sigma, the integral of rho_hat over L is about 1 at V = N. ``sigma > 0`` (radians).
    """

    kind: ClassVar[str] = "microfacet"

    def __init__(self, sigma: float) -> None:
        self.sigma = check_number("microfacet", "sigma", sigma, lo=0.0, lo_open=True)
        self._given: float = float(sigma)

    def _theta_h(self, L: FloatArray, V: FloatArray, N: FloatArray) -> FloatArray:
        H = _unit(L + V)
        return np.asarray(np.arccos(np.clip(dot(N, H), -1.0, 1.0)), dtype=np.float64)

    def rho_hat(self, theta_i: FloatArray, theta_o: FloatArray, phi: FloatArray) -> FloatArray:
        L, V, N = reflection_frame(theta_i, theta_o, phi)
        ok = (dot(N, L) > 0.0) & (dot(N, V) > 0.0)
        val = D_microfacet_simple(self._theta_h(L, V, N), self.sigma)
        return np.where(ok, val, 0.0)[..., None]

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        wi, wo, n = _as_vectors(wi, wo, n)
        ndl = dot(n, wi)
        val = D_microfacet_simple(self._theta_h(wi, wo, n), self.sigma) / np.where(ndl > 0.0, ndl, 1.0)
        return np.where(ndl > 0.0, val, 0.0)[..., None]

    def params(self) -> dict[str, Any]:
        return {"sigma": self._given}


Distribution = Literal["beckmann", "ggx"]
Fresnel = Literal["none", "schlick", "conductor"]


class TorranceSparrow(IsotropicBRDF):
    """Microfacet reflection ``f_r = D(h) G1(wi) G1(wo) F(wi.h) / (4 cos_i cos_o)`` (Walter et al. 2007 eq. 20).

    ``alpha > 0``: RMS slope for Beckmann (:func:`D_beckmann`, :func:`G1_smith_beckmann`, Walter's rational
    approximation) or the GGX roughness (:func:`D_ggx`, exact :func:`G1_smith_ggx`). ``fresnel``: ``"none"``
    (F = 1: with Beckmann this is exactly Mitsuba 3's ``roughconductor`` with ``material="none"``, docs/facts.md),
    ``"schlick"`` with ``f0`` in [0, 1] (grey or RGB), or ``"conductor"`` with complex IOR ``eta + i k`` (eta > 0,
    k >= 0, grey or RGB; :func:`F_conductor`).
    """

    kind: ClassVar[str] = "torrance-sparrow"

    def __init__(
        self,
        alpha: float,
        distribution: str = "beckmann",
        fresnel: str = "none",
        f0: float | Sequence[float] | None = None,
        eta: float | Sequence[float] | None = None,
        k: float | Sequence[float] | None = None,
    ) -> None:
        name = self.kind
        self.alpha = check_number(name, "alpha", alpha, lo=0.0, lo_open=True)
        self._alpha_given = float(alpha)
        if distribution not in ("beckmann", "ggx"):
            raise InputError(f"{name}: distribution must be 'beckmann' or 'ggx', got {distribution!r}")
        if fresnel not in ("none", "schlick", "conductor"):
            raise InputError(f"{name}: fresnel must be 'none', 'schlick' or 'conductor', got {fresnel!r}")
        self.distribution: str = distribution
        self.fresnel: str = fresnel
        self._extra: dict[str, Color] = {}
        self.f0 = self.eta = self.k = np.ones(1)
        if fresnel == "schlick":
            if eta is not None or k is not None:
                raise InputError(f"{name}: eta and k apply only to fresnel='conductor'")
            self.f0, self._extra["f0"] = check_color(name, "f0", 0.04 if f0 is None else f0, lo=0.0, hi=1.0)
        elif fresnel == "conductor":
            if f0 is not None:
                raise InputError(f"{name}: f0 applies only to fresnel='schlick'")
            if eta is None or k is None:
                raise InputError(f"{name}: fresnel='conductor' needs both eta and k")
            self.eta, self._extra["eta"] = check_color(name, "eta", eta, lo=0.0, lo_open=True)
            self.k, self._extra["k"] = check_color(name, "k", k, lo=0.0)
        elif f0 is not None or eta is not None or k is not None:
            raise InputError(f"{name}: f0, eta and k need fresnel='schlick' or 'conductor', got fresnel='none'")
        self.channels = _channels(self.f0, self.eta, self.k)

    def D(self, cos_h: FloatArray) -> FloatArray:
        return D_beckmann(cos_h, self.alpha) if self.distribution == "beckmann" else D_ggx(cos_h, self.alpha)

    def G1(self, cos_v: FloatArray) -> FloatArray:
        if self.distribution == "beckmann":
            return G1_smith_beckmann(cos_v, self.alpha)
        return G1_smith_ggx(cos_v, self.alpha)

    def F(self, cos_d: FloatArray) -> FloatArray:
        c = np.asarray(cos_d, dtype=np.float64)
        if self.fresnel == "schlick":
            return F_schlick(c, self.f0)
        if self.fresnel == "conductor":
            return F_conductor(c, self.eta, self.k)
        return np.ones(c.shape + (1,))

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        wi, wo, n = _as_vectors(wi, wo, n)
        ci, co = dot(n, wi), dot(n, wo)
        h = _unit(wi + wo)
        ok = (ci > 0.0) & (co > 0.0)
        den = 4.0 * np.where(ok, ci * co, 1.0)
        spec = np.where(ok, self.D(dot(n, h)) * self.G1(ci) * self.G1(co) / den, 0.0)
        return np.asarray(spec[..., None] * self.F(dot(wi, h)), dtype=np.float64)

    def params(self) -> dict[str, Any]:
        return {"alpha": self._alpha_given, "distribution": self.distribution, "fresnel": self.fresnel, **self._extra}


class GGX(TorranceSparrow):
    """:class:`TorranceSparrow` with the GGX distribution and exact Smith G1 (Walter et al. 2007 §5.2)."""

    kind: ClassVar[str] = "ggx"

    def __init__(
        self,
        alpha: float,
        fresnel: str = "none",
        f0: float | Sequence[float] | None = None,
        eta: float | Sequence[float] | None = None,
        k: float | Sequence[float] | None = None,
    ) -> None:
        super().__init__(alpha, "ggx", fresnel, f0=f0, eta=eta, k=k)

    def params(self) -> dict[str, Any]:
        out = super().params()
        del out["distribution"]
        return out


class BlinnPhong(IsotropicBRDF):
    """Normalised Blinn-Phong ``f_r = K(s) cos^s(theta_h)`` with Giesen's exact ``K`` (:func:`blinn_phong_norm`).

    Blinn 1977; the normalisation makes the directional albedo exactly 1 at normal incidence (it is
    ``(s+2)(s+4)/(8 pi (2^(-s/2) + s))``, close to the ``(s+8)/(8 pi)`` of Akenine-Möller et al., RTR 3rd ed.
    §7.6, which overshoots unit albedo by ~(s+8)/(s+6)). No Fresnel or shadowing. ``s >= 0``.
    """

    kind: ClassVar[str] = "blinn-phong"

    def __init__(self, s: float) -> None:
        self.s = check_number("blinn-phong", "s", s, lo=0.0)
        self._given = float(s)

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        wi, wo, n = _as_vectors(wi, wo, n)
        return D_blinn_phong(dot(n, _unit(wi + wo)), self.s)[..., None]

    def params(self) -> dict[str, Any]:
        return {"s": self._given}
