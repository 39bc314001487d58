"""Shading with per-view SH tables (Kautz, Sloan & Snyder 2002, §4 "Rendering Algorithm", eq. 1), on the CPU.

At each point p with frame F_p (rows t, b, n; ``relight.tangent_frames``):

1. rotate the world lighting coefficients into the local frame, ``L_p = (-1)^l M(-F_p P) L'`` (the parity rule of
   ``relight.sh_rotation.local_rotations``, docs/conventions.md);
2. rotate the view into the local frame, ``v_p = F_p v'``;
3. look the table up at v_p (``relight.sh_table.SHTable.lookup``);
4. ``Q_p = sum_i L_{p,i} c_i(v_p)`` (eq. 1), per colour channel.

Lighting (§3 "Calculating Lighting Coefficients"): an environment map's real coefficients to order F
(``relight.sh.project`` + ``to_real``: quadrature over the pixels, docs/conventions.md), rotatable
(:func:`rotate_lighting`), plus circular area lights in closed form (:func:`cap_light`). Windowing against ringing
(:func:`window_lighting`) multiplies band l by ``sigma_l`` (``relight.brdf.coefficients.window_factors``) and
states its cost: the relative L2 change of the lighting, ``sqrt(sum_l (1 - sigma_l)^2 E_l / sum_l E_l)`` with E_l
the lighting's band energies — the blur a windowed render trades for less negative light.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import sh, validate
from relight.brdf.coefficients import window_factors
from relight.errors import InputError
from relight.sh_rotation import SH_FROM_WORLD, band_rotations, local_rotations, rotate_coefficients
from relight.sh_table import SHTable
from relight.shrm import real_harmonics, sphere_geometry, unit_view
from relight.tangent_frames import azimuthal_frames, mesh_frames, projected_frames

FloatArray = NDArray[np.float64]


def environment_coefficients(pixels: ArrayLike, order: int) -> FloatArray:
    """Real world-SH coefficients ((F+1)^2, 3) of an (H, 2H, 3) lat-long map (docs/conventions.md)."""
    p = np.asarray(pixels, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise InputError(f"the environment map must be (H, W, 3), got shape {p.shape}")
    return np.asarray(sh.to_real(sh.project(p, order), order).T)


def sh_frame_dirs(world: ArrayLike) -> FloatArray:
    """SH-frame coordinates ``(X, Z, Y)`` of world directions (..., 3)."""
    return np.asarray(np.asarray(world, dtype=np.float64) @ SH_FROM_WORLD.T)


def evaluate_world(coeffs: ArrayLike, world_dirs: ArrayLike) -> FloatArray:
    """``sum_i c_i Yr_i(w)`` at world directions (..., 3) for real world coefficients (n, C): (..., C)."""
    c = np.asarray(coeffs, dtype=np.float64)
    order = int(round(np.sqrt(c.shape[0]))) - 1
    d = sh_frame_dirs(world_dirs)
    th = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    return np.asarray(real_harmonics(order, th, np.arctan2(d[..., 1], d[..., 0])) @ c)


def rotate_lighting(coeffs: ArrayLike, rotation: ArrayLike) -> FloatArray:
    """Coefficients of the environment turned by the world rotation R (3, 3): ``L'(w) = L(R^-1 w)``.

    In the SH frame the rotation is ``P R P`` (proper: det P^2 = 1).
    """
    c = np.asarray(coeffs, dtype=np.float64)
    order = int(round(np.sqrt(c.shape[0]))) - 1
    r_sh = SH_FROM_WORLD @ np.asarray(rotation, dtype=np.float64) @ SH_FROM_WORLD
    return rotate_coefficients(band_rotations(r_sh, order), c)


def cap_light(direction: ArrayLike, solid_angle: float, color: ArrayLike, order: int) -> FloatArray:
    """Real coefficients ((F+1)^2, 3) of a circular light of constant radiance ``color`` over the cap of
    ``solid_angle`` (steradians, in (0, 4 pi]) about the world ``direction``.

    Zonal coefficients about the axis (the paper's "simple formula"): with ``t = cos a = 1 - Omega / (2 pi)``,
    ``z_0 = 2 pi (1 - t) Y_00`` and ``z_l = 2 pi sqrt((2l+1)/(4 pi)) (P_{l-1}(t) - P_{l+1}(t)) / (2l+1)``; rotated to d
    by the addition theorem, ``L_lm = sqrt(4 pi / (2l+1)) z_l Yr_lm(d)``.
    """
    om = float(solid_angle)
    if not (np.isfinite(om) and 0.0 < om <= 4.0 * np.pi):
        raise InputError(f"a cap light's solid_angle must lie in (0, 4 pi], got {solid_angle!r}")
    d = np.asarray(direction, dtype=np.float64)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.any(d != 0.0):
        raise InputError(f"a cap light's direction must be a non-zero 3-vector, got {np.asarray(direction).tolist()}")
    col = np.broadcast_to(np.asarray(color, dtype=np.float64), (3,))
    t = 1.0 - om / (2.0 * np.pi)
    leg = np.polynomial.legendre.legvander(np.array([t]), order + 1)[0]  # P_0..P_{F+1}(t)
    z = np.zeros(order + 1)
    z[0] = 2.0 * np.pi * (1.0 - t) * np.sqrt(1.0 / (4.0 * np.pi))
    for l in range(1, order + 1):
        z[l] = 2.0 * np.pi * np.sqrt((2 * l + 1) / (4.0 * np.pi)) * (leg[l - 1] - leg[l + 1]) / (2 * l + 1)
    ds = sh_frame_dirs(d / np.linalg.norm(d))
    y = real_harmonics(order, np.arctan2(np.hypot(ds[0], ds[1]), ds[2]), np.arctan2(ds[1], ds[0]))
    l_of = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    return np.asarray((np.sqrt(4.0 * np.pi / (2 * l_of + 1)) * z[l_of] * y)[:, None] * col[None, :])


def window_lighting(coeffs: ArrayLike, kind: str) -> tuple[FloatArray, float]:
    """Windowed coefficients and the stated cost: the relative L2 change of the lighting (module docstring)."""
    c = np.asarray(coeffs, dtype=np.float64)
    order = int(round(np.sqrt(c.shape[0]))) - 1
    try:
        w = window_factors(order, kind)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    l_of = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    out = c * w[l_of][:, None]
    e = float(np.sum(c**2))
    cost = float(np.sqrt(np.sum((c - out) ** 2) / e)) if e > 0.0 else 0.0
    return out, cost


def local_view(frames: ArrayLike, view: ArrayLike) -> FloatArray:
    """``F v`` per point: the view in each local frame, (N, 3)."""
    return np.asarray(np.einsum("nij,...j->n...i", np.asarray(frames, np.float64), np.asarray(view, np.float64)))


def shade(table: SHTable, lighting: ArrayLike, frames: ArrayLike, view: ArrayLike, *,
          exact_azimuth: bool = True) -> FloatArray:
    """Radiance (N, 3) toward the distant view (3,) (or per point (N, 3)) at points with frames (N, 3, 3), for world
    lighting coefficients ((F'+1)^2, 3) with F' >= the table's order (higher bands are ignored: eq. 1 needs only
    the table's)."""
    f = np.asarray(frames, dtype=np.float64)
    light = np.asarray(lighting, dtype=np.float64)
    n = (table.order + 1) ** 2
    if light.ndim != 2 or light.shape[0] < n or light.shape[1] != 3:
        raise InputError(f"lighting must be (>= {n}, 3) real coefficients, got shape {light.shape}")
    v = np.asarray(view, dtype=np.float64)
    vl = np.einsum("nij,nj->ni", f, np.broadcast_to(v, f.shape[:-1]))
    coeffs = table.lookup(vl, exact_azimuth=exact_azimuth)  # (N, n, C)
    local = rotate_coefficients(local_rotations(f, table.order), light[:n][None])  # (N, n, 3)
    out = np.einsum("nic,nic->nc", local, np.broadcast_to(coeffs, coeffs.shape[:2] + (3,)))
    return np.where((vl[:, 2] > 0.0)[:, None], out, 0.0)


def frames_for(normals: ArrayLike, tangent: dict[str, Any] | None) -> FloatArray:
    """Frames from a tangent spec: ``{"kind": "azimuthal", "axis": [x, y, z]}`` (default axis +Y),
    ``{"kind": "project", "direction": [x, y, z]}`` or ``{"kind": "mesh", "tangents": array}``."""
    spec = {"kind": "azimuthal"} if tangent is None else dict(tangent)
    kind = spec.pop("kind", None)
    if kind == "azimuthal":
        return azimuthal_frames(normals, spec.get("axis", (0.0, 1.0, 0.0)))
    if kind == "project":
        if "direction" not in spec:
            raise InputError("tangent kind 'project' needs a direction")
        return projected_frames(normals, spec["direction"])
    if kind == "mesh":
        if "tangents" not in spec:
            raise InputError("tangent kind 'mesh' needs tangents")
        return mesh_frames(normals, spec["tangents"])
    raise InputError(f"unknown tangent kind {kind!r}; valid kinds are ['azimuthal', 'mesh', 'project']")


def render_sphere(table: SHTable, lighting: ArrayLike, view: ArrayLike, size: int, *,
                  tangent: dict[str, Any] | None = None, supersample: int = 1,
                  exact_azimuth: bool = True) -> FloatArray:
    """CPU image (size, size, 3) of the unit sphere of ``relight.shrm.sphere_geometry`` (Mitsuba's orthographic
    camera) shaded by the table; ``supersample`` x ``supersample`` samples per pixel, averaged."""
    v = unit_view(np.asarray(view, dtype=np.float64))
    validate.at_least("size", size, 1)
    validate.at_least("supersample", supersample, 1)
    big = size * supersample
    n, mask = sphere_geometry(v, big)
    img = np.zeros((big, big, 3))
    img[mask] = shade(table, lighting, frames_for(n[mask], tangent), v, exact_azimuth=exact_azimuth)
    return np.asarray(img.reshape(size, supersample, size, supersample, 3).mean(axis=(1, 3)))
