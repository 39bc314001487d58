"""Mitsuba 3 side of relight's external-oracle test (``tests/test_mitsuba_oracle.py``).

The scene, the conventions and the map conversion live in the product, ``relight.mitsuba_twin`` (its module
docstring); they are re-exported here for the tests, with the two helpers only the oracle test uses.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from relight.mitsuba_twin import (
    SphereRender,
    block_far_radius,
    block_mean,
    bsdf_eval,
    choose_variant,
    emitter_radiance,
    mitsuba_bitmap,
    render_sphere_mitsuba,
    sphere_scene,
    texel_dirs,
    twin,
)

__all__ = [
    "SphereRender", "block_far_radius", "block_mean", "bsdf_eval", "choose_variant", "emitter_radiance",
    "mitsuba_bitmap", "nearest_upsample", "render_sphere_mitsuba", "sphere_scene", "texel_dirs", "theta_v_deg", "twin",
]

FloatArray = NDArray[np.float64]


def nearest_upsample(pixels: NDArray[np.floating], k: int) -> FloatArray:
    """The same piecewise-constant map on a k times finer lat-long grid (each pixel split into k x k)."""
    p = np.asarray(pixels, dtype=np.float64)
    return np.repeat(np.repeat(p, k, axis=0), k, axis=1)


def theta_v_deg(radius: float) -> float:
    """Angle between N and V (degrees) at image radius ``radius`` of the orthographic sphere image."""
    return math.degrees(math.asin(min(radius, 1.0)))
