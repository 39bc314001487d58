"""The BRDF matrix of the in-out factorization on weighted quadrature grids (Mahajan, Tseng & Ramamoorthi 2008).

Eq. 2 of the paper factors ``rho(w_i, w_o) = sum_k sigma_k h_k(w_o) g_k(w_i)``; the sigma_k are the singular values
of the integral operator with kernel rho on L^2 of the sphere or of the visible hemisphere. Sampled on nodes w_a
with quadrature weights W_a, the operator becomes the matrix ``A = W_o^{1/2} rho W_i^{1/2}`` (rows outgoing,
columns incident), whose singular values converge to the operator's, and whose singular vectors divided by
``W^{1/2}`` sample the orthonormal functions h_k and g_k. Without the weights a non-uniform grid gives wrong
singular values (docs/conventions.md, "In-out factorization").

Grids (local frame: normal +z, tangent +x; ``mu = cos theta``):

* ``gauss``: Gauss–Legendre nodes in mu on [0, 1] (hemisphere) or [-1, 1] (sphere) times n_phi uniform azimuths
  ``phi_j = 2 pi j / n_phi`` (trapezoid rule, exact for trigonometric polynomials of degree < n_phi);
* ``equal-area``: the paper's §3.2 grid, midpoints uniform in mu times the same azimuths, all weights equal.

The kernel (the value that is factored) is relight's lobe value ``f_r cos(theta_i)`` with ``include_cosine=True``
(``rho_hat`` of ``relight.brdf.base``: relight defines Phong (seed 000 §6.3) and the half-angle lobe (seed 000
eq. 11 = seed 004 eq. 14) this way, and these are exactly the functions the paper writes as rho in eqs. 5 and 14),
or the BRDF ``f_r`` itself with ``include_cosine=False`` (the cosine then belongs to the transport T_k, eq. 3).
Radial lobes about R are evaluated on the whole sphere as ``u(R . w_i)`` (the paper's §3.1–3.2 analysis);
general isotropic BRDFs are 0 unless both directions lie in the upper hemisphere. RGB materials are reduced to
the mean of their channels (the paper's Fig. 7 averages the colours).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from relight.brdf.base import IsotropicBRDF, Lobe, RadialLobe
from relight.brdf.frame import FrameBRDF, FrameSum, LobeAdapter
from relight.brdf.models import SumBRDF
from relight.errors import InputError

FloatArray = NDArray[np.float64]
Domain = Literal["hemisphere", "sphere"]
GridKind = Literal["gauss", "equal-area"]
DOMAINS: tuple[str, ...] = ("hemisphere", "sphere")
GRID_KINDS: tuple[str, ...] = ("gauss", "equal-area")
#: A vectorised callable ``f(wi, wo)`` of unit vectors (..., 3) in the local frame, values (...) or (..., C).
DirectionalFunction = Callable[[FloatArray, FloatArray], Any]
#: Largest accepted grid size per axis (a dense matrix of n_theta n_phi rows; blocks of n_theta rows).
MAX_NODES = 8192


@dataclass(frozen=True)
class Grid:
    """Quadrature nodes over the domain: ``mu`` (n_theta,) with weights ``w_mu`` (sum: 1 or 2) and ``phi`` (n_phi,)."""

    domain: str
    kind: str
    mu: FloatArray
    w_mu: FloatArray
    phi: FloatArray

    @property
    def n_theta(self) -> int:
        return int(self.mu.size)

    @property
    def n_phi(self) -> int:
        return int(self.phi.size)

    @property
    def theta(self) -> FloatArray:
        return np.asarray(np.arccos(self.mu), dtype=np.float64)

    @property
    def weights(self) -> FloatArray:
        """Solid-angle weights of the n_theta x n_phi nodes (flattened, theta major); they sum to the area."""
        return np.asarray(np.repeat(self.w_mu, self.n_phi) * (2.0 * np.pi / self.n_phi), dtype=np.float64)

    def directions(self) -> FloatArray:
        """Unit vectors of the nodes, shape (n_theta * n_phi, 3), theta major."""
        st = np.sqrt(np.clip(1.0 - self.mu * self.mu, 0.0, None))[:, None]
        d = np.stack(
            [st * np.cos(self.phi)[None, :], st * np.sin(self.phi)[None, :], np.broadcast_to(self.mu[:, None],
             (self.n_theta, self.n_phi))], axis=-1)
        return np.asarray(d.reshape(-1, 3), dtype=np.float64)


def _count(name: str, value: Any, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} must be an integer, got {value!r}")
    if not lo <= int(value) <= MAX_NODES:
        raise InputError(f"{name} must lie in [{lo}, {MAX_NODES}], got {value}")
    return int(value)


def make_grid(domain: str, n_theta: int, n_phi: int, kind: str = "gauss") -> Grid:
    """The ``kind`` quadrature grid over ``domain`` with n_theta nodes in cos(theta) and n_phi azimuths."""
    if domain not in DOMAINS:
        raise InputError(f"domain must be one of {', '.join(DOMAINS)}, got {domain!r}")
    if kind not in GRID_KINDS:
        raise InputError(f"grid must be one of {', '.join(GRID_KINDS)}, got {kind!r}")
    n_t = _count("n_theta", n_theta, 2)
    n_p = _count("n_phi", n_phi, 1)
    lo = 0.0 if domain == "hemisphere" else -1.0
    half = 0.5 * (1.0 - lo)
    if kind == "gauss":
        x, w = np.polynomial.legendre.leggauss(n_t)
        mu, w_mu = lo + half * (x + 1.0), half * w
    else:
        mu = lo + (1.0 - lo) * (np.arange(n_t) + 0.5) / n_t
        w_mu = np.full(n_t, (1.0 - lo) / n_t)
    phi = 2.0 * np.pi * np.arange(n_p) / n_p
    return Grid(domain=domain, kind=kind, mu=np.asarray(mu, np.float64), w_mu=np.asarray(w_mu, np.float64), phi=phi)


def _mean_channels(v: Any, shape: tuple[int, ...]) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape == shape:
        return a
    if a.ndim == len(shape) + 1 and a.shape[-1] == 1:
        return a[..., 0]
    if a.ndim == len(shape) + 1:
        return np.asarray(a.mean(axis=-1), dtype=np.float64)
    raise InputError(f"a BRDF returned values of shape {a.shape} for directions of shape {shape + (3,)}")


@dataclass(frozen=True)
class Kernel:
    """The function that is factored. ``full(wi, wo)`` for unit vectors (..., 3) in the local frame; isotropic
    kernels also give ``iso(mu_o, mu_i, dphi)`` (dphi = phi_i - phi_o) and ``even`` (symmetric in dphi)."""

    full: Callable[[FloatArray, FloatArray], FloatArray]
    iso: Callable[[FloatArray, FloatArray, FloatArray], FloatArray] | None
    include_cosine: bool
    description: str

    @property
    def isotropic(self) -> bool:
        return self.iso is not None

    def is_even(self, seed: int = 0) -> bool:
        """Whether the isotropic kernel is even in dphi (then every azimuthal block is real), probed at 256 points."""
        if self.iso is None:
            return False
        rng = np.random.default_rng(seed)
        mo, mi = rng.uniform(0.0, 1.0, 256), rng.uniform(0.0, 1.0, 256)
        d = rng.uniform(0.0, np.pi, 256)
        a, b = self.iso(mo, mi, d), self.iso(mo, mi, -d)
        return bool(np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(float(np.abs(a).max()), 1e-300)))


def _iso_vectors(mu_o: FloatArray, mu_i: FloatArray, dphi: FloatArray) -> tuple[FloatArray, FloatArray]:
    mo, mi, dp = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (mu_o, mu_i, dphi)))
    so = np.sqrt(np.clip(1.0 - mo * mo, 0.0, None))
    si = np.sqrt(np.clip(1.0 - mi * mi, 0.0, None))
    wo = np.stack([so, np.zeros_like(so), mo], axis=-1)
    wi = np.stack([si * np.cos(dp), si * np.sin(dp), mi], axis=-1)
    return wi, wo


def _cos_factor(mu_i: FloatArray, include_cosine: bool) -> FloatArray:
    """1 / mu_i when the lobe's cosine is divided out (hemisphere only: mu_i > 0), else 1."""
    if include_cosine:
        return np.ones_like(mu_i)
    return np.asarray(1.0 / np.where(mu_i > 0.0, mu_i, np.inf), dtype=np.float64)


def _lobe_kernel(lobe: Lobe, include_cosine: bool) -> Kernel:
    if isinstance(lobe, RadialLobe) and lobe.center in ("R", "N"):
        center = lobe.center

        def iso(mu_o: FloatArray, mu_i: FloatArray, dphi: FloatArray) -> FloatArray:
            # natural broadcasting: cos(dphi) and the sines are evaluated on their own (small) shapes only
            mo, mi, dp = (np.asarray(x, dtype=np.float64) for x in (mu_o, mu_i, dphi))
            if center == "R":  # R = (-x, -y, z) of w_o (n = +z), w_o at phi = 0
                so = np.sqrt(np.clip(1.0 - mo * mo, 0.0, None))
                si = np.sqrt(np.clip(1.0 - mi * mi, 0.0, None))
                t = mo * mi - (so * si) * np.cos(dp)
            else:
                t = np.broadcast_to(mi, np.broadcast_shapes(mo.shape, mi.shape, dp.shape))
            val = _mean_channels(lobe.u(t), t.shape)
            if include_cosine:
                return val
            return val * _cos_factor(np.broadcast_to(mi, t.shape), include_cosine)

        def full(wi: FloatArray, wo: FloatArray) -> FloatArray:
            wi, wo = np.broadcast_arrays(np.asarray(wi, np.float64), np.asarray(wo, np.float64))
            if center == "R":
                t = wo[..., 2] * wi[..., 2] - wo[..., 0] * wi[..., 0] - wo[..., 1] * wi[..., 1]
            else:
                t = wi[..., 2]
            return _mean_channels(lobe.u(t), t.shape) * _cos_factor(wi[..., 2], include_cosine)

        return Kernel(full=full, iso=iso, include_cosine=include_cosine, description=str(lobe.spec()))
    if isinstance(lobe, IsotropicBRDF):

        def full_iso(wi: FloatArray, wo: FloatArray) -> FloatArray:
            wi, wo = np.broadcast_arrays(np.asarray(wi, np.float64), np.asarray(wo, np.float64))
            n = np.broadcast_to(np.array([0.0, 0.0, 1.0]), wi.shape)
            mi, mo = wi[..., 2], wo[..., 2]
            ok = (mi > 0.0) & (mo > 0.0)
            val = _mean_channels(lobe.f(wi, wo, n), mi.shape) * (np.clip(mi, 0.0, None) if include_cosine else 1.0)
            return np.asarray(np.where(ok, val, 0.0), dtype=np.float64)

        def iso_iso(mu_o: FloatArray, mu_i: FloatArray, dphi: FloatArray) -> FloatArray:
            wi, wo = _iso_vectors(mu_o, mu_i, dphi)
            return full_iso(wi, wo)

        return Kernel(full=full_iso, iso=iso_iso, include_cosine=include_cosine, description=str(lobe.spec()))
    raise InputError(
        f"{lobe.kind or type(lobe).__name__}: the factorization needs a lobe about R or N or an isotropic BRDF "
        "f(wi, wo, n); lobes about a tangent are anisotropic: pass a callable f(wi, wo) in a tangent frame"
    )


def unwrap(brdf: Any) -> Any:
    """relight lobes behind the tangent-frame interface (``relight.brdf.frame``) as plain lobes or a ``SumBRDF``,
    so that isotropic ones take the block SVD and the radial predictions; other objects unchanged."""
    if isinstance(brdf, LobeAdapter):
        return brdf.lobe
    if isinstance(brdf, FrameSum) and all(isinstance(t, LobeAdapter) for t in brdf.terms):
        return SumBRDF([t.lobe for t in brdf.terms if isinstance(t, LobeAdapter)])
    return brdf


def _frame_kernel(brdf: FrameBRDF, include_cosine: bool) -> Kernel:
    """A tangent-frame BRDF (anisotropic: dense SVD) in the local frame x = t, y = b, z = n."""

    def full(wi: FloatArray, wo: FloatArray) -> FloatArray:
        wi, wo = np.broadcast_arrays(np.asarray(wi, np.float64), np.asarray(wo, np.float64))
        val = brdf.fcos_local(wi, wo) if include_cosine else brdf.f_local(wi, wo)
        return _mean_channels(val, wi.shape[:-1])

    return Kernel(full=full, iso=None, include_cosine=include_cosine, description=str(brdf.spec()))


def make_kernel(brdf: Any, *, domain: str = "hemisphere", include_cosine: bool = True) -> Kernel:
    """The kernel of ``brdf``: a relight lobe, a ``SumBRDF`` of lobes, a tangent-frame BRDF
    (``relight.brdf.frame.FrameBRDF``, e.g. ``parse_frame_brdf``'s anisotropic models) or a vectorised callable
    ``f(wi, wo)``.

    A callable is taken as f_r in the local frame (normal +z, tangent +x) and treated as anisotropic (dense SVD);
    with ``include_cosine`` it is multiplied by ``max(cos theta_i, 0)``. Lobes about the tangent (Kajiya–Kay) are
    evaluated through ``LobeAdapter`` with the tangent along +x (dense SVD).
    """
    if domain not in DOMAINS:
        raise InputError(f"domain must be one of {', '.join(DOMAINS)}, got {domain!r}")
    if not include_cosine and domain != "hemisphere":
        raise InputError("include_cosine=False (f_r = rho_hat / cos theta_i) is defined on the hemisphere only")
    brdf = unwrap(brdf)
    if isinstance(brdf, Lobe) and brdf.center == "T":
        if not include_cosine:
            raise InputError(f"{brdf.kind}: a lobe about the tangent is defined with its cosine (rho_hat) only")
        return _frame_kernel(LobeAdapter(brdf), True)
    if isinstance(brdf, FrameBRDF):
        return _frame_kernel(brdf, include_cosine)
    lobes = getattr(brdf, "lobes", None)
    if isinstance(brdf, Lobe):
        return _lobe_kernel(brdf, include_cosine)
    if isinstance(lobes, list) and lobes and all(isinstance(x, Lobe) for x in lobes):
        if any(x.center == "T" for x in lobes):
            return _frame_kernel(FrameSum([LobeAdapter(x) for x in lobes]), include_cosine)
        parts = [_lobe_kernel(x, include_cosine) for x in lobes]

        def full_sum(wi: FloatArray, wo: FloatArray) -> FloatArray:
            return np.asarray(sum(p.full(wi, wo) for p in parts), dtype=np.float64)

        def iso_sum(mu_o: FloatArray, mu_i: FloatArray, dphi: FloatArray) -> FloatArray:
            return np.asarray(sum(p.iso(mu_o, mu_i, dphi) for p in parts if p.iso is not None), dtype=np.float64)

        return Kernel(full=full_sum, iso=iso_sum, include_cosine=include_cosine,
                      description=" + ".join(p.description for p in parts))
    if callable(brdf):
        func: DirectionalFunction = brdf

        def full_call(wi: FloatArray, wo: FloatArray) -> FloatArray:
            wi, wo = np.broadcast_arrays(np.asarray(wi, np.float64), np.asarray(wo, np.float64))
            val = _mean_channels(func(wi, wo), wi.shape[:-1])
            if include_cosine:
                val = val * np.clip(wi[..., 2], 0.0, None)
            if not np.all(np.isfinite(val)):
                raise InputError("the BRDF callable returned non-finite values on the grid")
            return val

        return Kernel(full=full_call, iso=None, include_cosine=include_cosine,
                      description=getattr(func, "__name__", type(func).__name__))
    raise InputError(f"cannot factor {type(brdf).__name__}: give a BRDF spec, a lobe or a callable f(wi, wo)")
