"""The split-sum GGX lobe that engines prefilter their environment chains with (``ggx-ld:roughness=r``).

Every real-time engine that ships a prefiltered specular chain (Filament's cmgen, three.js' PMREM, the Khronos
glTF-IBL-Sampler) makes Karis' split-sum approximation: the view is assumed equal to the normal, so the lobe is
radially symmetric about the texel's direction n. They importance-sample GGX half-vectors with pdf
``D(h) (n.h) / (4 v.h)`` and weight each sample by ``n.l``; with v = n (so v.h = n.h) the kernel they compute is

    K(n . l) = D_GGX(h; alpha) max(0, n . l) / Z,     h = normalize(n + l),  alpha = r^2,

normalised to unit integral over the sphere (Z below), with r the engine's *perceptual* roughness. Writing
t = n . l, the half-vector's cosine is ``(n . h)^2 = (1 + t) / 2``, and ``D_GGX = alpha^2 / (pi (1 + k x)^2)`` with
``x = (n.h)^2``, ``k = alpha^2 - 1``. The normalisation, with ``y = 1 + k x``:

    Z = 2 pi int_0^1 D t dt = 4 alpha^2 int_{1/2}^{1} (2x - 1) / (1 + k x)^2 dx
      = 4 alpha^2 / k^2 [ 2 ln(y1 / y0) + (2 + k) (1 / y1 - 1 / y0) ],  y0 = 1 + k / 2,  y1 = alpha^2,

which cancels catastrophically as k -> 0 (alpha -> 1, where D = 1/pi and Z -> 1); there the series in k is used.
``tests/relight/test_splitsum.py`` checks Z and the kernel against brute-force quadrature.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from relight.brdf.base import FloatArray, RadialLobe
from relight.errors import InputError

#: Smallest perceptual roughness a lobe accepts (alpha = 1e-6): sharper is a mirror, which a chain samples directly.
MIN_ROUGHNESS = 1.0e-3


def ggx_d(nh2: FloatArray, alpha: float) -> FloatArray:
    """GGX (Trowbridge–Reitz) normal distribution ``alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)``."""
    a2 = alpha * alpha
    return np.asarray(a2 / (np.pi * (nh2 * (a2 - 1.0) + 1.0) ** 2), dtype=np.float64)


def splitsum_normaliser(alpha: float) -> float:
    """``Z = 2 pi int_0^1 D_GGX(sqrt((1 + t) / 2)) t dt`` in closed form (module docstring)."""
    a2 = alpha * alpha
    k = a2 - 1.0
    if abs(k) < 3e-3:
        # The integrand's series 1 / (1 + k x)^2 = 1 - 2 k x + 3 k^2 x^2 - 4 k^3 x^3 + O(k^4), integrated term by
        # term on [1/2, 1] (truncation error ~ 5 k^4 < 5e-10 here).
        i0 = 1.0 / 4.0  # int (2x - 1) dx
        i1 = 5.0 / 24.0  # int (2x - 1) x dx
        i2 = 17.0 / 96.0  # int (2x - 1) x^2 dx
        i3 = 49.0 / 320.0  # int (2x - 1) x^3 dx
        return 4.0 * a2 * (i0 - 2.0 * k * i1 + 3.0 * k * k * i2 - 4.0 * k**3 * i3)
    y0 = 1.0 + 0.5 * k
    y1 = a2
    return 4.0 * a2 / (k * k) * (2.0 * math.log(y1 / y0) + (2.0 + k) * (1.0 / y1 - 1.0 / y0))


class GGXSplitSum(RadialLobe):
    """The engines' split-sum prefilter lobe about the normal, ``K(t) = D_GGX(h; r^2) max(t, 0) / Z``.

    ``roughness`` is the perceptual roughness r in [1e-3, 1] (alpha = r^2, the glTF / Filament / three.js
    convention). The lobe integrates to 1 over the sphere, so a uniform environment is reproduced exactly.
    ``max_roughness`` admits r > 1 (alpha > 1, a GGX wider than the clamped cosine, still normalised): Babylon's
    prefilter writes such levels at the end of its chains (``relight.cube_chain``); the ``ggx-ld`` spec keeps 1.
    """

    kind: ClassVar[str] = "ggx-ld"

    def __init__(self, roughness: float, *, max_roughness: float = 1.0) -> None:
        try:
            r = float(roughness)
        except (TypeError, ValueError):
            raise InputError(f"roughness must be a number, got {roughness!r}") from None
        if not math.isfinite(r) or not MIN_ROUGHNESS <= r <= max_roughness:
            raise InputError(f"roughness must lie in [{MIN_ROUGHNESS:g}, {max_roughness:g}], got {roughness!r}")
        self.roughness = r
        self.alpha = r * r
        self.center = "N"
        self.channels = 1
        self._z = splitsum_normaliser(self.alpha)

    def u(self, t: FloatArray) -> FloatArray:
        t = np.clip(np.asarray(t, dtype=np.float64), -1.0, 1.0)
        val = ggx_d(0.5 * (1.0 + t), self.alpha) * np.maximum(t, 0.0) / self._z
        return np.asarray(val[..., None], dtype=np.float64)

    def params(self) -> dict[str, Any]:
        return {"roughness": self.roughness}
