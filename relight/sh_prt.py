"""SH tables combined with precomputed transfer: shadowed arbitrary BRDFs (Kautz, Sloan & Snyder 2002, §5).

Per vertex p a transfer matrix ``T_p`` maps the world lighting to the *transferred incident radiance*
``L_p = T_p L'``; shadows only: ``T_p = int V_p Yr_i Yr_j`` (``relight.visibility``, kind ``shadow_matrix``:
symmetric, the Gaunt contraction of the visibility; tested there). The table renderer then runs unchanged on
``L_p``: rotate into the local frame, look the table up at the local view, dot (§4 steps 1–4). As the paper
suggests, the rotation is folded into the matrix once (§5 "As an optimization"):

    T'_p = S M(R_p) T_p      (the parity rule of relight.sh_rotation.local_rotations; docs/conventions.md)

so per frame ``Q_p = c(F_p v) . (T'_p L')``: one (n x n) matrix-vector product per vertex and channel, the
lighting and the view both free. The BRDF is not part of ``T_p`` (shadows only), so the table can be swapped on
the fly. Interreflections (a BRDF-dependent transfer, one matrix per colour channel: (V, n, n, C)) are
``relight.sh_prt_bounce``; both functions here take such matrices as well.

Identity (tests/relight/test_sh_prt.py): with the same ray directions w_s and weights, for lighting band-limited
to the table's order, ``Q_p = (4 pi / R) sum_s V_p(w_s) L(w_s) f*_F(F_p w_s, F_p v)`` exactly (``f*_F`` the
table's order-F product function), because ``T_p`` is that sum's bilinear form and the rotation is exact within a
band. The GPU twin is ``MODE_TRANSFER`` of ``web/shaders/sh_table.vert.glsl``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.errors import InputError
from relight.sh_rotation import block_diagonal, local_rotations
from relight.sh_table import SHTable

FloatArray = NDArray[np.float64]


def folded_transfer(frames: ArrayLike, transfer: ArrayLike, order: int) -> FloatArray:
    """``T'_p = S M(R_p) T_p`` (V, n, n) for frames (V, 3, 3) (rows t, b, n) and world transfer matrices
    (V, n', n') with n' >= n = (order + 1)^2 (the leading n x n block is used: the lighting is order F); with a
    trailing channel axis (V, n', n', C) (interreflected transfer) the result is (V, n, n, C)."""
    f = np.asarray(frames, dtype=np.float64)
    t = np.asarray(transfer, dtype=np.float64)
    n = (order + 1) ** 2
    if t.ndim not in (3, 4) or t.shape[1] != t.shape[2] or t.shape[1] < n or t.shape[0] != f.shape[0]:
        raise InputError(f"transfer must be (V, >= {n}, >= {n}) for {f.shape[0]} frames, got shape {t.shape}")
    rot = block_diagonal(local_rotations(f, order))  # (V, n, n)
    if t.ndim == 4:
        return np.asarray(np.einsum("vij,vjkc->vikc", rot, t[:, :n, :n]), dtype=np.float64)
    return np.asarray(rot @ t[:, :n, :n], dtype=np.float64)


def shade_prt(table: SHTable, lighting: ArrayLike, frames: ArrayLike, view: ArrayLike, folded: ArrayLike, *,
              exact_azimuth: bool = True) -> FloatArray:
    """Radiance (V, 3) toward the distant view (3,) at vertices with frames (V, 3, 3) and folded transfer matrices
    (V, n, n) or (V, n, n, C) (:func:`folded_transfer`), for world lighting ((F'+1)^2, 3), F' >= the table's
    order."""
    f = np.asarray(frames, dtype=np.float64)
    light = np.asarray(lighting, dtype=np.float64)
    tp = np.asarray(folded, dtype=np.float64)
    n = (table.order + 1) ** 2
    if light.ndim != 2 or light.shape[0] < n or light.shape[1] != 3:
        raise InputError(f"lighting must be (>= {n}, 3) real coefficients, got shape {light.shape}")
    if tp.shape[:3] != (f.shape[0], n, n) or tp.ndim not in (3, 4) or (tp.ndim == 4 and tp.shape[3] not in (1, 3)):
        raise InputError(f"folded transfer must be ({f.shape[0]}, {n}, {n}[, C]), got shape {tp.shape}")
    vl = np.einsum("nij,j->ni", f, np.asarray(view, dtype=np.float64))
    coeffs = table.lookup(vl, exact_azimuth=exact_azimuth)  # (V, n, C)
    if tp.ndim == 4:  # per-channel transfer: channel c of the lighting through matrix c
        local = np.einsum("vijc,jc->vic", np.broadcast_to(tp, tp.shape[:3] + (3,)), light[:n])
    else:
        local = np.einsum("vij,jc->vic", tp, light[:n])
    out = np.einsum("vic,vic->vc", local, np.broadcast_to(coeffs, coeffs.shape[:2] + (3,)))
    return np.where((vl[:, 2] > 0.0)[:, None], out, 0.0)
