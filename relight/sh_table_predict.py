"""Predictions for a per-view SH table before it is computed (Kautz, Sloan & Snyder 2002, §3; for the planner):
how much of the BRDF's product function an order-F table misses, per band of view angle, and how many seconds the
table takes.

**Error** (:func:`predicted_table_error`). For a local view v the order-F table holds the projection of ``f*(., v)``
on l <= F; the uncaptured energy fraction ``eps(v) = 1 - sum_{l<=F,m} c_lm(v)^2 / int f*^2`` is seed 000's
``epsilon_brdf`` for one view, and ``sqrt(eps)`` the relative RMS (L2) error of the lobe — the error of the render
under lighting that excites every band equally, and an upper bound on the relative error under band-limited
lighting of order <= F, where the table is exact (``relight.orders`` / the README's ``relative RMS = sqrt(epsilon)``).
Views: ``elevations`` values of ``N.V`` at the midpoints of equal steps of (0, 1], times ``azimuths`` azimuths (one
for isotropic BRDFs; [0, pi/2] for mirror-symmetric ones, the whole circle otherwise); each view by
``relight.sh_table.product_energy`` (the table's own lobe quadrature at refine 2). Reported per N.V band
``[0, 0.3], [0.3, 0.7], [0.7, 1]`` (the bands of the reports' ``predicted.by_view``) as the largest over the band's
views, and overall. A sharp lobe blurred by the order shows as a large ``rms``.

**Cost** (:func:`predicted_table_seconds`). ``build_table`` integrates ``views x nodes`` products (R views of the
1-D table for isotropic BRDFs, R^2 / 4 distinct views for mirror-symmetric ones, R^2 otherwise; ``nodes`` from
``relight.sh_table.lobe_quadrature`` for the lobe's width), each with one evaluation of ``f*`` and n = (F+1)^2
harmonics, and an isotropic table is expanded to R^2 texels x n coefficients:
``seconds = views nodes (A + B n) + [isotropic] R^2 n E``, summed over a sum's terms. A, B, E come from one
calibration on the shared 2-core development machine (AS (48, 16) and anisotropic GGX at R = 32, 64, F = 4, 8;
isotropic TS at R = 128); the machine's load alone moves measurements by 2x, and measured BRDFs cost more per node
(trilinear MERL lookups): ``bench/shtable.py`` printed AS 1.01 s predicted against 0.47-1.1 s measured at R = 32,
MERL 0.14 s against 0.31 s. A factor-of-3 estimate, enough to tell seconds from minutes.
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from relight.brdf.frame import FrameBRDF, FrameSum, as_frame_brdf
from relight.sh_table import check_order, lobe_quadrature, product_energy

#: Seconds per (view x node) and per (view x node x coefficient), and per expanded texel coefficient (module
#: docstring).
SECONDS_PER_NODE: Final = 1.4e-6
SECONDS_PER_NODE_COEFFICIENT: Final = 3.0e-9
SECONDS_PER_EXPANDED: Final = 1.1e-6
#: The N.V bands of the reports (``predicted.by_view``).
VIEW_BANDS: Final = ((0.0, 0.3), (0.3, 0.7), (0.7, 1.0))


def _views(brdf: FrameBRDF, elevations: int, azimuths: int) -> tuple[np.ndarray, np.ndarray]:
    cos_t = (np.arange(elevations) + 0.5) / elevations
    if brdf.isotropic:
        phis = np.zeros(1)
    elif brdf.mirror_symmetric:
        phis = np.linspace(0.0, np.pi / 2, azimuths)
    else:
        phis = np.arange(azimuths) * 2.0 * np.pi / azimuths
    ct, ph = np.meshgrid(cos_t, phis, indexing="ij")
    st = np.sqrt(1.0 - ct**2)
    return np.stack([st * np.cos(ph), st * np.sin(ph), ct], axis=-1).reshape(-1, 3), ct.ravel()


def predicted_table_error(brdf: Any, order: int, *, elevations: int = 8, azimuths: int = 5) -> dict[str, Any]:
    """Uncaptured energy and relative RMS of the order-F table (module docstring): ``{"order", "missing_energy",
    "rms", "by_view": [{"n_dot_v": [lo, hi], "missing_energy", "rms"}, ...]}`` (largest over views and channels)."""
    f = as_frame_brdf(brdf)
    order = check_order(order)
    if elevations < 3 or azimuths < 1:
        raise ValueError(f"need at least 3 elevations and 1 azimuth, got {elevations}, {azimuths}")
    views, cos_t = _views(f, elevations, azimuths)
    missing = np.empty(views.shape[0])
    for k, v in enumerate(views):
        bands, total = product_energy(f, v, order)
        frac = 1.0 - bands.sum(axis=0) / np.where(total > 0.0, total, 1.0)
        missing[k] = float(np.max(np.where(total > 0.0, frac, 0.0)))
    missing = np.clip(missing, 0.0, 1.0)
    by_view = []
    for lo, hi in VIEW_BANDS:
        sel = (cos_t > lo) & (cos_t <= hi)
        e = float(missing[sel].max())
        by_view.append({"n_dot_v": [lo, hi], "missing_energy": e, "rms": float(np.sqrt(e))})
    e_all = float(missing.max())
    return {"order": order, "missing_energy": e_all, "rms": float(np.sqrt(e_all)), "by_view": by_view}


def predicted_table_seconds(brdf: Any, order: int, resolution: int) -> float:
    """Seconds ``relight.sh_table.build_table`` takes for this BRDF, order and R (module docstring)."""
    f = as_frame_brdf(brdf)
    n = (check_order(order) + 1) ** 2
    r = int(resolution)
    if r < 2:
        raise ValueError(f"resolution must be >= 2, got {resolution}")
    terms = f.terms if isinstance(f, FrameSum) else [f]
    total = 0.0
    for t in terms:
        nodes = lobe_quadrature(t.lobe_width, 1, horizon=t.lobe_center == "N")[1].size
        views = r if f.isotropic else (r * r / 4.0 if t.mirror_symmetric else float(r * r))
        total += views * nodes * (SECONDS_PER_NODE + SECONDS_PER_NODE_COEFFICIENT * n)
    if f.isotropic:
        total += r * r * n * SECONDS_PER_EXPANDED
    return float(total)
