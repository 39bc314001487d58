"""What optional windowing of a radial lobe's expansion costs in accuracy and gains in ringing
(``prefilter_radial(window=...)``; Gibbs overshoot of the band-limited kernel, seed 000 §5)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.brdf.base import RadialLobe
from relight.conventions import luminance
from relight.metrics import relative_rms
from relight.tradeoff.points import check_pixels


def window_tradeoff(
    pixels: NDArray[np.floating],
    lobe: RadialLobe,
    *,
    order: int,
    size: int,
    reference: NDArray[np.floating] | None = None,
    windows: Sequence[str] = ("none", "hann", "lanczos"),
) -> list[dict[str, Any]]:
    """Accuracy cost and ringing gain of windowing the order-F expansion (``prefilter_radial(window=...)``).

    For each window: ``relative_rms`` against ``reference`` (default: the untruncated angular reference),
    ``kernel_min`` (the most negative value of the band-limited lobe, the prefilter report's ringing figure),
    ``kernel_min_relative`` (that over the lobe's peak ``u_F(1)``), the report's lower bound on every output texel,
    the most negative output value (luminance) relative to the output's largest, and the fraction of negative
    output texels (luminance). Negative lobes of ``u_F`` are what turn a bright sun into dark rings (Gibbs).
    """
    from relight.brdf.coefficients import kernel_on_grid, radial_transfer, window_factors
    from relight.prefilter import prefilter_radial
    from relight.reference import reference_radial

    px = check_pixels(pixels)
    ref = np.asarray(reference, dtype=np.float64) if reference is not None else reference_radial(
        px, lobe, size, epsilon=0.0)
    transfer = radial_transfer(lobe, order).transfer
    out = []
    for w in windows:
        res = prefilter_radial(px, lobe, order=order, size=size, window=w)
        factors = transfer * window_factors(order, w)[:, None]
        peak = float(np.max(kernel_on_grid(factors, np.array([1.0]))))
        y = luminance(res.map)
        ring = res.report.ringing
        out.append({
            "window": w,
            "order": order,
            "relative_rms": relative_rms(res.map, ref),
            "kernel_min": ring.kernel_min,
            "kernel_min_relative": ring.kernel_min / peak if peak > 0 else 0.0,
            "lower_bound_rgb": list(ring.lower_bound_rgb),
            "min_output_relative": float(y.min() / y.max()) if y.max() > 0 else 0.0,
            "negative_fraction": float(np.mean(y < 0.0)),
        })
    return out

