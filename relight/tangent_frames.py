"""Tangent frames ``(t, b, n)`` at surface points (seed 003 §4 and §6: the local frame of each point).

Kautz, Sloan & Snyder map a point's normal to +z and "two chosen tangent vectors" to x and y (§4); their
anisotropic images use a "brushing direction derived from projecting a constant vector to the tangent space at each
point" (§6). Three sources of the tangent t are provided, each returning frames (..., 3, 3) whose rows are
``(t, b, n)`` in world coordinates (``docs/conventions.md``, "Tangent frames"):

* :func:`projected_frames` — the constant direction d projected onto the tangent plane, ``t = normalize(d - (d.n)
  n)`` (Kautz et al. §6).
* :func:`azimuthal_frames` — the azimuthal field about an axis a, ``t = normalize(a x n)``; with a = +Y this is
  ``relight.shrm.tangent_field`` (the Kajiya–Kay tangent, seed 000 §7.1) and with a = +Z it is the ``dp/du``
  direction of Mitsuba 3's analytic ``sphere`` shape.
* :func:`mesh_frames` — given per-vertex tangents with a handedness sign (glTF ``TANGENT`` = (x, y, z, w),
  ``b = w (n x t)``, glTF 2.0 §3.7.2.1), re-orthogonalised against n.

Every field of tangents on the sphere vanishes somewhere (hairy-ball theorem): d's field where ``n = +-d``, the
azimuthal one where ``n = +-a``, a mesh tangent where it is zero or parallel to n. There the tangent falls back
to a fixed direction perpendicular to n: the projection of the world axis least aligned with d (or a), i.e.
:func:`fallback_tangent`. The switch happens only when the projected length is below ``SINGULAR_EPS`` = 1e-12;
next to it (1e-8 away) the projection is used, re-orthogonalised twice (Gram–Schmidt, so that the relative
rounding of a tiny projection cannot leave t off the tangent plane). Frames are orthonormal to ~1e-15 everywhere
and never NaN. The bitangent is ``b = n x t`` (right-handed, ``det = +1``) except for mesh tangents with w < 0.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError

FloatArray = NDArray[np.float64]

#: Projected tangent lengths at or below this use the fallback (module docstring).
SINGULAR_EPS = 1e-12


def _unit_rows(v: ArrayLike, what: str) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise InputError(f"{what} must have a trailing axis of length 3, got shape {a.shape}")
    validate.finite_array(what, a)
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if np.any(n == 0.0):
        raise InputError(f"{what} must be non-zero vectors")
    return np.asarray(a / n, dtype=np.float64)


def _project(v: FloatArray, n: FloatArray) -> FloatArray:
    return np.asarray(v - np.einsum("...k,...k->...", v, n)[..., None] * n, dtype=np.float64)


def fallback_tangent(normals: ArrayLike, avoid: ArrayLike) -> FloatArray:
    """A unit tangent at each normal: the world axis least aligned with ``avoid`` (3,), projected on the tangent
    plane; if that projection is degenerate too (n along that axis), the next axis (X, Y, Z order of preference)."""
    n = _unit_rows(normals, "normals")
    d = _unit_rows(avoid, "direction").reshape(3)
    order = np.argsort(np.abs(d), kind="stable")  # least aligned axis first
    out = np.zeros_like(n)
    done = np.zeros(n.shape[:-1], dtype=bool)
    for k in order:
        axis = np.zeros(3)
        axis[k] = 1.0
        p = _project(np.broadcast_to(axis, n.shape), n)
        ln = np.linalg.norm(p, axis=-1)
        use = (~done) & (ln > 0.5)  # an axis orthogonal to d: |p| >= sqrt(1/2) for one of any two axes
        out[use] = p[use] / ln[use][:, None]
        done |= use
    return out


def _tangent_with_fallback(raw: FloatArray, n: FloatArray, avoid: FloatArray) -> FloatArray:
    ln = np.linalg.norm(raw, axis=-1, keepdims=True)
    singular = ln[..., 0] <= SINGULAR_EPS
    t = raw / np.where(singular[..., None], 1.0, ln)
    for _ in range(2):  # Gram–Schmidt twice: a tiny projection's relative rounding is removed
        t = _project(t, n)
        t = t / np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-300)
    if np.any(singular):
        t = np.where(singular[..., None], fallback_tangent(n, avoid), t)
    return np.asarray(t, dtype=np.float64)


def assemble(t: FloatArray, n: FloatArray, sign: ArrayLike = 1.0) -> FloatArray:
    """Frames (..., 3, 3) with rows ``(t, sign (n x t), n)``."""
    s = np.asarray(sign, dtype=np.float64)
    b = np.cross(n, t) * s[..., None] if s.ndim else np.cross(n, t) * float(s)
    return np.asarray(np.stack([t, b, n], axis=-2), dtype=np.float64)


def projected_frames(normals: ArrayLike, direction: ArrayLike) -> FloatArray:
    """Frames whose tangent is the constant ``direction`` projected on each tangent plane (Kautz et al. §6).

    Singular where ``n = +-direction``: there t is :func:`fallback_tangent` (module docstring).
    """
    n = _unit_rows(normals, "normals")
    d = _unit_rows(direction, "direction")
    if d.shape != (3,):
        raise InputError(f"the brushing direction must be one 3-vector, got shape {d.shape}")
    t = _tangent_with_fallback(_project(np.broadcast_to(d, n.shape), n), n, d)
    return assemble(t, n)


def azimuthal_frames(normals: ArrayLike, axis: ArrayLike = (0.0, 1.0, 0.0)) -> FloatArray:
    """Frames with ``t = normalize(axis x n)`` (the azimuthal field; axis +Y = ``relight.shrm.tangent_field``).

    At ``n = +-axis`` t is :func:`fallback_tangent` (for axis +Y that is +X, as ``tangent_field``).
    """
    n = _unit_rows(normals, "normals")
    a = _unit_rows(axis, "axis")
    if a.shape != (3,):
        raise InputError(f"the azimuthal axis must be one 3-vector, got shape {a.shape}")
    raw = np.cross(np.broadcast_to(a, n.shape), n)
    return assemble(_tangent_with_fallback(raw, n, a), n)


def mesh_frames(normals: ArrayLike, tangents: ArrayLike) -> FloatArray:
    """Frames from per-vertex tangents (..., 3) or glTF ``TANGENT`` (..., 4) with handedness w = +-1.

    ``t = normalize(t - (t.n) n)``, ``b = w (n x t)`` (glTF 2.0: "bitangent = cross(normal, tangent.xyz) *
    tangent.w"); w < 0 gives a mirrored frame (det -1), which ``relight.sh_rotation.local_rotations`` handles.
    Where the tangent is zero or parallel to n, t is :func:`fallback_tangent` of the world axis least aligned with n.
    """
    n = _unit_rows(normals, "normals")
    tw = np.asarray(tangents, dtype=np.float64)
    if tw.shape[-1:] not in ((3,), (4,)) or tw.shape[:-1] != n.shape[:-1]:
        raise InputError(f"tangents must have shape {n.shape[:-1] + (3,)} or {n.shape[:-1] + (4,)}, got {tw.shape}")
    validate.finite_array("tangents", tw)
    sign = np.ones(n.shape[:-1])
    if tw.shape[-1] == 4:
        w = tw[..., 3]
        if np.any(np.abs(np.abs(w) - 1.0) > 1e-6):
            raise InputError("glTF tangent w (handedness) must be +1 or -1")
        sign = np.sign(w)
    raw = _project(tw[..., :3], n)
    # the fallback avoids each normal's own dominant axis: use +Y's projection unless n is near +-Y
    t = _tangent_with_fallback(raw, n, np.array([0.0, 1.0, 0.0]))
    return assemble(t, n, sign)


def frame_errors(frames: ArrayLike) -> float:
    """``max |F F^T - I|`` over all frames (orthonormality check)."""
    f = np.asarray(frames, dtype=np.float64)
    return float(np.abs(np.einsum("...ik,...jk->...ij", f, f) - np.eye(3)).max(initial=0.0))
