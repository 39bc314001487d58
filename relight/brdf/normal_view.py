"""A BRDF's lobe at view = normal, the kernel of a cube-chain level for ``--brdf SPEC`` (issue 17, item 1).

An engine's prefiltered chain assumes the view equals the normal (``relight.brdf.splitsum``). For any isotropic
BRDF the same assumption gives a kernel radially symmetric about the texel's direction n: with v = n the
reflection vector is n too, so every lobe's ``rho_hat`` (BRDF x cosine about its centre, ``relight.brdf.base``) is
evaluated at ``theta_o = 0`` and the level's texel is

    B(n) = int L(l) K(n . l) dl,     K(t) = sum over the lobes of rho_hat(arccos t, 0, 0)

— the radiance the material reflects back along the normal, not renormalised (``ggx-ld`` is unit-integral itself,
so ``--brdf ggx-ld`` is the default chain). What a level means for a spec (docs/conventions.md "Chains of other
lobes"): a ``ggx-ld`` or ``gltf-pbr`` term that leaves its ``roughness`` out takes each level's roughness r (the
target's lod mapping; ``gltf-pbr``'s GGX gets alpha = r^2 also beyond 1, as Babylon's last levels ask); at r = 0
such a term is its mirror limit, a delta of weight ``F(1)`` (1 for ``ggx-ld``, F0 for ``gltf-pbr``: D tends to a
delta about n, G1 to 1), i.e. the map itself times that weight. Every other parameter, and a roughness the spec
gives, is the BRDF's own and the same at every level. Tangent-centred (Kajiya–Kay) and anisotropic lobes have no
kernel about n and are refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from relight.brdf.base import FloatArray, Lobe, RadialLobe
from relight.brdf.gltf_pbr import gltf_pbr
from relight.brdf.microfacet import TorranceSparrow
from relight.brdf.models import GGX, SumBRDF
from relight.brdf.spec import parse_brdf_data, spec_terms
from relight.brdf.splitsum import MIN_ROUGHNESS, GGXSplitSum
from relight.errors import InputError

#: Kinds whose ``roughness`` a chain level sets when the spec leaves it out.
LEVEL_ROUGHNESS_KINDS = ("ggx-ld", "gltf-pbr")


class NormalViewLobe(RadialLobe):
    """``K(t) = sum_i rho_hat_i(arccos t, 0, 0)``, the lobes' kernel at view = normal (module docstring)."""

    kind: ClassVar[str] = "normal-view"

    def __init__(self, lobes: list[Lobe]) -> None:
        bad = [lobe.kind for lobe in lobes if lobe.center == "T"]
        if bad:
            raise InputError(f"--brdf: {bad[0]} has no lobe about the normal at view = normal (tangent-centred)")
        self.lobes = list(lobes)
        self.center = "N"
        self.channels = 3 if any(lobe.channels == 3 for lobe in lobes) else 1

    def u(self, t: FloatArray) -> FloatArray:
        t = np.clip(np.asarray(t, dtype=np.float64), -1.0, 1.0)
        theta = np.arccos(t)
        zero = np.zeros_like(theta)
        out = np.zeros(t.shape + (self.channels,))
        for lobe in self.lobes:
            out = out + np.asarray(lobe.rho_hat(theta, zero, zero), dtype=np.float64)
        return out

    def params(self) -> dict[str, Any]:
        return {"lobes": [lobe.spec() for lobe in self.lobes]}


class ChannelLobe(RadialLobe):
    """Channel ``k`` of an RGB radial lobe as a grey lobe (a chain convolves an RGB kernel one channel at a time)."""

    kind: ClassVar[str] = "channel"

    def __init__(self, lobe: RadialLobe, k: int) -> None:
        self.lobe, self.k = lobe, k
        self.center = lobe.center
        self.channels = 1

    def u(self, t: FloatArray) -> FloatArray:
        return np.asarray(self.lobe.u(t), dtype=np.float64)[..., self.k:self.k + 1]

    def params(self) -> dict[str, Any]:
        return {"lobe": self.lobe.spec(), "channel": self.k}


@dataclass(frozen=True)
class LevelKernel:
    """A level's kernel: ``mirror`` (RGB weight of the map itself, the mirror limit of level-rough terms at r = 0)
    plus the continuous ``lobes``, one radial lobe per lobe of the spec (a chain plans each on its own: a broad
    Lambert and a sharp GGX split at different angles). ``K_i`` is their sum."""

    mirror: FloatArray
    lobes: list[RadialLobe]


def _radial(lobe: Lobe) -> RadialLobe:
    """The lobe at view = normal; a ``ggx-ld`` lobe is that already (about n, so ``--brdf ggx-ld`` is the default)."""
    return lobe if isinstance(lobe, GGXSplitSum) else NormalViewLobe([lobe])


class ChainBrdf:
    """A ``--brdf`` spec string as a family of level kernels (module docstring)."""

    def __init__(self, spec: str, *, max_roughness: float = 1.0) -> None:
        self.spec = spec.strip()
        self.terms = spec_terms(self.spec)
        self.max_roughness = max_roughness
        self.kernel(0.0)  # every error of the spec now, before any level is computed
        self.kernel(0.5)

    def kernel(self, roughness: float) -> LevelKernel:
        mirror = np.zeros(3)
        lobes: list[RadialLobe] = []
        for kind, kw in self.terms:
            if kind not in LEVEL_ROUGHNESS_KINDS or "roughness" in kw:
                brdf = parse_brdf_data({"kind": kind, **kw})
                lobes.extend(_radial(lobe) for lobe in (brdf.lobes if isinstance(brdf, SumBRDF) else [brdf]))
                continue
            r = float(roughness)
            if kind == "ggx-ld":
                if r < MIN_ROUGHNESS:
                    mirror += 1.0
                else:
                    lobes.append(GGXSplitSum(r, max_roughness=max(self.max_roughness, 1.0)))
                continue
            preset = gltf_pbr(**kw, roughness=1.0)  # the lobes at r = 1; the GGX gets this level's alpha
            for lobe in preset.lobes if isinstance(preset, SumBRDF) else [preset]:
                if not isinstance(lobe, TorranceSparrow):
                    lobes.append(_radial(lobe))
                elif r < MIN_ROUGHNESS:
                    mirror += np.broadcast_to(np.asarray(lobe.F(np.ones(1)), dtype=np.float64)[0], (3,))
                else:
                    lobes.append(NormalViewLobe([GGX(r * r, fresnel="schlick", f0=lobe.params()["f0"])]))
        return LevelKernel(mirror, lobes)

    def uses_level_roughness(self) -> bool:
        return any(kind in LEVEL_ROUGHNESS_KINDS and "roughness" not in kw for kind, kw in self.terms)
