"""Lat-long map resampling: exact solid-angle area averaging down, bilinear up (project layout,
:mod:`relight.conventions`: row ``i`` spans ``theta`` in ``[i, i + 1] pi / H``, columns wrap in ``phi``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import bilinear_latlong, check_latlong_shape
from relight.errors import InputError

F32 = NDArray[np.float32]


def resample_latlong(rgb: NDArray[np.floating], height: int) -> F32:
    """Resample an (H, 2H[, C]) lat-long map to (height, 2 height[, C]).

    Downsampling is an exact area average: each output pixel is the solid-angle-weighted mean of the input
    pixels it overlaps (fractional overlaps for non-integer factors). Rows weigh by ``cos theta_top -
    cos theta_bottom`` of the overlap, columns by the overlapping ``phi`` length, so ``sum L Omega`` over the
    sphere is preserved exactly (to rounding) for any factor. Upsampling is bilinear between pixel centres
    (wrapping in ``phi``, clamped at the poles).
    """
    arr = np.asarray(rgb, dtype=np.float64)
    squeeze = arr.ndim == 2
    if squeeze:
        arr = arr[..., None]
    if arr.ndim != 3:
        raise InputError(f"a lat-long map must have shape (H, W[, C]), got {arr.shape}")
    try:
        h_in, w_in = check_latlong_shape(arr.shape)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    height = validate.positive_int("output height", height)
    if height == h_in:
        out = arr
    elif height < h_in:
        rows = _area_weights(h_in, height, lambda k: np.cos(np.pi * k / (h_in * height)))
        cols = _area_weights(w_in, 2 * height, lambda k: k / (w_in * 2 * height))
        out = _apply_weights(cols, _apply_weights(rows, arr, axis=0), axis=1)
    else:
        out = _bilinear_latlong(arr, height)
    result = np.asarray(out, dtype=np.float32)
    return result[..., 0] if squeeze else result


Weights = tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64], int]


def _area_weights(n_in: int, n_out: int, measure: Callable[[NDArray[np.intp]], NDArray[np.float64]]) -> Weights:
    """Sparse overlap weights for area-averaging ``n_in`` equal cells into ``n_out`` (``n_out < n_in``).

    Boundaries are integers in a common unit (input cell ``i`` spans ``[i n_out, (i+1) n_out]``, output cell
    ``o`` spans ``[o n_in, (o+1) n_in]``), so overlaps are found exactly; ``measure(k)`` maps a boundary to the
    measure coordinate (``cos theta`` for rows, ``phi`` for columns). Each input cell meets at most two
    output cells. Returns (output index, input index, weight, n_out), weights normalised per output cell.
    """
    i = np.arange(n_in)
    lo, hi = i * n_out, (i + 1) * n_out
    first = lo // n_in  # output cell holding the start of input cell i
    second = (hi - 1) // n_in  # output cell holding its end (the same one, or the next)

    split = second != first
    o_all = np.concatenate([first, second[split]])
    i_all = np.concatenate([i, i[split]])
    a = np.maximum(lo[i_all], o_all * n_in)
    b = np.minimum(hi[i_all], (o_all + 1) * n_in)
    w_all = np.asarray(np.abs(measure(b) - measure(a)), dtype=np.float64)
    total = np.bincount(o_all, weights=w_all, minlength=n_out)
    return o_all, i_all, w_all / total[o_all], n_out


def _apply_weights(weights: Weights, arr: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    o, i, w, n_out = weights
    moved = np.moveaxis(arr, axis, 0)
    out = np.zeros((n_out,) + moved.shape[1:], dtype=np.float64)
    np.add.at(out, o, moved[i] * w.reshape((-1,) + (1,) * (moved.ndim - 1)))
    return np.moveaxis(out, 0, axis)


def _bilinear_latlong(arr: NDArray[np.float64], height: int) -> NDArray[np.float64]:
    """Upsampling: the lat-long sampler (:func:`relight.conventions.bilinear_latlong`) at the new pixel centres."""
    h_in, w_in = arr.shape[:2]
    y = np.clip((np.arange(height) + 0.5) * h_in / height - 0.5, 0.0, h_in - 1.0)
    x = (np.arange(2 * height) + 0.5) * w_in / (2 * height) - 0.5
    return bilinear_latlong(arr, y[:, None], x[None, :])
