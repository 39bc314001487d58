"""The glTF 2.0 metallic-roughness material as a relight BRDF (``gltf-pbr:base=...,metallic=...,roughness=...``).

glTF 2.0 specification, Appendix B ("BRDF Implementation"): ``c_diff = lerp(base, black, metallic)``,
``F0 = lerp(0.04, base, metallic)``, ``alpha = roughness^2``, a GGX specular with Schlick's Fresnel and the
separable Smith visibility ``V = 1 / ((NoL + sqrt(a^2 + (1 - a^2) NoL^2)) (NoV + sqrt(a^2 + (1 - a^2) NoV^2)))``
(= ``G1(l) G1(v) / (4 NoL NoV)``, relight's :class:`~relight.brdf.models.GGX`), and a Lambertian diffuse
``c_diff / pi``. The spec's ``mix`` weights the diffuse by ``(1 - F)``; relight keeps the two lobes separate (each is
prefiltered about its own centre, seed 000 §3.1), so the diffuse here is plain Lambert, as the issue's preset
states. The preset expands to the sum ``lambert:albedo=c_diff + ggx:alpha=r^2,fresnel=schlick,f0=F0`` (the Lambert
term is left out when ``c_diff`` is black: a metal is the GGX lobe alone); its canonical spec is that sum.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from relight.brdf.models import GGX, SumBRDF, check_color, check_number
from relight.brdf.radial import Lambert

#: The dielectric F0 of glTF's metallic-roughness model (Appendix B, "f0 = 0.04").
DIELECTRIC_F0 = 0.04


def gltf_pbr(base: float | Sequence[float] = 1.0, metallic: float = 1.0,
             roughness: float = 1.0) -> GGX | SumBRDF:
    """The preset's lobes (module docstring); ``base`` grey or RGB in [0, 1], metallic in [0, 1], roughness in
    (0, 1] (0 would be a mirror, which has no GGX lobe; use a small value)."""
    base_arr, _ = check_color("gltf-pbr", "base", base, lo=0.0, hi=1.0)
    m = check_number("gltf-pbr", "metallic", metallic, lo=0.0, hi=1.0)
    r = check_number("gltf-pbr", "roughness", roughness, lo=0.0, hi=1.0, lo_open=True)
    c_diff = base_arr * (1.0 - m)
    f0 = DIELECTRIC_F0 * (1.0 - m) + base_arr * m

    def color(v: np.ndarray) -> float | list[float]:
        return float(v[0]) if v.size == 1 else [float(x) for x in v]

    lobes: list[GGX | Lambert] = []
    if np.any(c_diff > 0.0):
        lobes.append(Lambert(color(c_diff)))
    lobes.append(GGX(r * r, fresnel="schlick", f0=color(f0)))
    return lobes[0] if len(lobes) == 1 else SumBRDF(lobes)  # type: ignore[return-value]
