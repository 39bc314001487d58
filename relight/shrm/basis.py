"""The SHRM's real basis in the outgoing direction (seed 000 §4 eq. 6; storage as ``relight.sh.to_real``).

``Yr_p0 = Y_p0``, ``Yr_{p,q>0} = sqrt2 (-1)^q Re Y_pq``, ``Yr_{p,q<0} = sqrt2 (-1)^q Im Y_{p|q|}``; a real field's
complex ``B_pq`` and real ``Br_pq`` convert with :func:`real_to_complex` / :func:`complex_to_real`. Which terms a
lobe needs (radial: one map; azimuthal: q = 0; general: (P + 1)^2) is :func:`terms_for` / :func:`structure_of`.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from relight import sh
from relight.brdf.base import Lobe
from relight.indexing import full_index, full_size

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Structure = Literal["radial", "azimuthal", "general"]
Backend = Literal["ducc0", "wigner"]

SQRT2 = math.sqrt(2.0)
#: Y_00 = 1 / sqrt(4 pi)
Y00 = 1.0 / math.sqrt(4.0 * math.pi)


# ---------------------------------------------------------------------------------------------- terms
def terms_for(structure: Structure, p_order: int) -> list[tuple[int, int]]:
    """The (p, q) terms stored for a component: [(0,0)]; [(p,0)]; or all (p, q) in the ``full`` layout's order
    (:func:`relight.indexing.full_index`)."""
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
    ((P+1)^2,), indexed by :func:`relight.indexing.full_index`.

    From ``relight.sh.legendre_rows`` (``Y_pq = Pbar_pq(cos theta) e^{i q phi}``, CS phase).
    """
    t, ph_full = np.broadcast_arrays(np.asarray(theta, dtype=np.float64), np.asarray(phi, dtype=np.float64))
    ph = ph_full.ravel()
    out = np.zeros((t.size, full_size(p_order)))
    with np.errstate(invalid="ignore"):  # sh.legendre_rows forms 0 * log(0) at the poles (then discards it)
        rows = list(sh.legendre_rows(p_order, t.ravel()))
    for p, row in enumerate(rows):
        out[:, full_index(p, 0)] = row[0]
        for q in range(1, p + 1):
            sign = SQRT2 * (-1.0) ** q
            out[:, full_index(p, q)] = sign * row[q] * np.cos(q * ph)
            out[:, full_index(p, -q)] = sign * row[q] * np.sin(q * ph)
    return out.reshape(t.shape + (full_size(p_order),))


def real_to_complex(block: FloatArray, p: int) -> ComplexArray:
    """Complex ``B_ps`` (axis 0 indexed s + p) from real ``Br_ps`` (axis 0 indexed s + p) — ``sh.from_real``."""
    out = np.zeros(block.shape, dtype=np.complex128)
    out[p] = block[p]
    for s in range(1, p + 1):
        sign = (-1.0) ** s
        out[p + s] = sign * (block[p + s] - 1j * block[p - s]) / SQRT2
        out[p - s] = (block[p + s] + 1j * block[p - s]) / SQRT2  # (-1)^s conj(B_ps)
    return out


def complex_to_real(block: ComplexArray, p: int) -> FloatArray:
    """Inverse of :func:`real_to_complex` for a real field (uses q >= 0 only) — ``sh.to_real``."""
    out = np.zeros(block.shape, dtype=np.float64)
    out[p] = block[p].real
    for q in range(1, p + 1):
        sign = SQRT2 * (-1.0) ** q
        out[p + q] = sign * block[p + q].real
        out[p - q] = -sign * block[p + q].imag
    return out


