"""Spherical Harmonic Reflection Maps (seed 000 §4 eqs. 5–8, §7.5 eq. 12, App. A eq. 14, App. C steps 2–3).

Seed 000 (Ramamoorthi & Hanrahan 2002) represents the reflected light field of a lobe centred on a direction C
(the reflection vector R, the normal N or the tangent T; §3.1) as a low-order expansion in the local outgoing
direction (eq. 6)::

    B(alpha, beta; theta_o, phi_o) = sum_{p <= P} sum_{|q| <= p} B_pq(alpha, beta) Y_pq(theta_o, phi_o)

where (alpha, beta) are the SH angles of C (``relight.conventions``: theta from +Y, phi the lat-long azimuth) and
(theta_o, phi_o) are the angles of the view V in the *local frame* of C: ``R_{alpha,beta} = R_z(beta) R_y(alpha)``
(SH frame ``(x', y', z') = (X, Z, Y)``), i.e. local x = theta-hat (towards increasing alpha), local y = phi-hat,
local z = C. In world coordinates::

    theta_hat = (cos a cos b, -sin a, cos a sin b), phi_hat = (-sin b, 0, cos b), C = (sin a cos b, cos a, sin a sin b)

Notes: the formula computed (eq. 5 and App. A's redefinition)
-----------------------------------------------------------
Writing ``L(R_{alpha,beta} w) = sum_lm L_lm Y_lm(R w)`` and using ``Y_lm(R w) = sum_q Y_lq(w) D^l_qm(R^{-1})`` with
``R^{-1} = R_y(-alpha) R_z(-beta)``, ``D^l_qm(R^{-1}) = d^l_qm(-alpha) e^{i m beta} = d^l_mq(alpha) e^{i m beta}``
(``relight.wigner``'s Edmonds convention), and the BRDF expansion of ``relight.brdf.lpq``, eq. 2 becomes::

    B_pq(alpha, beta) = sum_{l,m} L_lm rho_hat_lpq d^l_mq(alpha) e^{i m beta}       (eq. 14, App. C step 3)

So App. A's ``B_lmpq Lambda_l^{-1} D^l_mq`` with eq. 5's ``B_lmpq = Lambda_l L_lm rho_hat_lpq`` (Lambda_l cancels):
the coefficients synthesised are ``B_lmpq = L_lm rho_hat_lpq`` (App. A's redefinition), with ``D^l_mq(alpha) =
d^l_mq(alpha)``. For q = 0, ``d^l_m0(alpha) e^{i m beta} = Lambda_l Y_lm(alpha, beta)``, ``Lambda_l =
sqrt(4 pi / (2l + 1))``, so ``B_p0 = sum_lm (Lambda_l rho_hat_lp0 L_lm) Y_lm`` — an ordinary SH synthesis. For a
radially symmetric lobe ``rho_hat_l00 = sqrt(4 pi) rho_l`` and ``B = B_00 Y_00 = sum_lm Lambda_l rho_l L_lm Y_lm``,
exactly ``relight.prefilter``'s map (checked in the tests).

Real storage (identical to ``relight.sh.to_real``): the field is real, so ``B_{p,-q} = (-1)^q conj(B_pq)`` and each
SHRM coefficient is stored as a real RGB map ``Br_pq`` with ``B = sum Br_pq Yr_pq``, ``Yr_p0 = Y_p0``,
``Yr_{p,q>0} = sqrt2 (-1)^q Re Y_pq``, ``Yr_{p,q<0} = sqrt2 (-1)^q Im Y_{p|q|}``; i.e. ``Br_p0 = B_p0``,
``Br_{p,q>0} = sqrt2 (-1)^q Re B_pq``, ``Br_{p,-q} = -sqrt2 (-1)^q Im B_pq``.

Fast path (``backend="ducc0"``): ducc0's spin-weighted synthesis computes, for spin s > 0 with gradient-only
coefficients ``a^E_lm`` (``mode="GRAD_ONLY"``), ``Q + i U = (-1)^{s+1} sum_{l,m} a^E_lm Lambda_l^{-1}
d^l_{m,-s}(theta) e^{i m phi}`` (measured against ``relight.wigner``; the tests keep checking it). With
``a^E_lm = sqrt2 (-1)^{q+1} Lambda_l L_lm rho_hat_lpq`` and s = q this gives ``Q + i U = sqrt2 B_{p,-q}``, and by
the symmetry above ``Br_{p,q} = Q``, ``Br_{p,-q} = U``: one spin-q synthesis per (p, q >= 0, colour), O(F S^2)
each (App. C's O(F P^2 S^2) in all). Reference (``backend="wigner"``): the plain App. C step 3 — ``B_mpq(alpha) =
sum_l B_lmpq d^l_mq(alpha)`` with d from ``relight.wigner`` (stable to l = 2048), then ``sum_m B_mpq e^{i m beta}``
by an explicit DFT, then the real combinations. The two are tested against each other to l = 2048.

Global SHRM (eq. 8, distant viewer): ``B~_pq(alpha, beta) = sum_s d^p_qs(alpha) e^{-i q beta} B_ps(alpha, beta)``
(``D^p_sq(-alpha) = d^p_qs(alpha)``), from ``Y_pq(R^{-1} V) = sum_s Y_ps(V) D^p_sq(R)``, ``D^p_sq(R_z(b) R_y(a)) =
e^{-i s b} d^p_sq(a)``. Then eq. 12: ``B~(alpha, beta) = sum_pq B~r_pq(alpha, beta) Yr_pq(V)`` with V's SH angles.

Structure-aware size: a radially symmetric lobe needs P = 0 (one map); a lobe without azimuthal dependence
(Kajiya–Kay, §7.1) needs only q = 0 (P + 1 maps); a general isotropic lobe needs (P + 1)^2 maps. A sum-of-lobes
material gives one *component* per lobe, each with its own centre and orders.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import ducc0
import numpy as np
from numpy.typing import NDArray

from relight import __version__, sh, wigner
from relight.brdf import lpq
from relight.brdf.base import Lobe
from relight.brdf.coefficients import lambda_l
from relight.conventions import (
    column_phis,
    dirs_to_pixel,
    latlong_dirs,
    phi0,
    require_rgb_latlong,
    ring_thetas,
)
from relight.errors import InputError
from relight.orders import order_for_tolerance, rms_from_energy, uncaptured
from relight.prefilter import DEFAULT_EPSILON, LightingSpectrum, Timer, project_lighting, size_for_order

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Structure = Literal["radial", "azimuthal", "general"]
Backend = Literal["ducc0", "wigner"]

SQRT2 = math.sqrt(2.0)
#: Y_00 = 1 / sqrt(4 pi)
Y00 = 1.0 / math.sqrt(4.0 * math.pi)


# ------------------------------------------------------------------------------------------ index arithmetic
def real_index(p: int, q: int) -> int:
    """Position of the real term (p, q) in a full order-P block: ``p^2 + p + q`` (as ``relight.sh.to_real``)."""
    return p * p + p + q


def terms_for(structure: Structure, p_order: int) -> list[tuple[int, int]]:
    """The (p, q) terms stored for a component: [(0,0)]; [(p,0)]; or all (p, q) in ``real_index`` order."""
    if structure == "radial":
        return [(0, 0)]
    if structure == "azimuthal":
        return [(p, 0) for p in range(p_order + 1)]
    return [(p, q) for p in range(p_order + 1) for q in range(-p, p + 1)]


def structure_of(lobe: Lobe) -> tuple[Structure, str]:
    """The structure class of a lobe and the reason, for the report (module docstring)."""
    if lobe.radially_symmetric:
        return "radial", "radially symmetric lobe (rho_hat depends on theta_i only): P = 0, one plain map (§3.1)"
    if lobe.azimuthally_symmetric:
        return "azimuthal", "no azimuthal dependence (q = 0 only, §7.1): P + 1 maps B_p0"
    return "general", "general isotropic lobe: (P + 1)^2 maps B_pq (§4)"


def real_harmonics(p_order: int, theta: NDArray[np.floating], phi: NDArray[np.floating]) -> FloatArray:
    """Real harmonics ``Yr_pq(theta, phi)`` (module docstring convention), shape broadcast(theta, phi).shape +
    ((P+1)^2,), indexed by :func:`real_index`.

    From ``relight.sh.legendre_rows`` (``Y_pq = Pbar_pq(cos theta) e^{i q phi}``, CS phase).
    """
    t, ph_full = np.broadcast_arrays(np.asarray(theta, dtype=np.float64), np.asarray(phi, dtype=np.float64))
    ph = ph_full.ravel()
    out = np.zeros((t.size, (p_order + 1) ** 2))
    with np.errstate(invalid="ignore"):  # sh.legendre_rows forms 0 * log(0) at the poles (then discards it)
        rows = list(sh.legendre_rows(p_order, t.ravel()))
    for p, row in enumerate(rows):
        out[:, real_index(p, 0)] = row[0]
        for q in range(1, p + 1):
            sign = SQRT2 * (-1.0) ** q
            out[:, real_index(p, q)] = sign * row[q] * np.cos(q * ph)
            out[:, real_index(p, -q)] = sign * row[q] * np.sin(q * ph)
    return out.reshape(t.shape + ((p_order + 1) ** 2,))


def _real_to_complex(block: FloatArray, p: int) -> ComplexArray:
    """Complex ``B_ps`` (axis 0 indexed s + p) from real ``Br_ps`` (axis 0 indexed s + p) — ``sh.from_real``."""
    out = np.zeros(block.shape, dtype=np.complex128)
    out[p] = block[p]
    for s in range(1, p + 1):
        sign = (-1.0) ** s
        out[p + s] = sign * (block[p + s] - 1j * block[p - s]) / SQRT2
        out[p - s] = (block[p + s] + 1j * block[p - s]) / SQRT2  # (-1)^s conj(B_ps)
    return out


def _complex_to_real(block: ComplexArray, p: int) -> FloatArray:
    """Inverse of :func:`_real_to_complex` for a real field (uses q >= 0 only) — ``sh.to_real``."""
    out = np.zeros(block.shape, dtype=np.float64)
    out[p] = block[p].real
    for q in range(1, p + 1):
        sign = SQRT2 * (-1.0) ** q
        out[p + q] = sign * block[p + q].real
        out[p - q] = -sign * block[p + q].imag
    return out


# --------------------------------------------------------------------------------------------- synthesis
def _full_light(alm: ComplexArray, lmax: int, l: int) -> ComplexArray:
    """``L_lm`` for m = -lmax..lmax (zero for |m| > l) of a real field, shape (C, 2 lmax + 1)."""
    m = np.arange(l + 1)
    pos = alm[:, sh.alm_index(l, m, lmax)]
    out = np.zeros((alm.shape[0], 2 * lmax + 1), dtype=np.complex128)
    out[:, lmax + m] = pos
    out[:, lmax - m[1:]] = ((-1.0) ** m[1:]) * np.conj(pos[:, 1:])
    return out


def synthesize_local(
    light_alm: ComplexArray,
    light_lmax: int,
    rho: FloatArray,
    terms: Sequence[tuple[int, int]],
    height: int,
    *,
    backend: Backend = "ducc0",
    alphas: FloatArray | None = None,
    nthreads: int | None = None,
) -> FloatArray:
    """Local SHRM maps ``Br_pq(alpha, beta)`` (seed 000 App. C step 3, eq. 14), shape (K, rows, 2 height, C).

    ``light_alm`` (C, nalm(light_lmax)) are ``L_lm``; ``rho[l, p, q, c]`` (``relight.brdf.lpq``) sets the orders:
    F = rho.shape[0] - 1 <= light_lmax. Rows are the lat-long rings of an ``height x 2 height`` map (or, for the
    reference backend only, the given ``alphas``). Grey lobes (one channel) broadcast over the lighting's channels.
    See the module docstring for both backends.
    """
    alm = np.asarray(light_alm, dtype=np.complex128)
    if alm.ndim != 2:
        raise ValueError(f"light_alm must be (channels, nalm), got shape {alm.shape}")
    f_order = rho.shape[0] - 1
    if f_order > light_lmax:
        raise ValueError(f"BRDF order F={f_order} exceeds the lighting order {light_lmax}")
    for p, q in terms:
        if not (0 <= p < rho.shape[1] and abs(q) <= p and abs(q) < rho.shape[2]):
            raise ValueError(f"term (p={p}, q={q}) outside the coefficients' range (F+1, P+1, Q+1) = {rho.shape[:3]}")
    alm = sh.truncate(alm, light_lmax, f_order)
    width = 2 * height
    if backend == "ducc0":
        if alphas is not None:
            raise ValueError("the ducc0 backend evaluates on the lat-long rings only (alphas=None)")
        return _synthesize_ducc0(alm, rho, terms, height, width, nthreads or sh.NTHREADS)
    if backend == "wigner":
        a = ring_thetas(height) if alphas is None else np.asarray(alphas, dtype=np.float64).ravel()
        return _synthesize_wigner(alm, rho, terms, a, width)
    raise ValueError(f"unknown backend {backend!r}; use 'ducc0' or 'wigner'")


def _rho_channel(rho: FloatArray, c: int) -> FloatArray:
    return rho[..., c if rho.shape[-1] > 1 else 0]


def _synthesize_ducc0(
    alm: ComplexArray, rho: FloatArray, terms: Sequence[tuple[int, int]], height: int, width: int, nthreads: int
) -> FloatArray:
    """Fast path: one ducc0 spin-|q| synthesis per (p, |q|, colour) (module docstring)."""
    f_order = rho.shape[0] - 1
    n_c = alm.shape[0]
    l, _ = sh.lm_arrays(f_order)
    lam = lambda_l(f_order)[l]
    index = {t: k for k, t in enumerate(terms)}
    out = np.zeros((len(terms), height, width, n_c))
    groups = sorted({(p, abs(q)) for p, q in terms})
    for p, qa in groups:
        if qa > f_order:
            continue  # rho_hat_lpq = 0 for l < |q|: the maps are zero
        for c in range(n_c):
            coef = lam * _rho_channel(rho, c)[l, p, qa] * alm[c]
            if qa == 0:
                res = ducc0.sht.synthesis_2d(
                    alm=coef[None], spin=0, lmax=f_order, geometry="F1", ntheta=height, nphi=width,
                    phi0=phi0(width), nthreads=nthreads,
                )
                out[index[(p, 0)], :, :, c] = res[0]
                continue
            coef = coef * (SQRT2 * (-1.0) ** (qa + 1))
            res = ducc0.sht.synthesis_2d(
                alm=coef[None], spin=qa, lmax=f_order, geometry="F1", ntheta=height, nphi=width,
                phi0=phi0(width), nthreads=nthreads, mode="GRAD_ONLY",
            )
            if (p, qa) in index:
                out[index[(p, qa)], :, :, c] = res[0]
            if (p, -qa) in index:
                out[index[(p, -qa)], :, :, c] = res[1]
    return out


def _synthesize_wigner(
    alm: ComplexArray, rho: FloatArray, terms: Sequence[tuple[int, int]], alphas: FloatArray, width: int
) -> FloatArray:
    """Reference: App. C step 3 summed literally with ``relight.wigner``'s d^l_mq (module docstring)."""
    f_order = rho.shape[0] - 1
    n_c = alm.shape[0]
    qs = np.array(sorted({abs(q) for _, q in terms}), dtype=np.int64)
    ps = np.array(sorted({p for p, _ in terms}), dtype=np.int64)
    rho_c = np.stack([_rho_channel(rho, c) for c in range(n_c)], axis=-1)[:, ps][:, :, qs]  # (F+1, np, nq, C)
    ms = np.arange(-f_order, f_order + 1)
    b_m = np.zeros((n_c, ps.size, qs.size, alphas.size, ms.size), dtype=np.complex128)
    q_ok = qs[qs <= f_order]
    if q_ok.size:
        for l, d in wigner.iter_wigner_d(f_order, alphas, q_ok, ms=ms):  # d: (n_alpha, 2F+1, nq_ok)
            light = _full_light(alm, f_order, l)  # (C, 2F+1)
            coef = light[:, :, None, None] * np.moveaxis(rho_c[l, :, : q_ok.size], -1, 0)[:, None]  # (C,M,np,nq)
            b_m[:, :, : q_ok.size] += np.einsum("amq,cmpq->cpqam", d, coef)
    betas = column_phis(width)
    phase = np.exp(1j * np.outer(ms, betas))  # (M, W)
    b = b_m @ phase  # (C, np, nq, n_alpha, W): complex B_pq(alpha, beta) for q >= 0
    out = np.zeros((len(terms), alphas.size, width, n_c))
    for k, (p, q) in enumerate(terms):
        v = b[:, int(np.searchsorted(ps, p)), int(np.searchsorted(qs, abs(q)))]
        if q == 0:
            real = v.real
        elif q > 0:
            real = SQRT2 * (-1.0) ** q * v.real
        else:
            real = -SQRT2 * (-1.0) ** q * v.imag
        out[k] = np.moveaxis(real, 0, -1)
    return out


def local_to_global(maps: FloatArray, terms: Sequence[tuple[int, int]], alphas: FloatArray) -> FloatArray:
    """Global SHRM ``B~r_pq`` for every (p, q) with p <= P from local maps (seed 000 eq. 8), (P+1)^2 maps.

    ``maps`` (K, rows, W, C) hold ``Br_pq`` for ``terms`` (missing terms are zero); rows are at ``alphas`` and
    columns at the lat-long azimuths. ``B~_pq = e^{-i q beta} sum_s d^p_qs(alpha) B_ps`` (module docstring).
    """
    n_rows, width = maps.shape[1], maps.shape[2]
    if alphas.shape != (n_rows,):
        raise ValueError(f"alphas must have shape ({n_rows},), got {alphas.shape}")
    p_order = max(p for p, _ in terms)
    betas = column_phis(width)
    index = {t: k for k, t in enumerate(terms)}
    out = np.zeros(((p_order + 1) ** 2,) + maps.shape[1:])
    for p in range(p_order + 1):
        block = np.zeros((2 * p + 1,) + maps.shape[1:])
        for s in range(-p, p + 1):
            if (p, s) in index:
                block[p + s] = maps[index[(p, s)]]
        if not block.any():
            continue
        local = _real_to_complex(block, p)  # (2p+1, rows, W, C), index s + p
        dmat = wigner.wigner_d_matrix(p, alphas)  # (rows, 2p+1, 2p+1): [a, q + p, s + p] = d^p_qs(alpha)
        rot = np.einsum("aqs,sabc->qabc", dmat, local)
        qv = np.arange(-p, p + 1)
        rot *= np.exp(-1j * np.outer(qv, betas))[:, None, :, None]
        out[p * p : (p + 1) ** 2] = _complex_to_real(rot, p)
    return out


# ------------------------------------------------------------------------------------------- data classes
@dataclass
class SHRMComponent:
    """One lobe's SHRM: local maps ``Br_pq`` on a lat-long grid indexed by the lobe's centre direction.

    ``maps[k]`` (rows, 2 rows, 3) holds the term ``terms[k] = (p, q)`` (module docstring: local frame, real basis).
    ``report`` carries orders, predicted errors and the reason for the structure. The global maps (eq. 8) are
    cached on first use: replace ``maps`` only before evaluating.
    """

    center: str
    structure: Structure
    F: int
    P: int
    terms: list[tuple[int, int]]
    maps: FloatArray
    lobe: dict[str, Any]
    report: dict[str, Any] = field(default_factory=dict)
    _global: FloatArray | None = field(default=None, repr=False)

    @property
    def height(self) -> int:
        return int(self.maps.shape[1])

    def global_maps(self) -> FloatArray:
        """``B~r_pq`` for all (P+1)^2 terms (eq. 8), cached; for P = 0 the local map itself."""
        if self._global is None:
            if self.P == 0:
                self._global = self.maps
            else:
                self._global = local_to_global(self.maps, self.terms, ring_thetas(self.height))
        return self._global

    def view_map(self, view: NDArray[np.floating]) -> FloatArray:
        """The eq. 12 map ``B~(alpha, beta)`` for the distant view V, on this component's grid, (rows, 2 rows, 3).

        Radial: ``Br_00 Y_00``. Azimuthal (q = 0 only): ``sum_p Br_p0(C) Yr_p0(theta_o)`` with ``cos theta_o =
        C . V`` at every pixel centre — eq. 6 evaluated exactly, which equals eq. 12. General: eq. 12 with the
        global maps of eq. 8.
        """
        v = unit_view(view)
        if self.structure == "radial":
            return np.asarray(self.maps[0] * Y00, dtype=np.float64)
        if self.structure == "azimuthal":
            dirs = latlong_dirs(self.height, 2 * self.height)
            theta_o = np.arccos(np.clip(dirs @ v, -1.0, 1.0))
            y = real_harmonics(self.P, theta_o, np.zeros_like(theta_o))
            cols = [real_index(p, 0) for p, _ in self.terms]
            return np.asarray(np.einsum("khwc,hwk->hwc", self.maps, y[..., cols]), dtype=np.float64)
        theta_v, phi_v = sh_angles(v)
        y = real_harmonics(self.P, theta_v, phi_v)
        return np.asarray(np.tensordot(y, self.global_maps(), axes=(0, 0)), dtype=np.float64)


@dataclass
class SHRM:
    """A material's SHRM: a list of components (one per lobe) sharing one output grid, with the report."""

    components: list[SHRMComponent]
    brdf: dict[str, Any] | None = None
    report: dict[str, Any] = field(default_factory=dict)

    @property
    def height(self) -> int:
        return self.components[0].height

    @property
    def width(self) -> int:
        return 2 * self.height


# ------------------------------------------------------------------------------------------------ geometry
def unit_view(view: NDArray[np.floating] | Sequence[float]) -> FloatArray:
    """A unit view vector from a 3-vector; raises InputError for a wrong shape or zero length."""
    v = np.asarray(view, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(f"a view direction must be 3 finite numbers, got {np.asarray(view).tolist()}")
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise InputError("the view direction must not be zero")
    return np.asarray(v / n, dtype=np.float64)


def sh_angles(dirs: NDArray[np.floating]) -> tuple[FloatArray, FloatArray]:
    """SH angles (theta from +Y, phi = atan2(z, x)) of directions (..., 3), accurate next to the poles.

    Same angles as ``relight.conventions.dirs_to_angles`` but ``theta = atan2(hypot(x, z), y)`` instead of an
    arccos, which loses half the digits within 1e-8 of +-Y.
    """
    d = np.asarray(dirs, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"directions must have a trailing axis of length 3, got shape {d.shape}")
    return np.arctan2(np.hypot(d[..., 0], d[..., 2]), d[..., 1]), np.arctan2(d[..., 2], d[..., 0])


def local_frame(dirs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """World vectors theta-hat and phi-hat of the local frame at directions C (..., 3) (module docstring)."""
    a, b = sh_angles(dirs)
    th = np.stack([np.cos(a) * np.cos(b), -np.sin(a), np.cos(a) * np.sin(b)], axis=-1)
    ph = np.stack([-np.sin(b), np.zeros_like(b), np.cos(b)], axis=-1)
    return th, ph


def local_view_angles(centres: FloatArray, view: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(theta_o, phi_o) of V (3,) or (..., 3) in the local frames of the centres C (..., 3) (eq. 3)."""
    th, ph = local_frame(centres)
    v = np.broadcast_to(view, centres.shape)
    cz = np.einsum("...k,...k->...", centres, v)
    cx = np.einsum("...k,...k->...", th, v)
    cy = np.einsum("...k,...k->...", ph, v)
    return np.arctan2(np.hypot(cx, cy), cz), np.arctan2(cy, cx)


def tangent_field(normals: FloatArray) -> FloatArray:
    """The tangent T used by T-centred (Kajiya–Kay) lobes: ``T = normalize(+Y x N)`` (horizontal, along the
    latitude circles, like hair combed around the vertical axis); ``T = +X`` where N = +-Y (measure zero)."""
    n = np.asarray(normals, dtype=np.float64)
    t = np.stack([n[..., 2], np.zeros(n.shape[:-1]), -n[..., 0]], axis=-1)
    norm = np.linalg.norm(t, axis=-1, keepdims=True)
    fallback = np.broadcast_to(np.array([1.0, 0.0, 0.0]), t.shape)
    return np.where(norm > 1e-12, t / np.where(norm > 1e-12, norm, 1.0), fallback)


def lobe_centres(center: str, normals: FloatArray, reflected: FloatArray) -> FloatArray:
    """The centre direction C of a lobe for each (N, R): R, N, or the tangent field's T(N) (§3.1)."""
    if center == "R":
        return reflected
    if center == "N":
        return normals
    if center == "T":
        return tangent_field(normals)
    raise InputError(f"unknown lobe centre {center!r}; expected 'R', 'N' or 'T'")


def sample_latlong(maps: FloatArray, dirs: FloatArray) -> FloatArray:
    """Bilinear lookup of lat-long maps (K, H, W, C) at directions (N, 3) -> (N, K, C).

    Pixel centres are the sample points (``relight.conventions.dirs_to_pixel``); columns wrap, rows clamp at
    the poles.
    """
    _, h, w, _ = maps.shape
    y, x = dirs_to_pixel(dirs, h, w)
    y = np.clip(y, 0.0, h - 1.0)
    y0 = np.clip(np.floor(y).astype(np.intp), 0, max(h - 2, 0))
    fy = (y - y0)[:, None, None]
    y1 = np.minimum(y0 + 1, h - 1)
    x0f = np.floor(x)
    fx = (x - x0f)[:, None, None]
    x0 = np.mod(x0f.astype(np.intp), w)
    x1 = np.mod(x0 + 1, w)
    m = np.moveaxis(maps, 0, 2)  # (H, W, K, C)
    top = m[y0, x0] * (1.0 - fx) + m[y0, x1] * fx
    bot = m[y1, x0] * (1.0 - fx) + m[y1, x1] * fx
    return np.asarray(top * (1.0 - fy) + bot * fy, dtype=np.float64)


def reflect_dirs(normals: FloatArray, view: FloatArray) -> FloatArray:
    """``R = 2 (N . V) N - V`` (V broadcast)."""
    ndv = np.einsum("...k,...k->...", normals, np.broadcast_to(view, normals.shape))
    return np.asarray(2.0 * ndv[..., None] * normals - view, dtype=np.float64)


def halfway_normals(reflected: FloatArray, view: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """``N = normalize(R + V)`` and a mask of valid pixels (R = -V has no normal)."""
    s = reflected + view
    n = np.linalg.norm(s, axis=-1, keepdims=True)
    ok = n[..., 0] > 1e-9
    return s / np.where(n > 1e-9, n, 1.0), ok


# --------------------------------------------------------------------------------------------- evaluation
def reflect(shrm: SHRM, view: NDArray[np.floating] | Sequence[float], *, size: int | None = None) -> FloatArray:
    """The reflection map for a distant view V (seed 000 eq. 12, §7.5), indexed by R, shape (S, 2S, 3).

    Each pixel holds the radiance reflected toward V by a surface whose reflection vector is that pixel's
    direction R (``docs/conventions.md``); its normal is ``N = normalize(R + V)``. R-centred components give their
    eq. 12 map directly (no resampling when ``size`` is the SHRM's); N- and T-centred components are looked up
    bilinearly at N and T(N). The one direction R = -V (no normal) reads 0.
    """
    v = unit_view(view)
    s = shrm.height if size is None else int(size)
    if s < 1:
        raise InputError(f"size must be >= 1, got {s}")
    r = latlong_dirs(s, 2 * s)
    n, ok = halfway_normals(r, v)
    out = np.zeros((s, 2 * s, 3))
    for comp in shrm.components:
        vm = comp.view_map(v)
        if comp.center == "R" and comp.height == s:
            out += vm
            continue
        c = lobe_centres(comp.center, n, r).reshape(-1, 3)
        out += sample_latlong(vm[None], c)[:, 0].reshape(s, 2 * s, 3)
    return np.where(ok[..., None], out, 0.0)


def sphere_geometry(view: FloatArray, size: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Normals of a unit sphere seen by an orthographic camera looking along -V, +Y up, filling the frame.

    The camera matches Mitsuba's ``look_at(origin=3 V, target=0, up=+Y)`` (``shared/FACTS.md``): image right =
    ``normalize(up x V)`` (+X for V = +Z), image up = ``V x right``; pixel (i, j) sits at
    ``x = 2 (j + 1/2) / size - 1``, ``y = 1 - 2 (i + 1/2) / size``. Returns (size, size, 3) normals and the mask
    of pixels on the sphere. For V = +-Y the up vector is +Z instead.
    """
    up = np.array([0.0, 1.0, 0.0]) if abs(view[1]) < 1.0 - 1e-9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(up, view)
    right /= np.linalg.norm(right)
    upv = np.cross(view, right)
    c = (np.arange(size) + 0.5) * 2.0 / size - 1.0
    x, y = np.meshgrid(c, -c)
    rr = x * x + y * y
    mask = rr < 1.0
    z = np.sqrt(np.clip(1.0 - rr, 0.0, None))
    n = x[..., None] * right + y[..., None] * upv + z[..., None] * view
    return np.asarray(n, dtype=np.float64), mask


def render_sphere(
    shrm: SHRM,
    view: NDArray[np.floating] | Sequence[float],
    size: int,
    *,
    local: bool = False,
    background: NDArray[np.floating] | float = 0.0,
) -> FloatArray:
    """CPU render of a unit sphere with the SHRM (seed 000 §7.5), (size, size, 3).

    Orthographic camera of :func:`sphere_geometry`; per pixel N from the sphere, ``R = 2 (N.V) N - V``, and each
    component looked up by bilinear interpolation at its centre (R, N or T(N) of :func:`tangent_field`).
    ``local=False``: the distant-viewer global SHRM, i.e. one eq. 12 map per frame sampled at C.
    ``local=True``: the local SHRM, eq. 6 per pixel: the maps ``Br_pq`` sampled at C, weighted by
    ``Yr_pq(theta_o, phi_o)`` of V in C's local frame (identical to the global path up to interpolation).
    Pixels off the sphere get ``background``.
    """
    v = unit_view(view)
    if size < 1:
        raise InputError(f"size must be >= 1, got {size}")
    n, mask = sphere_geometry(v, size)
    out = np.empty((size, size, 3))
    out[...] = np.asarray(background, dtype=np.float64)
    out[mask] = shade(shrm, n[mask], v, local=local)
    return out


def shade(
    shrm: SHRM, normals: NDArray[np.floating], view: NDArray[np.floating], *, local: bool = False,
    map_view: NDArray[np.floating] | None = None,
) -> FloatArray:
    """Radiance (n, 3) leaving surface points with unit normals N (n, 3) toward V (unit; (3,) or per point
    (n, 3)), seed 000 §7.5: ``R = 2 (N.V) N - V`` and each component looked up bilinearly at its centre C.

    ``local=False`` (distant viewer): one eq. 12 map for ``map_view`` (default: ``view``, which must then be a
    single direction) sampled at C. ``local=True`` (near viewer): eq. 6 per point, the maps ``Br_pq`` sampled at C
    and weighted by ``Yr_pq`` of the point's own V in C's local frame.
    """
    nn = np.asarray(normals, dtype=np.float64)
    v = np.asarray(view, dtype=np.float64)
    r = reflect_dirs(nn, v)
    mv = v if map_view is None else unit_view(map_view)
    if not local and mv.shape != (3,):
        raise InputError("a distant viewer needs one view direction for its eq. 12 map (map_view)")
    acc = np.zeros((nn.shape[0], 3))
    for comp in shrm.components:
        c = lobe_centres(comp.center, nn, r)
        if not local:
            acc += sample_latlong(comp.view_map(mv)[None], c)[:, 0]
            continue
        coeffs = sample_latlong(comp.maps, c)  # (n, K, 3)
        theta_o, phi_o = local_view_angles(c, v)
        y = real_harmonics(comp.P, theta_o, phi_o)
        cols = [real_index(p, q) for p, q in comp.terms]
        acc += np.einsum("nkc,nk->nc", coeffs, y[:, cols])
    return acc


def evaluate_local(comp: SHRMComponent, view: NDArray[np.floating] | Sequence[float]) -> FloatArray:
    """Eq. 6 at every pixel centre of the component's grid for a distant view V: ``sum Br_pq(C) Yr_pq(R_C^{-1} V)``.

    Equals :meth:`SHRMComponent.view_map` (eq. 8 + eq. 12) to rounding; used to check eq. 8.
    """
    v = unit_view(view)
    dirs = latlong_dirs(comp.height, 2 * comp.height)
    theta_o, phi_o = local_view_angles(dirs, v)
    y = real_harmonics(comp.P, theta_o, phi_o)
    cols = [real_index(p, q) for p, q in comp.terms]
    return np.asarray(np.einsum("khwc,hwk->hwc", comp.maps, y[..., cols]), dtype=np.float64)


# ------------------------------------------------------------------------------------------ explicit forms
def icosahedron_views() -> FloatArray:
    """The 12 vertices of a regular icosahedron (unit vectors): Cabral et al. 1999's view set (App. C)."""
    g = (1.0 + math.sqrt(5.0)) / 2.0
    v = []
    for a in (-1.0, 1.0):
        for b in (-g, g):
            v += [(0.0, a, b), (a, b, 0.0), (b, 0.0, a)]
    arr = np.array(v)
    return np.asarray(arr / np.linalg.norm(arr, axis=1, keepdims=True), dtype=np.float64)


def view_grid(t_b: int) -> FloatArray:
    """A ``T_B x T_B`` set of view directions (App. C): lat-long pixel centres of a T_B x T_B grid, (T_B, T_B, 3)."""
    if t_b < 1:
        raise InputError(f"T_B must be >= 1, got {t_b}")
    t = ring_thetas(t_b)[:, None]
    p = ((np.arange(t_b) + 0.5) / t_b - 0.5)[None, :] * 2.0 * np.pi
    st = np.sin(t)
    return np.stack(np.broadcast_arrays(st * np.cos(p), np.cos(t), st * np.sin(p)), axis=-1)


def explicit_maps(shrm: SHRM, views: FloatArray) -> NDArray[np.float32]:
    """Reflection maps (eq. 12) for many views at once (App. C "conversion to explicit forms"), (n, S, 2S, 3).

    Cabral's 12 maps: ``explicit_maps(shrm, icosahedron_views())``; a T_B x T_B set: ``view_grid(T_B)``. For
    R-centred general components the maps are one matrix product ``Yr(V_k) @ B~r`` (O(P^2) per output pixel).
    """
    vs = np.asarray(views, dtype=np.float64).reshape(-1, 3)
    vs = vs / np.linalg.norm(vs, axis=1, keepdims=True)
    s = shrm.height
    out = np.zeros((vs.shape[0], s, 2 * s, 3), dtype=np.float32)
    fast = [c for c in shrm.components if c.center == "R" and c.structure == "general"]
    for comp in fast:
        theta_v, phi_v = sh_angles(vs)
        y = real_harmonics(comp.P, theta_v, phi_v)  # (n, K)
        g = comp.global_maps().reshape(y.shape[1], -1)
        for k0 in range(0, vs.shape[0], 16):  # bounded float64 temporaries
            out[k0 : k0 + 16] += (y[k0 : k0 + 16] @ g).reshape((-1,) + out.shape[1:]).astype(np.float32)
    rest = SHRM([c for c in shrm.components if not any(c is f for f in fast)])
    r = latlong_dirs(s, 2 * s)
    for k, v in enumerate(vs):
        if rest.components:
            out[k] += reflect(rest, v).astype(np.float32)
        out[k][np.linalg.norm(r + v, axis=-1) <= 1e-9] = 0.0  # R = -V has no normal: 0, as in reflect()
    return out


def kautz_mccool_texture(comp: SHRMComponent, n_theta: int) -> NDArray[np.float32]:
    """Kautz & McCool's 3-D texture ``B(alpha, beta, theta_o) = sum_p B_p0 Y_p0(theta_o)`` (App. C), q = 0 only.

    ``theta_o`` at the midpoints ``(k + 1/2) pi / n_theta``; shape (n_theta, S, 2S, 3).
    """
    if n_theta < 1:
        raise InputError(f"n_theta must be >= 1, got {n_theta}")
    theta = ring_thetas(n_theta)
    y = real_harmonics(comp.P, theta, np.zeros_like(theta))  # (n, (P+1)^2)
    out = np.zeros((n_theta,) + comp.maps.shape[1:])
    for k, (p, q) in enumerate(comp.terms):
        if q == 0:
            out += y[:, real_index(p, 0)][:, None, None, None] * comp.maps[k][None]
    return out.astype(np.float32)


# ------------------------------------------------------------------------------------------------ creation
def brdf_lobes(brdf: Any) -> list[Lobe]:
    """The lobes of a material: the BRDF itself if it is a lobe, else its ``lobes`` (a sum of lobes)."""
    if isinstance(brdf, Lobe):  # a lobe may have its own ``lobes`` (Lafortune's cosine lobes): it is one lobe
        return [brdf]
    lobes = getattr(brdf, "lobes", None)
    if lobes is None:
        raise InputError(f"not a BRDF lobe or sum of lobes: {type(brdf).__name__}")
    out = list(lobes)
    if not out or not all(isinstance(x, Lobe) for x in out):
        raise InputError("a sum of lobes needs at least one lobe, and only lobes")
    return out


def _spec(obj: Any) -> dict[str, Any] | None:
    try:
        from relight.brdf.spec import brdf_to_spec

        spec = brdf_to_spec(obj)
        return spec if isinstance(spec, dict) else {"spec": spec}
    except Exception:  # noqa: BLE001 - the spec module is optional; fall back to the lobe's own spec
        s = getattr(obj, "spec", None)
        return s() if callable(s) else None


def predicted_errors(
    coeffs: lpq.BRDFCoefficients, lighting: LightingSpectrum, f_b: int, p_b: int
) -> dict[str, float]:
    """Predicted uncaptured energy fractions of the 4-D light field at (F_B, P_B) (§5.1, App. B generalised).

    * ``epsilon_brdf``: the BRDF's uncaptured energy (the paper's choice, §5.1, Fig. 7);
    * ``epsilon_lighting``: the lighting's at F_B; ``epsilon_min_of_errors`` = min of the two;
    * ``epsilon_appendix_b``: App. B's bound with ``B_lmpq`` in place of ``B_lm``. By Parseval over (alpha, beta)
      and w_o the output energy is ``sum_l Lambda_l^2 E^L_l E^rho_lp`` (``E^L_l = sum_m |L_lm|^2``). The residual is
      ``Lambda_{F+1}^2 (eps_L L_tot)(eps_rho rho_tot)`` for l > F (App. B: Lambda_l decreases, all terms are
      non-negative) plus, for l <= F and p > P, ``sum_{l<=F} Lambda_l^2 E^L_l E^rho_{l,P<p<=P0}`` over the computed
      bands and ``max_{l<=F}(Lambda_l^2 E^L_l)`` times the BRDF energy outside the computed range (App. B's "worst
      case: all in one mode"); ``epsilon_B <= B_res / (B_captured + B_res)``.

    Each also as a relative RMS (``sqrt``). These are energies of the whole light field; a single view's map
    can have a larger or smaller relative error.
    """
    e_rho = coeffs.band_energy().max(axis=2)  # (F+1, P+1)
    rho_tot = float(coeffs.total_energy.max())
    table = coeffs.epsilon_table()
    eps_rho = float(table[f_b, p_b])
    e_light = lighting.band_energy()
    f_l = min(f_b, lighting.lmax)
    eps_l = float(uncaptured(e_light, lighting.total_energy)[f_l])
    lam2 = lambda_l(f_b + 1) ** 2
    captured = float(np.sum(lam2[: f_l + 1] * e_light[: f_l + 1] * e_rho[: f_l + 1, : p_b + 1].sum(axis=1)))
    outside = max(rho_tot - float(e_rho.sum()), 0.0)
    a_l = lam2[: f_l + 1] * e_light[: f_l + 1]
    res_p = float(np.sum(a_l * e_rho[: f_l + 1, p_b + 1 :].sum(axis=1)) + a_l.max() * outside)
    res_f = float(lam2[f_b + 1] * eps_l * lighting.total_energy * eps_rho * rho_tot)
    res = res_p + res_f
    eps_b = res / (captured + res) if captured + res > 0.0 else 0.0
    eps_min = min(eps_l, eps_rho)
    return {
        "epsilon_brdf": eps_rho,
        "epsilon_lighting": eps_l,
        "epsilon_min_of_errors": eps_min,
        "epsilon_appendix_b": eps_b,
        "rms_brdf": rms_from_energy(eps_rho),
        "rms_min_of_errors": rms_from_energy(eps_min),
        "rms_appendix_b": rms_from_energy(eps_b),
    }


#: Largest coefficient-map set create_shrm builds (float64, before any file is written).
MAX_SHRM_BYTES = 4 * 2**30


def create_shrm(
    pixels: NDArray[np.floating],
    brdf: Any,
    *,
    epsilon: float | None = None,
    order: int | None = None,
    p_order: int | None = None,
    size: int | None = None,
    backend: Backend = "ducc0",
) -> SHRM:
    """Prefilter a lat-long environment map (H, W, 3) into an SHRM (seed 000 Fig. 3, App. C).

    Per lobe: BRDF coefficients and orders (F_rho, P_rho) from ``epsilon`` (App. C order selection; default
    0.01) or the explicit ``order`` F and ``p_order`` P (P from the default tolerance when only F is given);
    lighting coefficients by pixel quadrature once, to the largest order needed; ``F_B = min(F_rho, F_L, H - 1)``
    (minimum-of-orders rule, §5.1), ``P_B = P_rho``; ``B_lmpq = L_lm rho_hat_lpq`` (eq. 5, App. A) synthesised
    into the local maps (App. C step 3). ``size`` is the output rows S (default S ~ 10 max F_B, §5.2). The report
    says, per component, which structure and why, the orders, predicted errors and timings.
    """
    if epsilon is not None and (order is not None or p_order is not None):
        raise InputError("give either epsilon or explicit orders, not both")
    if epsilon is None and order is None:
        epsilon = DEFAULT_EPSILON
    if epsilon is not None and not 0.0 < epsilon < 1.0:
        raise InputError(f"epsilon must lie in (0, 1), got {epsilon}")
    if order is not None and order < 0:
        raise InputError(f"order F must be >= 0, got {order}")
    if p_order is not None and p_order < 0:
        raise InputError(f"order P must be >= 0, got {p_order}")
    if size is not None and size < 2:
        raise InputError(f"size must be >= 2, got {size}")
    pixels = require_rgb_latlong(pixels)
    h, w = pixels.shape[:2]
    lobes = brdf_lobes(brdf)
    f_cap = h - 1
    timer = Timer()

    chosen: list[tuple[Lobe, lpq.BRDFCoefficients, int, int, dict[str, Any]]] = []
    for lobe in lobes:
        if order is not None:
            if lobe.radially_symmetric:
                p = 0
            elif p_order is not None:
                p = p_order
            else:  # F alone: P from the default tolerance (App. C order selection)
                p = lpq.cached_select_orders(lobe, DEFAULT_EPSILON)[0].P
            f_req = min(order, f_cap)  # orders above the map's resolution are never used (F_B <= H - 1)
            coeffs, cached = lpq.cached_coefficients(lobe, f_req, p)
            sel: dict[str, Any] = {"F_rho": f_req, "P_rho": p, "explicit": True, "cached": cached}
            chosen.append((lobe, coeffs, f_req, p, sel))
        else:
            assert epsilon is not None
            res, cached = lpq.cached_select_orders(lobe, epsilon)
            sel = {**res.as_dict(), "cached": cached}
            chosen.append((lobe, res.coefficients, res.F, res.P, sel))
    timer.lap("brdf_coefficients")

    f_proj = min(max(f for _, _, f, _, _ in chosen), f_cap)
    lighting = project_lighting(pixels, f_proj)
    timer.lap("lighting_projection")
    f_l = None
    if epsilon is not None:
        f_l = order_for_tolerance(lighting.band_energy(), lighting.total_energy, epsilon)
    timer.lap("order_selection")

    plans = []
    for lobe, coeffs, f_rho, p_rho, sel in chosen:
        f_b = min(f_rho, f_cap) if order is not None else min(f_rho, f_cap, f_l if f_l is not None else f_rho)
        structure, reason = structure_of(lobe)
        p_b = 0 if structure == "radial" else p_rho
        plans.append((lobe, coeffs, f_b, p_b, structure, reason, sel))
    s = size if size is not None else size_for_order(max(f for _, _, f, _, _, _, _ in plans))
    # Refuse plans whose coefficient maps cannot fit in memory (a sharp lobe at a tight tolerance can ask for
    # hundreds of S x 2S float64 maps): a clear error instead of an out-of-memory crash.
    n_maps = sum(len(terms_for(structure, p_b)) for _, _, _, p_b, structure, _, _ in plans)
    need = n_maps * s * 2 * s * 3 * 8
    if need > MAX_SHRM_BYTES:
        raise InputError(
            f"this SHRM needs {n_maps} maps of {s} x {2 * s} ({need / 2**30:.1f} GiB, limit "
            f"{MAX_SHRM_BYTES / 2**30:.0f} GiB): loosen epsilon, or give explicit orders and a smaller size"
        )

    components = []
    for lobe, coeffs, f_b, p_b, structure, reason, sel in plans:
        rho = coeffs.rho[: f_b + 1, : p_b + 1, : min(coeffs.Q, p_b) + 1]
        terms = terms_for(structure, p_b)
        maps = synthesize_local(lighting.alm, lighting.lmax, rho, terms, s, backend=backend)
        comp_report = {
            "center": lobe.center,
            "structure": structure,
            "reason": reason,
            "lobe": lobe.spec(),
            "orders": {"F_B": f_b, "P_B": p_b, "F_L": f_l, **{k: v for k, v in sel.items() if k != "probes"}},
            "probes": sel.get("probes", []),
            "n_maps": len(terms),
            "predicted": predicted_errors(coeffs, lighting, f_b, p_b),
            "brdf_energy": float(coeffs.total_energy.max()),
        }
        components.append(
            SHRMComponent(
                center=str(lobe.center), structure=structure, F=f_b, P=p_b, terms=terms, maps=maps,
                lobe=lobe.spec(), report=comp_report,
            )
        )
    timer.lap("synthesis")

    worst = max(components, key=lambda c: c.report["predicted"]["epsilon_brdf"])
    report: dict[str, Any] = {
        "representation": "shrm",
        "layout": "local",
        "brdf": _spec(brdf),
        "epsilon": epsilon,
        "order_requested": None if order is None else [order, p_order],
        "components": [c.report for c in components],
        "predicted": dict(worst.report["predicted"]),
        "input": {"height": h, "width": w},
        "output": {"height": s, "width": 2 * s, "layout": "latlong", "maps": sum(len(c.terms) for c in components)},
        "timings": dict(timer.seconds),
        "total_seconds": float(sum(timer.seconds.values())),
        "backend": backend,
        "relight_version": __version__,
    }
    return SHRM(components=components, brdf=report["brdf"], report=report)
