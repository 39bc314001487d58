"""Real spherical-harmonic rotation from 3 x 3 matrices, vectorised over many frames (seed 003, Appendix).

Kautz, Sloan & Snyder (EGWR 2002) rotate the lighting coefficients into each point's local frame (§4 step 1, App.).
Their Appendix goes through zyz Euler angles; here the band matrices are built directly from the 3 x 3 matrix by
the Ivanic–Ruedenberg recursion (J. Phys. Chem. 100 (1996) 6342, with the 1998 erratum, J. Phys. Chem. A 102
9099), so there is no Euler-angle singularity at beta = 0 or pi and no atan2 of tiny numbers.

Basis and action (``docs/conventions.md``, "Real SH rotation"): relight's real harmonics ``Yr_{lm}`` at index
``l^2 + l + m`` (``relight.sh.to_real``), whose band 1 is proportional to ``(y, z, x)`` of the SH frame. For a
proper rotation ``R`` (..., 3, 3) acting on SH-frame coordinates, :func:`band_rotations` returns per band ``l`` the
real orthogonal matrices ``M^l`` (..., 2l+1, 2l+1) with::

    Yr_{lm}(R^{-1} x) = sum_{m'} Yr_{lm'}(x) M^l_{m'm}(R)

so the field ``f(x) = sum c_i Yr_i(x)`` rotated actively, ``f'(x) = f(R^{-1} x)``, has ``c' = M(R) c`` — the real
form of ``relight.wigner``'s ``D^l_{m'm}(R)``: ``M^l = U D^l U^H`` with ``U`` the ``to_real`` unitary (tested to
1e-12 up to l = 14).

The recursion (Ivanic–Ruedenberg eqs. 8.1–8.5, Table 2) writes band ``l`` from band ``l - 1`` and band 1. With
``P_i = M^{l-1} G_i`` (``G_i`` a sparse (2l-1) x (2l+1) matrix from row ``i`` of ``M^1``), each band costs three
batched matrix products and three sparse recombinations, all vectorised over the frames.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.indexing import full_block, full_size

FloatArray = NDArray[np.float64]

#: SH-frame coordinates of a world vector: ``(x', y', z') = (X, Z, Y)`` (docs/conventions.md); det = -1.
SH_FROM_WORLD: FloatArray = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
SH_FROM_WORLD.setflags(write=False)

#: Band 1 of the real basis is proportional to SH-frame (y, z, x): m = -1, 0, 1 -> axis 1, 2, 0.
_BAND1_AXES = (1, 2, 0)

#: A 3 x 3 matrix counts as a rotation when ``|R^T R - I| <= tol`` and ``det R > 0``.
ORTHOGONALITY_TOL = 1e-6


def check_rotations(r: ArrayLike, *, proper: bool = True) -> FloatArray:
    """Rotation matrices (..., 3, 3) as float64; InputError for a wrong shape, non-finite or non-orthogonal input."""
    a = np.asarray(r, dtype=np.float64)
    if a.shape[-2:] != (3, 3):
        raise InputError(f"rotation matrices must have shape (..., 3, 3), got {a.shape}")
    validate.finite_array("rotation matrices", a)
    err = np.abs(np.einsum("...ki,...kj->...ij", a, a) - np.eye(3)).max(initial=0.0)
    if err > ORTHOGONALITY_TOL:
        raise InputError(f"rotation matrices must be orthogonal: |R^T R - I| = {err:.3g} > {ORTHOGONALITY_TOL:g}")
    if proper and np.any(np.linalg.det(a) <= 0.0):
        raise InputError("rotation matrices must be proper (det R = +1); for a mirrored frame use local_rotations")
    return a


@lru_cache(maxsize=64)
def _band_tables(l: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Fixed (2l+1) x (2l-1) recombination matrices ``(A0, A1, Am1)`` and the coefficient grids for band l >= 2.

    ``M^l = A0 @ P_0 + A1 @ P_1 + Am1 @ P_{-1}`` elementwise-weighted per column through ``u, v, w`` (which depend
    on (m, n)); returned as ``(S_u, S_v1, S_vm1, S_w1, S_wm1)`` stacked so that the caller forms
    ``M = u * (S_u @ P0) + v * (S_v1 @ P1 + S_vm1 @ Pm1) + w * (S_w1 @ P1 + S_wm1 @ Pm1)``.
    """
    n_out, n_in = 2 * l + 1, 2 * l - 1
    s_u = np.zeros((n_out, n_in))
    s_v1, s_vm1 = np.zeros((n_out, n_in)), np.zeros((n_out, n_in))
    s_w1, s_wm1 = np.zeros((n_out, n_in)), np.zeros((n_out, n_in))

    def put(mat: FloatArray, a: int, weight: float) -> None:
        if abs(a) <= l - 1 and weight != 0.0:
            mat[m + l, a + l - 1] += weight

    for m in range(-l, l + 1):
        put(s_u, m, 1.0)
        d1 = 1.0 if m in (1, -1) else 0.0
        if m == 0:  # V = P_1(1, n) + P_-1(-1, n); W unused (w = 0)
            put(s_v1, 1, 1.0)
            put(s_vm1, -1, 1.0)
        elif m > 0:
            put(s_v1, m - 1, np.sqrt(1.0 + d1))
            put(s_vm1, -m + 1, -(1.0 - d1))
            put(s_w1, m + 1, 1.0)
            put(s_wm1, -m - 1, 1.0)
        else:
            put(s_v1, m + 1, 1.0 - d1)
            put(s_vm1, -m - 1, np.sqrt(1.0 + d1))
            put(s_w1, m - 1, 1.0)
            put(s_wm1, -m + 1, -1.0)
    return s_u, s_v1, s_vm1, s_w1, s_wm1


@lru_cache(maxsize=64)
def _uvw(l: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Ivanic–Ruedenberg Table 2 coefficients u, v, w for band l, each (2l+1, 2l+1) indexed [m + l, n + l]."""
    m = np.arange(-l, l + 1)[:, None].astype(np.float64)
    n = np.arange(-l, l + 1)[None, :].astype(np.float64)
    d = (m == 0).astype(np.float64)
    denom = np.where(np.abs(n) == l, 2.0 * l * (2.0 * l - 1.0), (l + n) * (l - n))
    am = np.abs(m)
    u = np.sqrt((l + m) * (l - m) / denom)
    v = 0.5 * np.sqrt(np.maximum((1.0 + d) * (l + am - 1.0) * (l + am), 0.0) / denom) * (1.0 - 2.0 * d)
    w = -0.5 * np.sqrt(np.maximum((l - am - 1.0) * (l - am), 0.0) / denom) * (1.0 - d)
    return u, v, w


def band_one(r: FloatArray) -> FloatArray:
    """Band-1 real rotation (..., 3, 3): ``M^1[m', m] = R[axis(m'), axis(m)]`` with axes (y, z, x) for m = -1, 0, 1."""
    ax = list(_BAND1_AXES)
    return np.asarray(r[..., ax, :][..., :, ax], dtype=np.float64)


def band_rotations(r: ArrayLike, lmax: int) -> list[FloatArray]:
    """Real band rotation matrices ``[M^0, ..., M^lmax]``, ``M^l`` of shape (..., 2l+1, 2l+1) (module docstring).

    ``r``: proper rotations (..., 3, 3) acting on SH-frame coordinates.
    """
    if isinstance(lmax, bool) or not isinstance(lmax, (int, np.integer)) or lmax < 0:
        raise InputError(f"lmax must be a non-negative integer, got {lmax!r}")
    rot = check_rotations(r)
    lead = rot.shape[:-2]
    out = [np.ones(lead + (1, 1))]
    if lmax == 0:
        return out
    m1 = band_one(rot)
    out.append(m1)
    for l in range(2, int(lmax) + 1):
        prev = out[-1]  # (..., 2l-1, 2l-1)
        p = {}
        for i in (-1, 0, 1):
            g = np.zeros(lead + (2 * l - 1, 2 * l + 1))
            ri_m1, ri_0, ri_1 = m1[..., i + 1, 0], m1[..., i + 1, 1], m1[..., i + 1, 2]
            idx = np.arange(2 * l - 1)
            g[..., idx, idx + 1] = ri_0[..., None]  # |b| < l: r1(i, 0) M^{l-1}(a, b)
            g[..., 2 * l - 2, 2 * l] = ri_1  # b = l:  r1(i, 1) M(a, l-1) - r1(i, -1) M(a, -l+1)
            g[..., 0, 2 * l] = -ri_m1
            g[..., 0, 0] = ri_1  # b = -l: r1(i, 1) M(a, -l+1) + r1(i, -1) M(a, l-1)
            g[..., 2 * l - 2, 0] = ri_m1
            p[i] = prev @ g
        s_u, s_v1, s_vm1, s_w1, s_wm1 = _band_tables(l)
        u, v, w = _uvw(l)
        out.append(u * (s_u @ p[0]) + v * (s_v1 @ p[1] + s_vm1 @ p[-1]) + w * (s_w1 @ p[1] + s_wm1 @ p[-1]))
    return out


def block_diagonal(blocks: list[FloatArray]) -> FloatArray:
    """The dense (..., n, n) matrix, n = (lmax+1)^2, of per-band blocks (:func:`band_rotations`)."""
    lead = blocks[0].shape[:-2]
    n = len(blocks) ** 2
    out = np.zeros(lead + (n, n))
    for l, b in enumerate(blocks):
        out[..., full_block(l), full_block(l)] = b
    return out


def rotate_coefficients(blocks: list[FloatArray], coeffs: ArrayLike) -> FloatArray:
    """``c' = M c`` per band: ``coeffs`` (..., n, C) with n = (lmax+1)^2 (channels last), broadcast against the
    blocks' leading shape; returns (broadcast lead, n, C)."""
    c = np.asarray(coeffs, dtype=np.float64)
    lmax = len(blocks) - 1
    if c.ndim < 2 or c.shape[-2] != full_size(lmax):
        raise InputError(f"coefficients must have shape (..., {full_size(lmax)}, C) for lmax = {lmax}, got {c.shape}")
    parts = [b @ c[..., full_block(l), :] for l, b in enumerate(blocks)]
    return np.concatenate(parts, axis=-2)


def band_signs(lmax: int) -> FloatArray:
    """``(-1)^l`` for each of the (lmax+1)^2 coefficients: the real coefficients of ``f(-x)`` (parity)."""
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    return np.where(l % 2 == 0, 1.0, -1.0)


def local_rotations(frames: ArrayLike, lmax: int) -> list[FloatArray]:
    """Per-band matrices taking relight's *world* lighting coefficients to a point's *local* coefficients.

    ``frames`` (..., 3, 3): rows ``(t, b, n)`` in world coordinates, orthonormal, of either handedness. The local
    coefficients are those of ``L(F^T u)`` expanded in ``Yr`` of the local coordinates ``u = (x, y, z) = (t.w,
    b.w, n.w)`` taken as SH-frame coordinates. The world SH frame is the mirror ``P = SH_FROM_WORLD`` of the world
    (docs/conventions.md, "Parity"), so ``L_local(u) = L_sh(Q u)`` with ``Q = P F^T``. For a right-handed frame
    ``det Q = -1``: ``Q = -(-Q)`` with ``-Q`` proper, and ``f(-x)`` has coefficients ``(-1)^l c``, so
    ``M = (-1)^l M(-F P)``. For a mirrored frame (``det F = -1``, e.g. a glTF tangent with w = -1) ``Q`` itself is
    proper and ``M = M(F P)``.
    """
    f = check_rotations(frames, proper=False)
    det = np.linalg.det(f)
    sign = np.where(det > 0.0, -1.0, 1.0)[..., None, None]  # right-handed frames: the inversion trick
    proper = sign * np.einsum("...ij,jk->...ik", f, SH_FROM_WORLD)  # (Q^T) up to the sign: R = -F P or F P
    blocks = band_rotations(proper, lmax)
    return [b * np.where(sign < 0.0, (-1.0) ** l, 1.0) for l, b in enumerate(blocks)]


def rotation_about_z(phi: ArrayLike, lmax: int) -> list[FloatArray]:
    """Band matrices of the rotation by ``phi`` about the SH z axis (closed form: 2 x 2 rotations of (m, -m) pairs).

    ``Yr_{l,m}`` with m > 0 is ``cos(m phi')``-like and m < 0 ``sin``-like, so rotating the field by ``phi`` maps
    ``(c_m, c_-m) -> (cos(m phi) c_m - sin(m phi) c_-m, sin(m phi) c_m + cos(m phi) c_-m)``.
    """
    ph = np.asarray(phi, dtype=np.float64)
    out = []
    for l in range(int(lmax) + 1):
        b = np.zeros(ph.shape + (2 * l + 1, 2 * l + 1))
        b[..., l, l] = 1.0
        for m in range(1, l + 1):
            c, s = np.cos(m * ph), np.sin(m * ph)
            b[..., l + m, l + m] = c
            b[..., l + m, l - m] = -s
            b[..., l - m, l + m] = s
            b[..., l - m, l - m] = c
        out.append(b)
    return out
