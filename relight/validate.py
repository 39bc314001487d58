"""The number validator: finite / range / integer checks that raise :class:`relight.errors.InputError` naming the
parameter and the value given, in one wording everywhere.

``finite("exposure", x)`` -> "exposure must be finite, got nan"; ``in_range("epsilon", e, 0, 1, lo_open=True,
hi_open=True)`` -> "epsilon must lie in (0, 1), got 1.5"; ``at_least("size", s, 2)`` -> "size must be >= 2, got 1";
``positive("height", h)`` -> "height must be positive, got 0"; ``int_in_range("levels", n, 1, 32)`` -> "levels must be
an integer in [1, 32], got 40"; ``finite_array("tangents", t)`` -> "tangents must be finite (3 non-finite values)".
Each returns the value (as float, or int for the
integer checks) so a caller can validate and convert in one line.
"""

from __future__ import annotations

import math
import numbers
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

from relight.errors import InputError


def _real(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a real number, got {value!r}")
    return float(value)


def finite(name: str, value: object) -> float:
    """``value`` as a float; an InputError unless it is a finite real number."""
    v = _real(name, value)
    if not math.isfinite(v):
        raise InputError(f"{name} must be finite, got {value!r}")
    return v


def in_range(name: str, value: object, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
             hi_open: bool = False) -> float:
    """``value`` as a float, finite and inside the interval (open or closed at each end; None = unbounded)."""
    v = finite(name, value)
    below = lo is not None and (v <= lo if lo_open else v < lo)
    above = hi is not None and (v >= hi if hi_open else v > hi)
    if below or above:
        left = "-inf" if lo is None else f"{lo:g}"
        right = "inf" if hi is None else f"{hi:g}"
        interval = f"{'(' if lo_open or lo is None else '['}{left}, {right}{')' if hi_open or hi is None else ']'}"
        raise InputError(f"{name} must lie in {interval}, got {value!r}")
    return v


def positive(name: str, value: object) -> float:
    """``value`` as a float, finite and > 0."""
    v = finite(name, value)
    if v <= 0.0:
        raise InputError(f"{name} must be positive, got {value!r}")
    return v


def integer(name: str, value: object) -> int:
    """``value`` as an int: an integer type (not bool), or an integral float such as ``3.0``."""
    if isinstance(value, bool):
        raise InputError(f"{name} must be an integer, got {value!r}")
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real) and math.isfinite(float(value)) and float(value).is_integer():
        return int(float(value))
    raise InputError(f"{name} must be an integer, got {value!r}")


def at_least(name: str, value: object, minimum: int) -> int:
    """``value`` as an int >= ``minimum``."""
    v = integer(name, value)
    if v < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value!r}")
    return v


def positive_int(name: str, value: object) -> int:
    """``value`` as an int > 0."""
    v = integer(name, value)
    if v <= 0:
        raise InputError(f"{name} must be positive, got {value!r}")
    return v


def int_in_range(name: str, value: object, lo: int, hi: int) -> int:
    """``value`` as an int with ``lo <= value <= hi``."""
    v = integer(name, value)
    if not lo <= v <= hi:
        raise InputError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return v


def finite_array(name: str, values: ArrayLike) -> NDArray[Any]:
    """``values`` as an array (its own dtype), every element finite."""
    import numpy as np  # here: the CLI imports this module at start-up, before it needs NumPy

    a = np.asarray(values)
    bad = a.size - int(np.count_nonzero(np.isfinite(a)))
    if bad:
        raise InputError(f"{name} must be finite ({bad} non-finite value{'s' if bad > 1 else ''})")
    return a
