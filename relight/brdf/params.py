"""Parameters of the analytic BRDF models (``relight.brdf.models``, ``relight.brdf.microfacet``,
``relight.brdf.anisotropic``): numbers and colours validated on construction (NaN, inf or out-of-range values raise
``InputError`` naming the model, the field and the value; a colour is one number (grey) or 3 (RGB)), and the
direction helpers the models share."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from relight.brdf.base import FloatArray
from relight.errors import InputError

Color = float | list[float]


def check_number(
    owner: str,
    name: str,
    value: Any,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """A finite real number in the given range, or ``InputError`` naming ``owner.name`` and the value."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{owner}: {name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{owner}: {name} must be finite, got {value!r}")
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise InputError(f"{owner}: {name} must be {'>' if lo_open else '>='} {lo:g}, got {value!r}")
    if hi is not None and (v > hi or (hi_open and v == hi)):
        raise InputError(f"{owner}: {name} must be {'<' if hi_open else '<='} {hi:g}, got {value!r}")
    return v


def check_color(
    owner: str, name: str, value: Any, *, lo: float | None = None, hi: float | None = None, lo_open: bool = False
) -> tuple[FloatArray, Color]:
    """A grey (1 number) or RGB (3 numbers) parameter: ``(array of shape (c,), canonical JSON value)``."""
    if isinstance(value, (list, tuple, np.ndarray)):
        items = list(np.asarray(value, dtype=object).ravel()) if isinstance(value, np.ndarray) else list(value)
        if len(items) not in (1, 3):
            raise InputError(f"{owner}: {name} must be one number or 3 (RGB), got {len(items)} values")
        vals = [check_number(owner, name, x, lo=lo, hi=hi, lo_open=lo_open) for x in items]
        if len(vals) == 1:
            return np.array(vals), vals[0]
        return np.array(vals), vals
    v = check_number(owner, name, value, lo=lo, hi=hi, lo_open=lo_open)
    return np.array([v]), v


def channels(*arrays: FloatArray) -> int:
    return max(a.size for a in arrays)


def unit(v: FloatArray) -> FloatArray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.asarray(v / np.where(n > 0.0, n, 1.0), dtype=np.float64)


def as_vectors(*vs: ArrayLike) -> tuple[FloatArray, ...]:
    out = []
    for v in vs:
        a = np.asarray(v, dtype=np.float64)
        if a.shape[-1:] != (3,):
            raise ValueError(f"direction arrays must have a trailing axis of length 3, got shape {a.shape}")
        out.append(a)
    return tuple(np.broadcast_arrays(*out))
