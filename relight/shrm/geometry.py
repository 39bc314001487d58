"""Directions for SHRM evaluation: unit views, SH angles, the local frame of a lobe centre (seed 000 §4, eq. 3),
lobe centres R / N / T (§3.1), reflection and halfway vectors, and bilinear lat-long lookup.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from relight.conventions import (
    dirs_to_angles,
)
from relight.errors import InputError
from relight.shrm.basis import (
    FloatArray,
)


# ------------------------------------------------------------------------------------------------ geometry
def unit_view(view: NDArray[np.floating] | Sequence[float]) -> FloatArray:
    """A unit view vector from a 3-vector; raises InputError for a wrong shape or zero length."""
    v = np.asarray(view, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(f"a view direction must be 3 finite numbers, got {np.asarray(view).tolist()}")
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise InputError("the view direction must not be zero")
    return np.asarray(v / n, dtype=np.float64)


def local_frame(dirs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """World vectors theta-hat and phi-hat of the local frame at directions C (..., 3) (module docstring)."""
    a, b = dirs_to_angles(dirs)
    th = np.stack([np.cos(a) * np.cos(b), -np.sin(a), np.cos(a) * np.sin(b)], axis=-1)
    ph = np.stack([-np.sin(b), np.zeros_like(b), np.cos(b)], axis=-1)
    return th, ph


def local_view_angles(centres: FloatArray, view: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(theta_o, phi_o) of V (3,) or (..., 3) in the local frames of the centres C (..., 3) (eq. 3)."""
    th, ph = local_frame(centres)
    v = np.broadcast_to(view, centres.shape)
    cz = np.einsum("...k,...k->...", centres, v)
    cx = np.einsum("...k,...k->...", th, v)
    cy = np.einsum("...k,...k->...", ph, v)
    return np.arctan2(np.hypot(cx, cy), cz), np.arctan2(cy, cx)


def tangent_field(normals: FloatArray) -> FloatArray:
    """The tangent T used by T-centred (Kajiya–Kay) lobes: ``T = normalize(+Y x N)`` (horizontal, along the
    latitude circles, like hair combed around the vertical axis); ``T = +X`` where N = +-Y (measure zero)."""
    n = np.asarray(normals, dtype=np.float64)
    t = np.stack([n[..., 2], np.zeros(n.shape[:-1]), -n[..., 0]], axis=-1)
    norm = np.linalg.norm(t, axis=-1, keepdims=True)
    fallback = np.broadcast_to(np.array([1.0, 0.0, 0.0]), t.shape)
    return np.where(norm > 1e-12, t / np.where(norm > 1e-12, norm, 1.0), fallback)


def lobe_centres(center: str, normals: FloatArray, reflected: FloatArray) -> FloatArray:
    """The centre direction C of a lobe for each (N, R): R, N, or the tangent field's T(N) (§3.1)."""
    if center == "R":
        return reflected
    if center == "N":
        return normals
    if center == "T":
        return tangent_field(normals)
    raise InputError(f"unknown lobe centre {center!r}; expected 'R', 'N' or 'T'")


def reflect_dirs(normals: FloatArray, view: FloatArray) -> FloatArray:
    """``R = 2 (N . V) N - V`` (V broadcast)."""
    ndv = np.einsum("...k,...k->...", normals, np.broadcast_to(view, normals.shape))
    return np.asarray(2.0 * ndv[..., None] * normals - view, dtype=np.float64)


def halfway_normals(reflected: FloatArray, view: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """``N = normalize(R + V)`` and a mask of valid pixels (R = -V has no normal)."""
    s = reflected + view
    n = np.linalg.norm(s, axis=-1, keepdims=True)
    ok = n[..., 0] > 1e-9
    return s / np.where(n > 1e-9, n, 1.0), ok

