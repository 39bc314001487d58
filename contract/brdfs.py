"""BRDF specs: a pydantic discriminated union on ``kind``, one model per BRDF of ``relight.brdf.models``.

Strict: unknown keys, NaN/Inf and out-of-range values are rejected with a 422 that names the field. The core
(``relight.brdf.spec.parse_brdf``) validates again and is the authority on cross-field rules (a Lafortune preset
*or* lobes, conductor Fresnel needs eta and k ...). Upper bounds marked "service limit" are tighter than the
core's: they keep one request from asking for an absurd amount of work.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

#: Service limit on exponents (Phong s, Blinn-Phong s, Kajiya-Kay s, Lafortune n): orders grow like sqrt(s).
MAX_EXPONENT = 1.0e5
#: Service limit on roughness parameters (alpha, sigma).
MAX_ROUGHNESS = 10.0
#: Service limit: the smallest microfacet roughness (alpha, sigma). The Phong-Beckmann equivalence s = 2 / alpha^2 - 2
#: (Walter et al. 2007, §5.2) maps MAX_EXPONENT to alpha = 0.00447; rounded up. Narrower lobes would need orders far
#: beyond any server's limit, and at alpha ~ 1e-300 the core's error analysis underflows to "order 0, error 0".
MIN_ROUGHNESS = 0.005
#: Service limit on the terms of a sum (the object form's ``lobes`` and the ``a+b+...`` string form alike).
MAX_SUM_LOBES = 8
#: Service limit on a conductor's complex index of refraction (eta, k).
MAX_IOR = 100.0
#: ``relight.brdf.splitsum.MIN_ROUGHNESS`` (the contract imports nothing of the core; tests/service/test_brdfs.py
#: checks they agree): the sharpest split-sum lobe.
SPLITSUM_MIN_ROUGHNESS = 1.0e-3
#: gltf-pbr's GGX has alpha = roughness^2, which must meet MIN_ROUGHNESS: roughness >= sqrt(0.005) = 0.0707.
GLTF_MIN_ROUGHNESS = 0.0708


def _grey_or_rgb(v: list[float]) -> list[float]:
    if len(v) not in (1, 3):
        raise ValueError(f"must be one number or three (RGB), got {len(v)} values")
    return v


Unit = Annotated[float, Field(ge=0.0, le=1.0)]
Color01 = Unit | Annotated[list[Unit], AfterValidator(_grey_or_rgb)]
Positive = Annotated[float, Field(gt=0.0, le=MAX_IOR)]
NonNeg = Annotated[float, Field(ge=0.0, le=MAX_IOR)]
Real = Annotated[float, Field(ge=-1.0e6, le=1.0e6)]
Exponent = Annotated[float, Field(ge=0.0, le=MAX_EXPONENT)]


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class PhongSpec(_Spec):
    """Normalised Phong lobe about R (seed 000 §6.3)."""

    kind: Literal["phong"]
    s: float = Field(ge=0.0, le=MAX_EXPONENT, description="exponent")


class LambertSpec(_Spec):
    """Lambertian lobe about N."""

    kind: Literal["lambert"]
    albedo: Color01 = 1.0


class Lobe1DSpec(_Spec):
    """A tabulated radially symmetric lobe u(C . L): samples t (strictly increasing in [-1, 1]) and u."""

    kind: Literal["lobe1d"]
    t: list[Annotated[float, Field(ge=-1.0, le=1.0)]] = Field(min_length=2, max_length=65536)
    u: list[Real] | list[Annotated[list[Real], Field(min_length=1, max_length=3)]] = Field(min_length=2,
                                                                                           max_length=65536)
    center: Literal["R", "N", "T"] = "R"


class MicrofacetSpec(_Spec):
    """Seed 000's simplified microfacet model (eq. 11), sigma in radians."""

    kind: Literal["microfacet"]
    sigma: float = Field(ge=MIN_ROUGHNESS, le=MAX_ROUGHNESS)


class TorranceSparrowSpec(_Spec):
    """Microfacet reflection (Walter et al. 2007) with Beckmann or GGX and optional Fresnel."""

    kind: Literal["torrance-sparrow"]
    alpha: float = Field(ge=MIN_ROUGHNESS, le=MAX_ROUGHNESS)
    distribution: Literal["beckmann", "ggx"] = "beckmann"
    fresnel: Literal["none", "schlick", "conductor"] = "none"
    f0: Color01 | None = None
    eta: Positive | Annotated[list[Positive], AfterValidator(_grey_or_rgb)] | None = None
    k: NonNeg | Annotated[list[NonNeg], AfterValidator(_grey_or_rgb)] | None = None


class GGXSpec(_Spec):
    """Torrance-Sparrow with the GGX distribution."""

    kind: Literal["ggx"]
    alpha: float = Field(ge=MIN_ROUGHNESS, le=MAX_ROUGHNESS)
    fresnel: Literal["none", "schlick", "conductor"] = "none"
    f0: Color01 | None = None
    eta: Positive | Annotated[list[Positive], AfterValidator(_grey_or_rgb)] | None = None
    k: NonNeg | Annotated[list[NonNeg], AfterValidator(_grey_or_rgb)] | None = None


class BlinnPhongSpec(_Spec):
    """Normalised Blinn-Phong."""

    kind: Literal["blinn-phong"]
    s: float = Field(ge=0.0, le=MAX_EXPONENT)


LafortuneValue = Real | Annotated[list[Real], AfterValidator(_grey_or_rgb)]
LafortuneExponent = Exponent | Annotated[list[Exponent], AfterValidator(_grey_or_rgb)]


class LafortuneSpec(_Spec):
    """Isotropic generalised cosine lobes: ``lobes`` of (Cx, Cz, n) plus a diffuse term, or a ``preset``."""

    kind: Literal["lafortune"]
    lobes: list[tuple[LafortuneValue, LafortuneValue, LafortuneExponent]] | None = Field(None, max_length=16)
    diffuse: Color01 | None = None
    preset: str | None = Field(None, max_length=64)


class WardSpec(_Spec):
    """Isotropic Ward."""

    kind: Literal["ward"]
    rho_d: Color01
    rho_s: Color01
    alpha: float = Field(ge=MIN_ROUGHNESS, le=MAX_ROUGHNESS)


class OrenNayarSpec(_Spec):
    """Oren-Nayar (qualitative model), sigma in radians."""

    kind: Literal["oren-nayar"]
    sigma: float = Field(ge=0.0, le=MAX_ROUGHNESS)
    albedo: Color01 = 1.0


class KajiyaKaySpec(_Spec):
    """Kajiya-Kay about the tangent T."""

    kind: Literal["kajiya-kay"]
    s: float = Field(ge=0.0, le=MAX_EXPONENT)


class GGXSplitSumSpec(_Spec):
    """The engines' split-sum prefilter lobe about N (view = normal), ``relight.brdf.splitsum``: perceptual
    roughness r, alpha = r^2."""

    kind: Literal["ggx-ld"]
    roughness: float = Field(ge=SPLITSUM_MIN_ROUGHNESS, le=1.0)


class GltfPbrSpec(_Spec):
    """glTF 2.0's metallic-roughness material (``relight.brdf.gltf_pbr``): a preset stored as its canonical sum,
    Lambert (c_diff = base (1 - metallic)) + GGX (alpha = roughness^2, Schlick, F0 = lerp(0.04, base, metallic))."""

    kind: Literal["gltf-pbr"]
    base: Color01 = 1.0
    metallic: Unit = 1.0
    roughness: float = Field(1.0, ge=GLTF_MIN_ROUGHNESS, le=1.0,
                             description="perceptual roughness; alpha = roughness^2 must meet MIN_ROUGHNESS")


LobeSpec = Annotated[
    PhongSpec | LambertSpec | Lobe1DSpec | MicrofacetSpec | TorranceSparrowSpec | GGXSpec | BlinnPhongSpec
    | LafortuneSpec | WardSpec | OrenNayarSpec | KajiyaKaySpec | GGXSplitSumSpec,
    Field(discriminator="kind"),
]


class SumSpec(_Spec):
    """A material made of several lobes, each prefiltered about its own centre."""

    kind: Literal["sum"]
    lobes: list[LobeSpec] = Field(min_length=1, max_length=MAX_SUM_LOBES)


BrdfSpec = Annotated[
    PhongSpec | LambertSpec | Lobe1DSpec | MicrofacetSpec | TorranceSparrowSpec | GGXSpec | BlinnPhongSpec
    | LafortuneSpec | WardSpec | OrenNayarSpec | KajiyaKaySpec | GGXSplitSumSpec | GltfPbrSpec | SumSpec,
    Field(discriminator="kind"),
]

#: Every ``kind`` the union accepts (kept equal to the core's models by tests/service/test_brdfs.py).
KINDS = ("phong", "lambert", "lobe1d", "microfacet", "torrance-sparrow", "ggx", "blinn-phong", "lafortune", "ward",
         "oren-nayar", "kajiya-kay", "ggx-ld", "gltf-pbr", "sum")
#: Kinds that are presets (the core expands them into a sum; the stored canonical spec is that sum).
PRESETS = ("gltf-pbr",)
