"""The project's one error metric and its companions (used by reports, tests, benchmarks and the CLI).

``relative_rms(a, ref)``: relative RMS error over the sphere, solid-angle weighted, on Rec. 709 luminance::

    sqrt( sum_k dOmega_k (Y_a,k - Y_ref,k)^2 / sum_k dOmega_k Y_ref,k^2 )

For an orthogonal SH truncation this equals sqrt(epsilon_B), the square root of the paper's uncaptured energy
fraction (``relight.orders.rms_from_energy``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.conventions import check_latlong_shape, luminance, pixel_solid_angles

FloatArray = NDArray[np.float64]


def _lum_and_weights(a: NDArray[np.floating], ref: NDArray[np.floating]) -> tuple[FloatArray, FloatArray, FloatArray]:
    if a.shape != ref.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {ref.shape}")
    h, w = check_latlong_shape(a.shape)
    dom = np.broadcast_to(pixel_solid_angles(h, w)[:, None], (h, w))
    return luminance(a), luminance(ref), dom


def relative_rms(a: NDArray[np.floating], ref: NDArray[np.floating]) -> float:
    """Relative RMS error of ``a`` against ``ref`` (lat-long maps of equal shape), see the module docstring."""
    ya, yr, dom = _lum_and_weights(a, ref)
    den = float(np.sum(dom * yr * yr))
    num = float(np.sum(dom * (ya - yr) ** 2))
    if den == 0.0:
        return 0.0 if num == 0.0 else float("inf")
    return float(np.sqrt(num / den))


def compare(a: NDArray[np.floating], ref: NDArray[np.floating]) -> dict[str, Any]:
    """Relative RMS, max error relative to the reference's peak, and relative integrated-energy error (luminance)."""
    ya, yr, dom = _lum_and_weights(a, ref)
    peak = float(np.max(np.abs(yr)))
    e_a, e_r = float(np.sum(dom * ya)), float(np.sum(dom * yr))
    return {
        "relative_rms": relative_rms(a, ref),
        "max_abs_error": float(np.max(np.abs(ya - yr))),
        "max_error_relative_to_peak": float(np.max(np.abs(ya - yr)) / peak) if peak > 0 else 0.0,
        "energy_error": (e_a - e_r) / e_r if e_r != 0.0 else 0.0,
        "min_value": float(np.min(a)),
        "finite": bool(np.all(np.isfinite(a))),
    }
