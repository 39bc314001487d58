"""BRDF interfaces and the reflection-vector reparameterisation (seed 000, §3.1).

Every material is a sum of *lobes*. A lobe knows

* its central direction ``center``: ``"R"`` (the reflection vector; Phong-like and every general isotropic BRDF,
  §3.1) or ``"N"`` (the normal; Lambertian) or ``"T"`` (the tangent; Kajiya–Kay, §7.1). The output maps of a lobe
  are indexed by that direction.
* ``rho_hat(theta_i, theta_o, phi)``: the BRDF times the cosine of the incident angle, expressed in the lobe's own
  parameterisation: ``theta_i`` is the angle between the light L and the centre C, ``theta_o`` between the view V
  and C, and ``phi`` the azimuth between them about C (seed 000 eq. 2 with ``rho_hat = rho cos(theta_i)``).
  Returns shape ``(..., channels)``.
* ``channels``: 1 (grey) or 3 (RGB).

Radially symmetric lobes (``RadialLobe``) depend on ``theta_i`` only, through ``u(cos theta_i)``.
General isotropic BRDFs (``IsotropicBRDF``) define ``f(wi, wo, n)``, the BRDF value f_r for unit vectors
in any common frame; ``rho_hat`` is derived here by the reparameterisation: with C = R = +z,
``N = normalize(R + V)`` (because ``R = 2 (N.V) N - V``), and ``rho_hat = f(L, V, N) max(N.L, 0)``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Center = Literal["R", "N", "T"]


class Lobe(ABC):
    """One lobe of a material (see the module docstring)."""

    #: Short model name used in spec strings (``phong``, ``microfacet`` ...).
    kind: ClassVar[str] = ""
    center: Center = "R"
    channels: int = 1

    @abstractmethod
    def rho_hat(self, theta_i: FloatArray, theta_o: FloatArray, phi: FloatArray) -> FloatArray:
        """BRDF x cos(incident angle) in the lobe's parameterisation, shape (..., channels)."""

    @abstractmethod
    def params(self) -> dict[str, Any]:
        """Canonical parameters (JSON-serialisable); ``{"kind": self.kind, **params()}`` round-trips."""

    #: True when rho_hat depends on theta_i only (P = 0, a plain 2-D reflection map).
    radially_symmetric: ClassVar[bool] = False
    #: True when rho_hat has no azimuthal (phi) dependence (only q = 0 terms).
    azimuthally_symmetric: ClassVar[bool] = False

    def spec(self) -> dict[str, Any]:
        return {"kind": self.kind, **self.params()}


class RadialLobe(Lobe):
    """A 1-D lobe ``rho_hat = u(C . L)`` about its centre (seed 000 §3.1)."""

    radially_symmetric: ClassVar[bool] = True
    azimuthally_symmetric: ClassVar[bool] = True

    @abstractmethod
    def u(self, t: FloatArray) -> FloatArray:
        """The lobe as a function of ``t = cos(theta_i)``, shape ``t.shape + (channels,)``."""

    def rho_hat(self, theta_i: FloatArray, theta_o: FloatArray, phi: FloatArray) -> FloatArray:
        ti, _, _ = np.broadcast_arrays(np.asarray(theta_i, float), theta_o, phi)
        return self.u(np.cos(ti))


class IsotropicBRDF(Lobe):
    """A general isotropic BRDF given by ``f(wi, wo, n)``; reparameterised by R (seed 000 §3.1)."""

    center: Center = "R"

    @abstractmethod
    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        """BRDF value f_r (no cosine) for unit vectors (..., 3); shape (..., channels).

        Callers guarantee ``n . wi > 0`` and ``n . wo > 0``; values elsewhere are ignored.
        """

    def rho_hat(self, theta_i: FloatArray, theta_o: FloatArray, phi: FloatArray) -> FloatArray:
        L, V, N = reflection_frame(theta_i, theta_o, phi)
        ndl = np.einsum("...k,...k->...", N, L)
        ndv = np.einsum("...k,...k->...", N, V)
        ok = (ndl > 0.0) & (ndv > 0.0)
        val = self.f(L, V, N)
        return np.where(ok[..., None], val * np.clip(ndl, 0.0, None)[..., None], 0.0)


def reflection_frame(
    theta_i: FloatArray, theta_o: FloatArray, phi: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Unit L, V and N (..., 3) in the frame where the reflection vector R is +z (seed 000 §3.1).

    L is at (theta_i, phi) and V at (theta_o, 0) about R; N = normalize(R + V).
    """
    ti, to, ph = np.broadcast_arrays(
        np.asarray(theta_i, np.float64), np.asarray(theta_o, np.float64), np.asarray(phi, np.float64)
    )
    sti = np.sin(ti)
    L = np.stack([sti * np.cos(ph), sti * np.sin(ph), np.cos(ti)], axis=-1)
    V = np.stack([np.sin(to), np.zeros_like(to), np.cos(to)], axis=-1)
    N = V + np.array([0.0, 0.0, 1.0])
    nn = np.linalg.norm(N, axis=-1, keepdims=True)
    N = N / np.where(nn > 0.0, nn, 1.0)
    return L, V, N


def dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Dot product over the trailing axis."""
    return np.asarray(np.einsum("...k,...k->...", a, b), dtype=np.float64)
