"""Local -> global SHRM, seed 000 eq. 8 (distant viewer): ``B~_pq(alpha, beta) = e^{-i q beta} sum_s d^p_qs(alpha)
B_ps(alpha, beta)`` (``D^p_sq(-alpha) = d^p_qs(alpha)``; derivation in :mod:`relight.shrm`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from relight import wigner
from relight.conventions import (
    column_phis,
)
from relight.indexing import full_block, full_size
from relight.shrm.basis import (
    FloatArray,
    complex_to_real,
    real_to_complex,
)


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
    out = np.zeros((full_size(p_order),) + maps.shape[1:])
    for p in range(p_order + 1):
        block = np.zeros((2 * p + 1,) + maps.shape[1:])
        for s in range(-p, p + 1):
            if (p, s) in index:
                block[p + s] = maps[index[(p, s)]]
        if not block.any():
            continue
        local = real_to_complex(block, p)  # (2p+1, rows, W, C), index s + p
        dmat = wigner.wigner_d_matrix(p, alphas)  # (rows, 2p+1, 2p+1): [a, q + p, s + p] = d^p_qs(alpha)
        rot = np.einsum("aqs,sabc->qabc", dmat, local)
        qv = np.arange(-p, p + 1)
        rot *= np.exp(-1j * np.outer(qv, betas))[:, None, :, None]
        out[full_block(p)] = complex_to_real(rot, p)
    return out

