"""Reference integrators for the PRT tests (tests/relight/test_sh_prt_bounce.py, test_sh_prt_mitsuba.py): no SH."""

from __future__ import annotations

import numpy as np

from relight.brdf.frame import FrameBRDF
from relight.conventions import latlong_dirs, pixel_solid_angles
from relight.raycast import RayCaster


def brute_force_direct(caster: RayCaster, points: np.ndarray, normals: np.ndarray, frames: np.ndarray,
                       brdf: FrameBRDF, pixels: np.ndarray, view: np.ndarray, offset: float,
                       shadows: bool = True) -> np.ndarray:
    """``sum_p L_p V(x, w_p) f*(F_x w_p, F_x v) dOmega_p`` over every map pixel, (P, 3) (V = 1 without
    ``shadows``)."""
    h, w = pixels.shape[:2]
    dirs = latlong_dirs(h, w).reshape(-1, 3)
    weight = (pixels * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    vl = np.einsum("pij,j->pi", frames, view)
    out = np.zeros((points.shape[0], 3))
    origins = (points + offset * normals).astype(np.float32)
    for s0 in range(0, dirs.shape[0], 256):
        d = dirs[s0 : s0 + 256]
        local = np.einsum("pij,sj->psi", frames, d)  # (P, S, 3)
        above = np.einsum("pk,sk->ps", normals, d) > 0.0
        rows, cols = np.nonzero(above)
        vis = np.zeros(above.shape)
        vis[rows, cols] = ~caster.occluded(origins[rows], d[cols].astype(np.float32)) if shadows else 1.0
        f = brdf.fcos_local(local, vl[:, None, :])  # (P, S, C)
        out += np.einsum("ps,psc,sc->pc", vis, np.broadcast_to(f, f.shape[:2] + (3,)), weight[s0 : s0 + 256])
    return out
