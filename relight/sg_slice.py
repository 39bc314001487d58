"""The cosine-weighted BRDF slice ``T_theta_o`` of seed 002 (Green, Kautz & Durand 2007, §3.1, eq. 2) on a grid.

For a view at elevation theta_o (normal n = +z, view ``v = (sin theta_o, 0, cos theta_o)``, mirror direction
``r = (-sin theta_o, 0, cos theta_o)``), ``T(w) = f(w, v, n) max(w . n, 0)``, 0 below the horizon (the fit runs over
the whole sphere so a lobe leaking below the horizon is penalised, ``docs/conventions.md``).

Grid: polar about r, in the frame ``(e_r, e_1, e_2) = (r, rotation of r by 90 degrees toward n, +y)``; a direction
is ``cos(gamma) e_r + sin(gamma) (cos(psi) e_1 + sin(psi) e_2)``. ``gamma = pi u^2`` with midpoint nodes in u (nodes
crowd next to r, where sharp lobes live: 320 nodes put the first at 8e-6 rad and space them 0.08 degrees at 1
degree), ``psi`` midpoint nodes on [0, pi] only: isotropic BRDFs are symmetric about the plane of incidence, so
each node stands for its mirror image too (weight doubled). The grid does not depend on theta_o: a lobe centred on
r rotated by mu toward n has ``t = cos(gamma) cos(mu) + sin(gamma) cos(psi) sin(mu)`` at every elevation.

``T`` of any isotropic BRDF: ``IsotropicBRDF.f`` (analytic, MERL, ``.npz``), R-centred radial lobes ``u(r . w)``
(Phong, vMF), N-centred ones ``u(n . w)`` (Lambert), sums of these. MERL files: samples whose trilinear lookup
touches a missing (negative) entry are masked out (weight 0) instead of being fitted as zeros.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import IsotropicBRDF, Lobe, RadialLobe
from relight.brdf.measured import MERL_DIMS, MERLBRDF, half_diff_angles, trilinear
from relight.brdf.models import SumBRDF
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: Default grid (the design notes' measured setting: enough for alpha >= 0.1, seed-002 notes §2.4 item 4).
N_GAMMA, N_PSI = 320, 48


@dataclass(frozen=True)
class SliceGrid:
    """Nodes (cos gamma, sin gamma cos psi, sin gamma sin psi) in the (e_r, e_1, e_2) frame and solid-angle weights
    (doubled for the mirror half)."""

    local: FloatArray  # (M, 3)
    weights: FloatArray  # (M,)

    @property
    def size(self) -> int:
        return int(self.weights.size)

    def world(self, theta_o: float) -> FloatArray:
        """World directions (M, 3) of the nodes for elevation theta_o (n = +z, v in the +x half of the xz plane)."""
        s, c = math.sin(theta_o), math.cos(theta_o)
        e_r = np.array([-s, 0.0, c])
        e_1 = np.array([c, 0.0, s])
        e_2 = np.array([0.0, 1.0, 0.0])
        return np.asarray(np.outer(self.local[:, 0], e_r) + np.outer(self.local[:, 1], e_1)
                          + np.outer(self.local[:, 2], e_2), dtype=np.float64)


def slice_grid(n_gamma: int = N_GAMMA, n_psi: int = N_PSI) -> SliceGrid:
    """The polar grid of the module docstring (``gamma = pi u^2``, midpoint rule in u and psi)."""
    if n_gamma < 4 or n_psi < 2:
        raise InputError(f"slice grid needs n_gamma >= 4 and n_psi >= 2, got {n_gamma}, {n_psi}")
    u = (np.arange(n_gamma) + 0.5) / n_gamma
    gamma = np.pi * u * u
    wg = 2.0 * np.pi * u / n_gamma * np.sin(gamma)
    psi = (np.arange(n_psi) + 0.5) * np.pi / n_psi
    wp = np.full(n_psi, 2.0 * np.pi / n_psi)  # doubled: each node also stands for its mirror (psi -> -psi)
    g, p = np.meshgrid(gamma, psi, indexing="ij")
    local = np.stack([np.cos(g), np.sin(g) * np.cos(p), np.sin(g) * np.sin(p)], axis=-1).reshape(-1, 3)
    return SliceGrid(local=local, weights=(wg[:, None] * wp[None, :]).ravel())


@functools.lru_cache(maxsize=4)
def merl_missing(path: str) -> NDArray[np.bool_]:
    """Mask (90, 90, 180) of samples missing in a MERL file (negative in any channel)."""
    with Path(path).open("rb") as fh:
        fh.read(12)
        raw = np.frombuffer(fh.read(), dtype="<f8")
    return np.asarray((raw.reshape((3,) + MERL_DIMS) < 0.0).any(axis=0))


def _lobes(brdf: Lobe | SumBRDF) -> list[Lobe]:
    return list(brdf.lobes) if isinstance(brdf, SumBRDF) else [brdf]


def transfer_slice(brdf: Lobe | SumBRDF, grid: SliceGrid, theta_o: float) -> tuple[FloatArray, FloatArray]:
    """``T`` at the grid's nodes for elevation theta_o, shape (M, C) (C = 1 or 3), and a validity mask (M,) as
    float (0 where a MERL lookup touches a missing sample)."""
    validate.in_range("theta_o", theta_o, 0.0, math.pi / 2, hi_open=True)
    w = grid.world(theta_o)
    n = np.array([0.0, 0.0, 1.0])
    v = np.array([math.sin(theta_o), 0.0, math.cos(theta_o)])
    r = np.array([-v[0], 0.0, v[2]])
    cos_i = w[:, 2]
    up = cos_i > 0.0
    channels = max(lobe.channels for lobe in _lobes(brdf))
    total = np.zeros((w.shape[0], channels))
    valid = np.ones(w.shape[0])
    for lobe in _lobes(brdf):
        if isinstance(lobe, IsotropicBRDF):
            wi = w[up]
            val = np.zeros((w.shape[0], lobe.channels))
            fr = np.asarray(lobe.f(wi, np.broadcast_to(v, wi.shape), np.broadcast_to(n, wi.shape)), dtype=np.float64)
            val[up] = fr.reshape(wi.shape[0], -1) * cos_i[up, None]
            if isinstance(lobe, MERLBRDF):
                th, td, pd = half_diff_angles(wi, np.broadcast_to(v, wi.shape), np.broadcast_to(n, wi.shape))
                miss = trilinear(merl_missing(lobe.path)[..., None].astype(np.float64), lobe.grids, th, td, pd)[:, 0]
                valid[np.flatnonzero(up)[miss > 1e-9]] = 0.0
        elif isinstance(lobe, RadialLobe):
            if lobe.center == "R":
                t = w @ r
            elif lobe.center == "N":
                t = cos_i
            else:
                raise InputError(f"{lobe.kind}: a {lobe.center}-centred lobe is not an isotropic BRDF; cannot fit "
                                 "Gaussian lobes to it")
            val = np.asarray(lobe.u(t), dtype=np.float64).reshape(w.shape[0], -1)
        else:
            raise InputError(f"{lobe.kind}: only isotropic BRDFs can be fitted with Gaussian lobes")
        total = total + val
    total = np.where(up[:, None], total, 0.0)
    if not np.all(np.isfinite(total)):
        raise InputError(f"the BRDF is not finite at theta_o = {math.degrees(theta_o):.3g} degrees")
    return np.asarray(total, dtype=np.float64), valid
