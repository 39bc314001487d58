"""Test maps shared by the cube-chain and cap-convolution tests: a sky with a 1e4 sun (the hard case)."""

from __future__ import annotations

import numpy as np

from relight.conventions import latlong_dirs


def sun_sky(h: int) -> np.ndarray:
    d = latlong_dirs(h, 2 * h)
    sky = (0.3 + 0.5 * np.clip(d[..., 1:2], 0, 1)) * np.array([0.5, 0.7, 1.0])
    sun_dir = np.array([0.3, 0.6, -0.74]) / np.linalg.norm([0.3, 0.6, -0.74])
    sun = (d @ sun_dir > np.cos(0.08))[..., None] * np.array([1.0e4, 0.9e4, 0.8e4])
    return np.asarray(sky + sun, dtype=np.float64)
