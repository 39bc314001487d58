"""BRDFs with an explicit tangent frame, ``f(wi, wo, frame)`` (seed 003 §3: "any BRDF, isotropic or anisotropic").

Kautz, Sloan & Snyder tabulate the *BRDF product function* ``f*(s, v) = f(s, v) max(0, s . N)`` (§3) in a local
frame that maps the normal to +z and two tangents to x and y (§4). Every BRDF here is a :class:`FrameBRDF`:

* ``f_local(wi, wo)`` — the BRDF value f_r for unit directions (..., 3) in the local frame (x = tangent t,
  y = bitangent b, z = normal n); 0 unless both directions are above the surface. Returns (..., channels).
* ``fcos_local(wi, wo)`` — the product function f*; by default ``f_local * max(0, wi_z)``.
* ``f(wi, wo, frame)`` / ``fcos(wi, wo, frame)`` — the same for world directions and frames (..., 3, 3) whose rows
  are ``(t, b, n)`` (``relight.tangent_frames``): the local directions are ``frame @ w``.
* ``isotropic`` — True when f depends on the frame only through n (the SH table is then 1-D in theta_v, rotated
  about z: ``relight.sh_table``); ``lobe_width`` — a rough angular width (radians) of the lobe about the mirror
  direction, and ``lobe_center`` ("R" or "N"), used only to place quadrature nodes
  (``relight.sh_table.lobe_quadrature``); ``mirror_symmetric`` —
  True when ``f(S wi, S wo) = f(wi, wo)`` for the mirrors S = diag(-1, 1, 1) and diag(1, -1, 1) (every model here
  but Kajiya–Kay), which lets a table compute one quadrant of views (``relight.sh_table.project_views``).

:class:`LobeAdapter` puts every existing relight lobe (``relight.brdf.models``, ``relight.brdf.measured``) behind
this interface with relight's own product function (the integrand of ``relight.reference_view``): an
``IsotropicBRDF`` gives ``f(wi, wo, n) max(0, wi_z)``; a radially symmetric lobe ``u(C . wi)`` about C = N or the
mirror direction R (not clipped at the horizon, as in seed 000); a tangent-centred lobe (Kajiya–Kay) its
``rho_hat`` about C = the frame's tangent t. :class:`FrameSum` is a sum of such terms.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.brdf.base import FloatArray, IsotropicBRDF, Lobe, RadialLobe
from relight.brdf.models import SumBRDF
from relight.errors import InputError

#: Default lobe width hint (radians) for quadrature placement when a model gives none.
DEFAULT_LOBE_WIDTH = 0.3


def local_dirs(frame: ArrayLike, w: ArrayLike) -> FloatArray:
    """Local coordinates ``(t.w, b.w, n.w)`` of world directions w (..., 3) in frames (..., 3, 3)."""
    return np.asarray(np.einsum("...ij,...j->...i", np.asarray(frame, np.float64), np.asarray(w, np.float64)))


def mirror_local(wo: FloatArray) -> FloatArray:
    """The mirror direction of wo about the local normal +z: ``(-x, -y, z)``."""
    return np.asarray(wo * np.array([-1.0, -1.0, 1.0]), dtype=np.float64)


class FrameBRDF(ABC):
    """A BRDF evaluated with an explicit tangent frame (module docstring)."""

    kind: ClassVar[str] = ""
    channels: int = 1
    isotropic: bool = False
    mirror_symmetric: bool = False
    lobe_width: float = DEFAULT_LOBE_WIDTH
    #: Where the quadrature nodes concentrate: "R" (the mirror direction) or "N" (the normal; diffuse lobes).
    lobe_center: str = "R"

    @abstractmethod
    def f_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        """f_r for local unit directions (..., 3); shape (..., channels); 0 unless wi_z > 0 and wo_z > 0."""

    def fcos_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        """The product function ``f* = f max(0, wi_z)`` (local frame), shape (..., channels)."""
        wi = np.asarray(wi, dtype=np.float64)
        return np.asarray(self.f_local(wi, wo) * np.maximum(wi[..., 2], 0.0)[..., None], dtype=np.float64)

    def f(self, wi: ArrayLike, wo: ArrayLike, frame: ArrayLike) -> FloatArray:
        """f_r for world directions (..., 3) and frames (..., 3, 3) with rows (t, b, n)."""
        return self.f_local(local_dirs(frame, wi), local_dirs(frame, wo))

    def fcos(self, wi: ArrayLike, wo: ArrayLike, frame: ArrayLike) -> FloatArray:
        """The product function f* for world directions and frames."""
        return self.fcos_local(local_dirs(frame, wi), local_dirs(frame, wo))

    @abstractmethod
    def params(self) -> dict[str, Any]:
        """Canonical parameters; ``{"kind": kind, **params()}`` parses back (``relight.brdf.spec``)."""

    def spec(self) -> dict[str, Any]:
        return {"kind": self.kind, **self.params()}


def upper(wi: FloatArray, wo: FloatArray) -> NDArray[np.bool_]:
    """Mask (...,) of pairs with both directions strictly above the local surface."""
    return np.asarray((wi[..., 2] > 0.0) & (wo[..., 2] > 0.0), dtype=bool)


class LobeAdapter(FrameBRDF):
    """Any relight :class:`~relight.brdf.base.Lobe` through the frame interface (module docstring)."""

    def __init__(self, lobe: Lobe) -> None:
        if not isinstance(lobe, Lobe):
            raise InputError(f"not a BRDF lobe: {type(lobe).__name__}")
        self.lobe = lobe
        self.channels = int(lobe.channels)
        self.isotropic = lobe.center != "T"
        self.mirror_symmetric = self.isotropic
        self.lobe_center = "N" if lobe.center == "N" else "R"
        self.lobe_width = _width_hint(lobe)

    def _fcos_raw(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        lobe = self.lobe
        z = np.array([0.0, 0.0, 1.0])
        if isinstance(lobe, IsotropicBRDF):
            wi_b, wo_b = np.broadcast_arrays(wi, wo)
            val = np.asarray(lobe.f(wi_b, wo_b, np.broadcast_to(z, wi_b.shape)), dtype=np.float64)
            ok = upper(wi_b, wo_b)
            return np.where(ok[..., None], val * np.maximum(wi_b[..., 2], 0.0)[..., None], 0.0)
        if isinstance(lobe, RadialLobe):
            c = np.broadcast_to(z, wo.shape) if lobe.center == "N" else mirror_local(wo)
            cos_i = np.clip(np.einsum("...k,...k->...", np.broadcast_to(c, np.broadcast_shapes(c.shape, wi.shape)),
                                      wi), -1.0, 1.0)
            return np.asarray(lobe.u(cos_i), dtype=np.float64)
        # general lobe about its centre: rho_hat(theta_i, theta_o, phi) (relight.reference_view's integrand)
        if lobe.center == "T":
            c = np.array([1.0, 0.0, 0.0])
        elif lobe.center == "N":
            c = z
        else:
            c = mirror_local(wo)
        wi_b, wo_b, c_b = np.broadcast_arrays(wi, wo, c)
        cos_i = np.clip(np.einsum("...k,...k->...", c_b, wi_b), -1.0, 1.0)
        cos_o = np.clip(np.einsum("...k,...k->...", c_b, wo_b), -1.0, 1.0)
        a = wi_b - cos_i[..., None] * c_b
        b = wo_b - cos_o[..., None] * c_b
        na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
        good = (na > 1e-12) & (nb > 1e-12)
        cos_phi = np.where(good, np.einsum("...k,...k->...", a, b) / np.where(good, na * nb, 1.0), 1.0)
        val = lobe.rho_hat(np.arccos(cos_i), np.arccos(cos_o), np.arccos(np.clip(cos_phi, -1.0, 1.0)))
        return np.asarray(val, dtype=np.float64)

    def fcos_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        val = self._fcos_raw(wi, wo)
        if val.ndim == len(np.broadcast_shapes(wi.shape, wo.shape)) - 1:
            val = val[..., None]
        # the view must be above the surface; a radial lobe's product function is not clipped in the light
        return np.where((wo[..., 2] > 0.0)[..., None], val, 0.0)

    def f_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        if isinstance(self.lobe, IsotropicBRDF):
            wi_b, wo_b = np.broadcast_arrays(wi, wo)
            val = np.asarray(self.lobe.f(wi_b, wo_b, np.broadcast_to(np.array([0.0, 0.0, 1.0]), wi_b.shape)))
            val = val[..., None] if val.ndim == wi_b.ndim - 1 else val
            return np.where(upper(wi_b, wo_b)[..., None], val, 0.0)
        cz = wi[..., 2]
        val = self.fcos_local(wi, wo)
        ok = (cz > 0.0)[..., None]
        return np.where(ok, val / np.where(ok, cz[..., None], 1.0), 0.0)

    def params(self) -> dict[str, Any]:
        return self.lobe.params()

    def spec(self) -> dict[str, Any]:
        return self.lobe.spec()


def _width_hint(lobe: Lobe) -> float:
    """A rough lobe width (radians) for quadrature placement: from the model's roughness or exponent if it has one."""
    for name in ("alpha", "sigma"):
        v = getattr(lobe, name, None)
        if isinstance(v, float) and v > 0.0:
            return float(min(max(v, 0.01), DEFAULT_LOBE_WIDTH))
    s = getattr(lobe, "s", None)
    if isinstance(s, float) and s > 0.0:
        return float(min(max(1.0 / np.sqrt(s), 0.01), DEFAULT_LOBE_WIDTH))
    return DEFAULT_LOBE_WIDTH


class FrameSum(FrameBRDF):
    """A sum of frame BRDFs; grey terms broadcast against RGB ones."""

    kind: ClassVar[str] = "sum"

    def __init__(self, terms: Sequence[FrameBRDF]) -> None:
        if len(terms) == 0:
            raise InputError("sum: needs at least one term")
        self.terms = list(terms)
        self.channels = max(t.channels for t in self.terms)
        self.isotropic = all(t.isotropic for t in self.terms)
        self.mirror_symmetric = all(t.mirror_symmetric for t in self.terms)
        self.lobe_width = min(t.lobe_width for t in self.terms)

    def f_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        return np.asarray(sum(t.f_local(wi, wo) for t in self.terms), dtype=np.float64)

    def fcos_local(self, wi: FloatArray, wo: FloatArray) -> FloatArray:
        return np.asarray(sum(t.fcos_local(wi, wo) for t in self.terms), dtype=np.float64)

    def params(self) -> dict[str, Any]:
        return {"lobes": [t.spec() for t in self.terms]}


def as_frame_brdf(obj: Any) -> FrameBRDF:
    """A :class:`FrameBRDF` from a frame BRDF, a relight lobe or a :class:`~relight.brdf.models.SumBRDF`."""
    if isinstance(obj, FrameBRDF):
        return obj
    if isinstance(obj, SumBRDF):
        terms: list[FrameBRDF] = [LobeAdapter(lobe) for lobe in obj.lobes]
        return terms[0] if len(terms) == 1 else FrameSum(terms)
    if isinstance(obj, Lobe):
        return LobeAdapter(obj)
    raise InputError(f"not a BRDF: {type(obj).__name__}")
