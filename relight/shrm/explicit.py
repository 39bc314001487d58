"""Explicit forms of an SHRM (seed 000 App. C "conversion to explicit forms"): Cabral et al. 1999's 12 icosahedron
views, T_B x T_B view sets, and Kautz & McCool's 3-D texture.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import (
    dirs_to_angles,
    latlong_dirs,
    ring_thetas,
)
from relight.indexing import full_index
from relight.shrm.basis import (
    FloatArray,
    real_harmonics,
)
from relight.shrm.evaluation import reflect
from relight.shrm.model import SHRM, SHRMComponent


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
    validate.at_least("T_B", t_b, 1)
    t = ring_thetas(t_b)[:, None]
    p = ((np.arange(t_b) + 0.5) / t_b - 0.5)[None, :] * 2.0 * np.pi
    st = np.sin(t)
    return np.stack(np.broadcast_arrays(st * np.cos(p), np.cos(t), st * np.sin(p)), axis=-1)


def explicit_maps(shrm: SHRM, views: FloatArray, *, clamp: bool = True) -> NDArray[np.float32]:
    """Reflection maps (eq. 12) for many views at once (App. C "conversion to explicit forms"), (n, S, 2S, 3).

    Cabral's 12 maps: ``explicit_maps(shrm, icosahedron_views())``; a T_B x T_B set: ``view_grid(T_B)``. For
    R-centred general components the maps are one matrix product ``Yr(V_k) @ B~r`` (O(P^2) per output pixel).
    ``clamp``: negative radiance reads 0, as in ``relight.shrm.reflect`` (``relight.shrm.evaluation``).
    """
    vs = np.asarray(views, dtype=np.float64).reshape(-1, 3)
    vs = vs / np.linalg.norm(vs, axis=1, keepdims=True)
    s = shrm.height
    out = np.zeros((vs.shape[0], s, 2 * s, 3), dtype=np.float32)
    fast = [c for c in shrm.components if c.center == "R" and c.structure == "general"]
    for comp in fast:
        theta_v, phi_v = dirs_to_angles(vs)
        y = real_harmonics(comp.P, theta_v, phi_v)  # (n, K)
        g = comp.global_maps().reshape(y.shape[1], -1)
        for k0 in range(0, vs.shape[0], 16):  # bounded float64 temporaries
            out[k0 : k0 + 16] += (y[k0 : k0 + 16] @ g).reshape((-1,) + out.shape[1:]).astype(np.float32)
    rest = SHRM([c for c in shrm.components if not any(c is f for f in fast)])
    r = latlong_dirs(s, 2 * s)
    for k, v in enumerate(vs):
        if rest.components:
            out[k] += reflect(rest, v, clamp=False).astype(np.float32)
        out[k][np.linalg.norm(r + v, axis=-1) <= 1e-9] = 0.0  # R = -V has no normal: 0, as in reflect()
    return np.maximum(out, np.float32(0.0)) if clamp else out


def kautz_mccool_texture(comp: SHRMComponent, n_theta: int) -> NDArray[np.float32]:
    """Kautz & McCool's 3-D texture ``B(alpha, beta, theta_o) = sum_p B_p0 Y_p0(theta_o)`` (App. C), q = 0 only.

    ``theta_o`` at the midpoints ``(k + 1/2) pi / n_theta``; shape (n_theta, S, 2S, 3).
    """
    validate.at_least("n_theta", n_theta, 1)
    theta = ring_thetas(n_theta)
    y = real_harmonics(comp.P, theta, np.zeros_like(theta))  # (n, (P+1)^2)
    out = np.zeros((n_theta,) + comp.maps.shape[1:])
    for k, (p, q) in enumerate(comp.terms):
        if q == 0:
            out += y[:, full_index(p, 0)][:, None, None, None] * comp.maps[k][None]
    return out.astype(np.float32)

