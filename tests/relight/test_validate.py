"""Tests for relight.validate, the one number validator: values pass through converted, bad ones raise InputError
with the parameter's name and the value given."""

from __future__ import annotations

import math

import numpy as np
import pytest

from relight import validate
from relight.errors import InputError


def test_finite_and_positive() -> None:
    assert validate.finite("x", np.float32(1.5)) == 1.5
    assert validate.finite("x", 3) == 3.0 and isinstance(validate.finite("x", 3), float)
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(InputError, match=r"^exposure must be finite, got (nan|inf|-inf)$"):
            validate.finite("exposure", bad)
    for bad in ("1", None, True, 1 + 2j):
        with pytest.raises(InputError, match=r"^x must be a real number, got "):
            validate.finite("x", bad)
    assert validate.positive("h", 1e-300) == 1e-300
    with pytest.raises(InputError, match=r"^h must be positive, got 0$"):
        validate.positive("h", 0)


@pytest.mark.parametrize(("value", "ok"), [(0.0, False), (1e-12, True), (0.5, True), (1.0, False), (-0.1, False)])
def test_open_interval(value: float, ok: bool) -> None:
    if ok:
        assert validate.in_range("epsilon", value, 0.0, 1.0, lo_open=True, hi_open=True) == value
    else:
        with pytest.raises(InputError, match=r"^epsilon must lie in \(0, 1\), got "):
            validate.in_range("epsilon", value, 0.0, 1.0, lo_open=True, hi_open=True)


def test_closed_and_half_bounded_intervals() -> None:
    assert validate.in_range("t", 0.0, 0.0, 1.0) == 0.0 and validate.in_range("t", 1.0, 0.0, 1.0) == 1.0
    with pytest.raises(InputError, match=r"^t must lie in \[0, 1\], got 1.5$"):
        validate.in_range("t", 1.5, 0.0, 1.0)
    with pytest.raises(InputError, match=r"^d must lie in \[2, inf\), got 1$"):
        validate.in_range("d", 1, lo=2)
    with pytest.raises(InputError, match=r"^d must lie in \(-inf, 0\), got 0$"):
        validate.in_range("d", 0, hi=0, hi_open=True)
    with pytest.raises(InputError, match="must be finite"):
        validate.in_range("d", math.nan, 0.0, 1.0)  # NaN compares false with both bounds: caught as non-finite


def test_integers() -> None:
    assert validate.integer("n", np.int64(7)) == 7 and validate.integer("n", 4.0) == 4
    for bad in (4.5, True, math.inf, "4"):
        with pytest.raises(InputError, match=r"^n must be an integer, got "):
            validate.integer("n", bad)
    assert validate.at_least("size", 2, 2) == 2
    with pytest.raises(InputError, match=r"^size must be >= 2, got 1$"):
        validate.at_least("size", 1, 2)
    assert validate.positive_int("height", 1) == 1
    with pytest.raises(InputError, match=r"^height must be positive, got 0$"):
        validate.positive_int("height", 0)


def test_integer_ranges() -> None:
    assert validate.int_in_range("levels", 1, 1, 32) == 1 and validate.int_in_range("levels", np.int32(32), 1, 32) == 32
    for bad in (0, 33):
        with pytest.raises(InputError, match=rf"^levels must be an integer in \[1, 32\], got {bad}$"):
            validate.int_in_range("levels", bad, 1, 32)
    with pytest.raises(InputError, match=r"^levels must be an integer, got 2.5$"):
        validate.int_in_range("levels", 2.5, 1, 32)


def test_finite_arrays() -> None:
    ok = np.array([[0.0, 1.0], [2.0, -3.0]], dtype=np.float32)
    assert validate.finite_array("t", ok) is not None and validate.finite_array("t", ok).dtype == np.float32
    with pytest.raises(InputError, match=r"^tangents must be finite \(2 non-finite values\)$"):
        validate.finite_array("tangents", [[0.0, math.nan], [math.inf, 1.0]])
    with pytest.raises(InputError, match=r"^beta must be finite \(1 non-finite value\)$"):
        validate.finite_array("beta", -math.inf)
