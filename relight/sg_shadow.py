"""Glossy shadows from per-vertex SH visibility (Green, Kautz & Durand 2007, §3.3, eq. 7; §7's admitted error).

Eq. 7 pulls the visibility out of each lobe's integral and takes it at the lobe's centre c_k::

    L_o = sum_k w_k V(c_k) (G_{sigma_k} * L)(c_k)

with V the vertex's visibility in real SH of order F (``relight.visibility``: ``v_j = int V Yr_j dw`` in the world
frame, F = 3 is the paper's 16 coefficients), interpolated to the pixel with the hit's barycentrics (what the viewer
draws). Modes (:data:`MODES`):

* ``none``: V = 1 (eq. 5);
* ``ao``: the ambient occlusion of the paper's Fig. 7, the visible fraction of the upper hemisphere, from the DC
  term: ``2 Y00 v_0`` (the lower hemisphere of a vertex on a closed mesh is always blocked by the surface itself,
  so the sphere's visible fraction ``Y00 v_0`` is half the hemisphere's), the same for every lobe;
* ``sh``: eq. 7, ``V(c_k) = sum_j v_j Yr_j(c_k)`` (the order-F truncation rings: V can leave [0, 1]);
* ``sh-lobe``: the lobe-averaged visibility ``(G_{sigma_k} * V)(c_k) = sum_lm a_l(kappa_k) v_lm Yr_lm(c_k)`` with
  the vMF's Legendre factors ``a_l = I_{l+1/2}(kappa) / I_{1/2}(kappa)`` (``relight.brdf.vmf.vmf_transfer``):
  ``int G V L ~= (G * V)(c) (G * L)(c)``, exact whenever V or L is constant over the lobe, where the paper's point
  value is exact only when V is (design notes §2.6). F + 1 extra multiplies per lobe.

Every mode clamps V to [0, 1] (design notes §2.4 item 9); :func:`lobe_visibility` also returns the unclamped
values so callers report their range.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.vmf import sigma_to_kappa
from relight.errors import InputError
from relight.shrm import Y00
from relight.visibility import sh_basis

FloatArray = NDArray[np.float64]
MODES: Final = ("none", "ao", "sh", "sh-lobe")


def vmf_band_factors(sigma: NDArray[np.floating], lmax: int) -> FloatArray:
    """``a_l = I_{l+1/2}(kappa) / I_{1/2}(kappa)``, kappa = 1 / sigma^2, for l = 0..lmax: (..., lmax + 1).

    Vectorised ``relight.brdf.vmf.vmf_transfer``; where ``ive`` fails (kappa ~ 1e10 on) the large-kappa asymptote
    ``exp(-l (l + 1) / (2 kappa))``, as there."""
    from scipy import special

    k = np.asarray(sigma_to_kappa(np.asarray(sigma, dtype=np.float64)), dtype=np.float64)[..., None]
    l = np.arange(lmax + 1, dtype=np.float64)
    with np.errstate(under="ignore", invalid="ignore", divide="ignore", over="ignore"):
        ratio = special.ive(l + 0.5, k) / special.ive(0.5, k)
    asym = np.exp(-l * (l + 1.0) / (2.0 * np.maximum(k, 1e-300)))
    out = np.where(np.isfinite(ratio), ratio, asym)
    return np.asarray(np.clip(out, 0.0, 1.0), dtype=np.float64)


def order_of(coefficients: NDArray[np.floating]) -> int:
    """The order F of (..., (F+1)^2) coefficients."""
    n = int(np.asarray(coefficients).shape[-1])
    f = int(round(np.sqrt(n))) - 1
    if (f + 1) ** 2 != n:
        raise InputError(f"visibility needs (F+1)^2 coefficients per vertex, got {n}")
    return f


def lobe_visibility(coefficients: NDArray[np.floating], centres: NDArray[np.floating],
                    sigma: NDArray[np.floating], mode: str, order: int | None = None
                    ) -> tuple[FloatArray, FloatArray]:
    """Visibility weights (P, K) in [0, 1] and their unclamped values for SH visibility (P, (F+1)^2) at P points,
    lobe centres (P, K, 3) and widths (P, K) (module docstring); ``order`` truncates the coefficients (F = 1, 2, 3
    are the viewer's 4, 9, 16)."""
    if mode not in MODES:
        raise InputError(f"unknown visibility mode {mode!r}; expected one of {', '.join(MODES)}")
    c = np.asarray(centres, dtype=np.float64)
    p, k = c.shape[:2]
    if mode == "none":
        ones = np.ones((p, k))
        return ones, ones
    v = np.asarray(coefficients, dtype=np.float64)
    if v.ndim != 2 or v.shape[0] != p:
        raise InputError(f"visibility coefficients must be ({p}, (F+1)^2), got {v.shape}")
    f = order_of(v) if order is None else int(order)
    validate.int_in_range("visibility order", f, 0, order_of(v))
    v = v[:, : (f + 1) ** 2]
    if mode == "ao":
        raw = np.repeat(2.0 * Y00 * v[:, :1], k, axis=1)
    else:
        basis = sh_basis(c.reshape(-1, 3), f).reshape(p, k, -1)
        if mode == "sh-lobe":
            a = vmf_band_factors(np.asarray(sigma, dtype=np.float64), f)  # (P, K, F + 1)
            l_of = np.repeat(np.arange(f + 1), 2 * np.arange(f + 1) + 1)
            basis = basis * a[..., l_of]
        raw = np.einsum("pkj,pj->pk", basis, v)
    return np.asarray(np.clip(raw, 0.0, 1.0), dtype=np.float64), np.asarray(raw, dtype=np.float64)
