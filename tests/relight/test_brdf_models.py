"""Tests of relight.brdf.models and relight.brdf.spec against independent forms.

References: closed forms written out here, a scalar transcription of Mitsuba 3's roughconductor (docs/facts.md),
brute-force Gauss-Legendre x uniform-azimuth quadrature of the directional albedo, and textbook Fresnel values.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from relight.brdf import (
    GGX,
    BlinnPhong,
    F_conductor,
    F_schlick,
    G1_smith_beckmann,
    G1_smith_ggx,
    IsotropicBRDF,
    KajiyaKay,
    Lafortune,
    Lambert,
    Lobe,
    Lobe1D,
    Microfacet,
    OrenNayar,
    Phong,
    SumBRDF,
    TorranceSparrow,
    WardIsotropic,
    brdf_to_spec,
    parse_brdf,
)
from relight.brdf.models import blinn_phong_norm
from relight.errors import InputError

RNG_SEED = 42
Z = np.array([0.0, 0.0, 1.0])


def random_hemisphere(rng: np.random.Generator, n: int, max_theta: float = 1.45) -> NDArray[np.float64]:
    mu = rng.uniform(np.cos(max_theta), 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - mu**2)
    return np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=-1)


def albedo(brdf: IsotropicBRDF, theta_o: float, n: int = 256) -> NDArray[np.float64]:
    """Directional albedo int f(wi, wo) cos(theta_i) dwi over the hemisphere (Gauss-Legendre in cos x midpoint phi)."""
    mu, w = np.polynomial.legendre.leggauss(n)
    mu, w = 0.5 * (mu + 1), 0.5 * w
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    m, p = np.meshgrid(mu, phi, indexing="ij")
    st = np.sqrt(1 - m**2)
    wi = np.stack([st * np.cos(p), st * np.sin(p), m], -1)
    wo = np.broadcast_to([np.sin(theta_o), 0.0, np.cos(theta_o)], wi.shape)
    f = brdf.f(wi, wo, np.broadcast_to(Z, wi.shape))
    return np.asarray(np.einsum("ij...,i->...", f * m[..., None], w) * (np.pi / n))


# ---------------------------------------------------------------- radial lobes


def test_phong_closed_form_and_normalisation() -> None:
    s = 32.0
    lobe = Phong(s)
    th = np.linspace(0, np.pi, 181)
    got = lobe.rho_hat(th, 0.3 * np.ones_like(th), np.zeros_like(th))[..., 0]
    expected = np.where(th < np.pi / 2, (s + 1) / (2 * np.pi) * np.cos(th) ** s, 0.0)
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-300)
    # int rho_hat dL over the sphere = 2 pi int_0^1 u(t) dt = 1
    t, w = np.polynomial.legendre.leggauss(200)
    assert 2 * np.pi * np.sum(w * lobe.u(t)[:, 0]) == pytest.approx(1.0, rel=1e-12)
    assert lobe.radially_symmetric and lobe.azimuthally_symmetric and lobe.center == "R"
    assert Phong(1e-9).u(np.array([-0.5, 0.5]))[:, 0].tolist() == pytest.approx([0.0, 1 / (2 * np.pi)])


def test_lambert() -> None:
    lobe = Lambert([0.2, 0.5, 1.0])
    assert lobe.center == "N" and lobe.channels == 3 and lobe.radially_symmetric
    expected = np.array([[0.1 / np.pi, 0.25 / np.pi, 0.5 / np.pi], [0, 0, 0]])
    np.testing.assert_allclose(lobe.u(np.array([0.5, -0.5])), expected)
    assert Lambert().u(np.array(1.0))[0] == pytest.approx(1 / np.pi)


def test_lobe1d_table_and_callable() -> None:
    lobe = Lobe1D({"t": [0.0, 0.5, 1.0], "u": [0.0, 1.0, 3.0]})
    np.testing.assert_allclose(lobe.u(np.array([-0.5, 0.25, 0.75, 1.0]))[:, 0], [0.0, 0.5, 2.0, 3.0])
    assert lobe.params() == {"center": "R", "table": [[0.0, 0.0], [0.5, 1.0], [1.0, 3.0]]}
    assert Lobe1D([[0.0, 0.0], [0.5, 1.0], [1.0, 3.0]]).params() == lobe.params()  # radial's row form
    fn = Lobe1D(lambda t: np.maximum(t, 0.0) ** 2)
    np.testing.assert_allclose(fn.u(np.array([-1.0, 0.5]))[:, 0], [0.0, 0.25])
    with pytest.raises(InputError, match="callable cannot be serialised"):
        fn.params()
    with pytest.raises(InputError, match="increase strictly"):
        Lobe1D({"t": [0.0, 0.0, 1.0], "u": [1, 2, 3]})
    with pytest.raises(InputError, match=r"\[-1, 1\]"):
        Lobe1D({"t": [0.0, 2.0], "u": [1, 2]})
    with pytest.raises(InputError, match="non-finite"):
        Lobe1D({"t": [0.0, 1.0], "u": [1, np.nan]})
    with pytest.raises(InputError, match="one row per t"):
        Lobe1D({"t": [0.0, 0.5, 1.0], "u": [1, 2]})
    rgb = Lobe1D({"t": [-1, 1], "u": [[0, 0, 0], [1, 2, 3]], "center": "N"})
    assert rgb.channels == 3 and rgb.center == "N"


# ---------------------------------------------------------------- microfacet terms and models


def mitsuba_roughconductor_none(wi: NDArray[np.float64], wo: NDArray[np.float64], a: float) -> float:
    """Scalar transcription of docs/facts.md: Mitsuba 3 roughconductor, beckmann, material="none" (F = 1)."""
    h = (wi + wo) / np.linalg.norm(wi + wo)
    cos_h = h[2]
    tan2 = (1 - cos_h**2) / cos_h**2
    d = math.exp(-tan2 / a**2) / (math.pi * a**2 * cos_h**4)

    def g1(v: NDArray[np.float64]) -> float:
        tan = math.sqrt(1 - v[2] ** 2) / v[2]
        if tan == 0:
            return 1.0
        ap = 1 / (a * tan)
        return 1.0 if ap >= 1.6 else (3.535 * ap + 2.181 * ap**2) / (1 + 2.276 * ap + 2.577 * ap**2)

    eval_value = d * g1(wi) * g1(wo) / (4 * wi[2])  # Mitsuba eval(): f_r * cos(theta_o), wo on the light side
    return float(eval_value / wo[2])


@pytest.mark.parametrize("alpha", [0.05, 0.2, 0.6])
def test_torrance_sparrow_equals_mitsuba_roughconductor(alpha: float) -> None:
    rng = np.random.default_rng(RNG_SEED)
    wi, wo = random_hemisphere(rng, 300), random_hemisphere(rng, 300)
    got = TorranceSparrow(alpha, fresnel="none").f(wi, wo, np.broadcast_to(Z, wi.shape))[:, 0]
    expected = np.array([mitsuba_roughconductor_none(a, b, alpha) for a, b in zip(wi, wo, strict=True)])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-300)


def test_g1_terms() -> None:
    # Walter's rational approximation is continuous at a' = 1.6 and tends to 1 at normal incidence
    a = 0.3
    tan = 1 / (1.6 * a)
    cos = 1 / math.sqrt(1 + tan**2)
    below = G1_smith_beckmann(np.array([cos * (1 - 1e-9)]), a)[0]
    assert below == pytest.approx(1.0, abs=2e-3)
    assert G1_smith_beckmann(np.array([1.0]), a)[0] == 1.0 and G1_smith_beckmann(np.array([0.0]), a)[0] == 0.0
    # GGX: exact Smith G1 = 2 / (1 + sqrt(1 + a^2 tan^2)); at tan = 1/a: 2 / (1 + sqrt 2)
    assert G1_smith_ggx(np.array([cos]), 1 / tan)[0] == pytest.approx(2 / (1 + math.sqrt(2)))


def test_fresnel_terms() -> None:
    # dielectric limit k = 0 at normal incidence: ((n-1)/(n+1))^2; conductor: ((n-1)^2 + k^2)/((n+1)^2 + k^2)
    f = F_conductor(np.array([1.0]), [1.5, 0.2], [0.0, 3.0])[0]
    np.testing.assert_allclose(f, [0.04, (0.8**2 + 9) / (1.2**2 + 9)], rtol=1e-14)
    # grazing incidence -> 1 ; s/p average at 45 degrees for a dielectric n = 1.5 (Fresnel equations)
    assert F_conductor(np.array([0.0]), 1.5, 0.0)[0] == pytest.approx(1.0)
    ci = math.cos(math.pi / 4)
    ct = math.sqrt(1 - (math.sin(math.pi / 4) / 1.5) ** 2)
    rs = ((ci - 1.5 * ct) / (ci + 1.5 * ct)) ** 2
    rp = ((1.5 * ci - ct) / (1.5 * ci + ct)) ** 2
    assert F_conductor(np.array([ci]), 1.5, 0.0)[0] == pytest.approx(0.5 * (rs + rp), rel=1e-13)
    np.testing.assert_allclose(F_schlick(np.array([1.0, 0.0]), [0.04, 0.5]), [[0.04, 0.5], [1.0, 1.0]])


def test_torrance_sparrow_fresnel_and_channels() -> None:
    rng = np.random.default_rng(RNG_SEED)
    wi, wo = random_hemisphere(rng, 50), random_hemisphere(rng, 50)
    n = np.broadcast_to(Z, wi.shape)
    base = TorranceSparrow(0.3).f(wi, wo, n)
    gold = TorranceSparrow(0.3, fresnel="conductor", eta=[0.143, 0.374, 1.442], k=[3.983, 2.385, 1.603])
    assert gold.channels == 3
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    expected = base * F_conductor(np.einsum("ij,ij->i", wi, h), gold.eta, gold.k)
    np.testing.assert_allclose(gold.f(wi, wo, n), expected, rtol=1e-13)
    ggx = GGX(0.3, fresnel="schlick", f0=0.04)
    assert ggx.params() == {"alpha": 0.3, "f0": 0.04, "fresnel": "schlick"}


def test_microfacet_eq11_normalisation_and_hemisphere() -> None:
    """int rho_hat dL ~ 1 at V = N for small sigma (seed 000 eq. 11 is a rho_hat); 0 where N.L <= 0."""
    for sigma in (0.05, 0.1):
        lobe = Microfacet(sigma)
        # V = N means theta_o = 0 in the reflection frame (R = V = N)
        t, w = np.polynomial.legendre.leggauss(400)
        theta = 0.5 * np.pi * (t + 1) / 2 * 1.0  # theta_i in [0, pi/2]
        wt = 0.5 * np.pi / 2 * w
        vals = lobe.rho_hat(theta, np.zeros_like(theta), np.zeros_like(theta))[:, 0]
        integral = 2 * np.pi * np.sum(wt * vals * np.sin(theta))
        assert integral == pytest.approx(1.0, abs=2 * sigma**2)
    lobe = Microfacet(0.2)
    # L beyond the tangent plane of N gives 0: theta_o = 0 so N = R = +z; theta_i > pi/2 is below
    assert lobe.rho_hat(np.array([1.6, 2.5]), np.zeros(2), np.zeros(2))[:, 0].tolist() == [0.0, 0.0]
    # direct: theta_h between N and H
    L, V = np.array([np.sin(0.4), 0, np.cos(0.4)]), Z
    h = (L + V) / np.linalg.norm(L + V)
    expected = math.exp(-((math.acos(h[2]) / 0.2) ** 2)) / (4 * math.pi * 0.04)
    assert lobe.rho_hat(np.array(0.4), np.array(0.0), np.array(0.0))[0] == pytest.approx(expected)
    assert lobe.f(L, V, Z)[0] == pytest.approx(expected / math.cos(0.4))


def test_hemisphere_restriction_of_general_brdfs() -> None:
    """rho_hat vanishes where L is below the surface (N.L <= 0) in the reflection frame."""
    theta_o = np.full(7, 0.6)  # N is at angle 0.3 from R toward V (+x)
    theta_i = np.full(7, 2.0)
    phi = np.linspace(-0.5, 0.5, 7) + np.pi  # L far on the side away from V: N.L < 0
    for lobe in (TorranceSparrow(0.3), GGX(0.2), BlinnPhong(16), WardIsotropic(0.3, 0.2, 0.2), OrenNayar(0.3)):
        assert np.all(lobe.rho_hat(theta_i, theta_o, phi) == 0.0), lobe.kind
    # and rho_hat = f(L, V, N) max(N.L, 0) where both are above
    lobe = WardIsotropic(0.3, 0.2, 0.2)
    from relight.brdf.base import reflection_frame

    ti, to, ph = np.array([0.2, 0.5]), np.array([0.4, 1.0]), np.array([0.3, 2.0])
    L, V, N = reflection_frame(ti, to, ph)
    np.testing.assert_allclose(
        lobe.rho_hat(ti, to, ph), lobe.f(L, V, N) * np.einsum("ij,ij->i", N, L)[:, None], rtol=1e-14
    )


RECIPROCAL = [
    TorranceSparrow(0.3),
    TorranceSparrow(0.1, fresnel="schlick", f0=[0.9, 0.5, 0.2]),
    GGX(0.4, fresnel="conductor", eta=1.2, k=2.0),
    BlinnPhong(20),
    Lafortune(preset="housepaint-blue"),
    WardIsotropic([0.2, 0.3, 0.4], 0.3, 0.15),
    OrenNayar(0.4, 0.8),
]


@pytest.mark.parametrize("brdf", RECIPROCAL, ids=lambda b: b.kind)
def test_reciprocity(brdf: IsotropicBRDF) -> None:
    rng = np.random.default_rng(RNG_SEED)
    wi, wo = random_hemisphere(rng, 200), random_hemisphere(rng, 200)
    n = np.broadcast_to(Z, wi.shape)
    np.testing.assert_allclose(brdf.f(wi, wo, n), brdf.f(wo, wi, n), rtol=1e-12, atol=1e-300)


def test_frame_independence() -> None:
    """f depends only on the relative geometry: rotating wi, wo and n together leaves it unchanged."""
    rng = np.random.default_rng(RNG_SEED)
    wi, wo = random_hemisphere(rng, 60), random_hemisphere(rng, 60)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    for brdf in RECIPROCAL:
        a = brdf.f(wi, wo, np.broadcast_to(Z, wi.shape))
        b = brdf.f(wi @ q.T, wo @ q.T, np.broadcast_to(q @ Z, wi.shape))
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-14)


NORMALISED = [
    (TorranceSparrow(0.3), 1e-3),
    (TorranceSparrow(0.05), 1e-3),
    (GGX(0.3), 1e-3),
    (BlinnPhong(8), 1e-3),
    (BlinnPhong(64), 1e-3),
    (WardIsotropic(0.0, 1.0, 0.2), 1e-3),
    (WardIsotropic(0.3, 0.7, 0.6), 1e-3),
    (OrenNayar(1.0, 1.0), 1e-3),
    (Lafortune(preset="housepaint-blue"), 1e-3),
]


@pytest.mark.parametrize(("brdf", "tol"), NORMALISED, ids=lambda b: getattr(b, "kind", ""))
def test_white_furnace_albedo_at_most_one(brdf: IsotropicBRDF, tol: float) -> None:
    for theta_o in (0.0, 0.6, 1.2, 1.5):
        assert np.all(albedo(brdf, theta_o) <= 1.0 + tol), (brdf.kind, theta_o)


def test_albedo_exact_values() -> None:
    # Blinn-Phong with Giesen's normalisation has albedo exactly 1 at normal incidence; Beckmann TS (no
    # Fresnel) loses almost nothing at small roughness; Lambert's albedo is its parameter.
    assert albedo(BlinnPhong(32), 0.0)[0] == pytest.approx(1.0, abs=1e-6)
    assert blinn_phong_norm(0.0) == pytest.approx(1 / np.pi)  # s = 0: the constant (Lambertian) BRDF
    assert albedo(TorranceSparrow(0.1), 0.3)[0] == pytest.approx(1.0, abs=2e-3)
    assert albedo(WardIsotropic(0.5, 0.0, 0.1), 0.7)[0] == pytest.approx(0.5, rel=1e-6)
    assert albedo(OrenNayar(0.0, 0.6), 1.0)[0] == pytest.approx(0.6, rel=1e-6)


def test_kajiya_kay_depends_only_on_angle_difference() -> None:
    lobe = KajiyaKay(32)
    rng = np.random.default_rng(RNG_SEED)
    ti, to, ph = rng.uniform(0, np.pi, 50), rng.uniform(0, np.pi, 50), rng.uniform(-np.pi, np.pi, 50)
    base = lobe.rho_hat(ti, to, ph)[:, 0]
    shift = rng.uniform(-0.3, 0.3, 50)
    np.testing.assert_allclose(lobe.rho_hat(ti + shift, to + shift, ph)[:, 0], base, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(lobe.rho_hat(ti, to, rng.uniform(-3, 3, 50))[:, 0], base)
    np.testing.assert_allclose(base, np.maximum(np.cos(ti - to), 0) ** 32)
    assert lobe.center == "T" and lobe.azimuthally_symmetric and not lobe.radially_symmetric


def test_lafortune_definition_and_presets() -> None:
    lobe = Lafortune(lobes=[(-1.0, 0.9, 10.0)], diffuse=0.3)
    wi = np.array([np.sin(0.4), 0.0, np.cos(0.4)])
    wo = np.array([-np.sin(0.4), 0.0, np.cos(0.4)])  # mirror direction
    ux_vx = wi[0] * wo[0]
    expected = 0.3 / np.pi + (-1.0 * ux_vx + 0.9 * wi[2] * wo[2]) ** 10
    assert lobe.f(wi, wo, Z)[0] == pytest.approx(expected)
    paint = Lafortune(preset="housepaint-blue")
    assert paint.channels == 3 and paint.params() == {"preset": "housepaint-blue"}
    skin = Lafortune(preset="skin")
    assert skin.channels == 3 and skin.params() == {"preset": "skin"}
    # Marschner et al.'s skin fit (pbrt v1 skin.cpp): the forward-scattering third lobe dominates near grazing.
    t = np.radians(80.0)
    wi_g, wo_g = np.array([np.sin(t), 0.0, np.cos(t)]), np.array([-np.sin(t), 0.0, np.cos(t)])
    xy, zz = wi_g[0] * wo_g[0], wi_g[2] * wo_g[2]
    red = 0.428425 / np.pi + sum(
        max(cxy * xy + cz * zz, 0.0) ** n
        for cxy, cz, n in [(-1.131747, -1.209182, 6.421658), (-0.546570, 0.380123, 3.685044),
                           (-0.998888, 0.857998, 64.208486)]
    )  # fmt: skip
    assert skin.f(wi_g, wo_g, Z)[0] == pytest.approx(red, rel=1e-12)
    with pytest.raises(InputError, match="unknown preset 'marble'"):
        Lafortune(preset="marble")


def test_flags() -> None:
    assert Phong(4).radially_symmetric and Lambert().radially_symmetric
    assert Lobe1D({"t": [0, 1], "u": [0, 1]}).radially_symmetric
    for lobe in (Microfacet(0.2), TorranceSparrow(0.2), BlinnPhong(8), WardIsotropic(0.1, 0.1, 0.1), OrenNayar(0.1)):
        assert not lobe.radially_symmetric and not lobe.azimuthally_symmetric
    s = SumBRDF([Phong(8), Phong(64)])
    assert s.radially_symmetric and s.center == "R"
    mixed = SumBRDF([Lambert([0.5, 0.4, 0.3]), Phong(8)])
    assert not mixed.radially_symmetric and mixed.center is None and mixed.channels == 3


# ---------------------------------------------------------------- validation

BAD = [
    (lambda: Phong(-1), "s", "-1"),
    (lambda: Phong(float("nan")), "s", "nan"),
    (lambda: Phong(float("inf")), "s", "inf"),
    (lambda: Lambert(1.5), "albedo", "1.5"),
    (lambda: Lambert([0.1, 0.2]), "albedo", "2 values"),
    (lambda: Microfacet(0.0), "sigma", "0.0"),
    (lambda: TorranceSparrow(0.0), "alpha", "0.0"),
    (lambda: TorranceSparrow(0.2, distribution="phong"), "distribution", "phong"),
    (lambda: TorranceSparrow(0.2, fresnel="dielectric"), "fresnel", "dielectric"),
    (lambda: TorranceSparrow(0.2, fresnel="schlick", f0=1.2), "f0", "1.2"),
    (lambda: TorranceSparrow(0.2, fresnel="conductor", eta=1.0), "eta and k", "conductor"),
    (lambda: TorranceSparrow(0.2, fresnel="conductor", eta=-1.0, k=1.0), "eta", "-1.0"),
    (lambda: TorranceSparrow(0.2, f0=0.5), "f0", "none"),
    (lambda: GGX(float("nan")), "alpha", "nan"),
    (lambda: BlinnPhong(-2), "s", "-2"),
    (lambda: Lafortune(lobes=[(1.0, 1.0)]), "lobes", "Cx, Cz, n"),
    (lambda: Lafortune(lobes=[(1.0, 1.0, -3.0)]), "lobes", "-3.0"),
    (lambda: WardIsotropic(0.5, 0.5, -0.1), "alpha", "-0.1"),
    (lambda: WardIsotropic(0.5, 1.5, 0.1), "rho_s", "1.5"),
    (lambda: OrenNayar(-0.1), "sigma", "-0.1"),
    (lambda: OrenNayar(0.1, albedo="red"), "albedo", "red"),  # type: ignore[arg-type]
    (lambda: KajiyaKay(float("inf")), "s", "inf"),
    (lambda: SumBRDF([]), "sum", "at least one"),
]


@pytest.mark.parametrize(("make", "field", "value"), BAD)
def test_invalid_parameters_raise_input_error(make: Any, field: str, value: str) -> None:
    with pytest.raises(InputError) as err:
        make()
    msg = str(err.value)
    assert field in msg and value in msg and "\n" not in msg


# ---------------------------------------------------------------- specs

SPECS = [
    "lambert",
    "lambert:albedo=0.5/0.4/0.3",
    "phong:s=32",
    "microfacet:sigma=0.2",
    "torrance-sparrow:alpha=0.2,fresnel=none",
    "torrance-sparrow:alpha=0.2,distribution=ggx,fresnel=conductor,eta=0.2/0.4/1.4,k=4/2.4/1.6",
    "ggx:alpha=0.3",
    "ggx:alpha=0.3,fresnel=schlick,f0=0.04",
    "blinn-phong:s=64",
    "lafortune:preset=housepaint-blue",
    "ward:alpha=0.1,rho_s=0.05,rho_d=0.5",
    "oren-nayar:sigma=0.3",
    "oren-nayar:sigma=0.3,albedo=0.7",
    "kajiya-kay:s=32",
    "lambert+phong:s=64",
    " lambert:albedo=0.2 + ggx:alpha=0.1 + kajiya-kay:s=8 ",
]


def same_brdf(a: Lobe | SumBRDF, b: Lobe | SumBRDF) -> None:
    assert brdf_to_spec(a) == brdf_to_spec(b)
    lobes_a = a.lobes if isinstance(a, SumBRDF) else [a]
    lobes_b = b.lobes if isinstance(b, SumBRDF) else [b]
    rng = np.random.default_rng(RNG_SEED)
    ti, to, ph = rng.uniform(0, 1.5, 20), rng.uniform(0, 1.5, 20), rng.uniform(-3, 3, 20)
    for la, lb in zip(lobes_a, lobes_b, strict=True):
        assert type(la) is type(lb)
        np.testing.assert_array_equal(la.rho_hat(ti, to, ph), lb.rho_hat(ti, to, ph))


@pytest.mark.parametrize("spec", SPECS)
def test_spec_round_trip(spec: str) -> None:
    obj = parse_brdf(spec)
    canon = brdf_to_spec(obj)
    assert list(canon) == sorted(canon)
    json.dumps(canon)  # JSON-serialisable
    same_brdf(obj, parse_brdf(canon))
    assert brdf_to_spec(parse_brdf(json.loads(json.dumps(canon)))) == canon


def test_spec_values() -> None:
    obj = parse_brdf("ward:alpha=0.1,rho_s=0.05,rho_d=0.5")
    assert brdf_to_spec(obj) == {"alpha": 0.1, "kind": "ward", "rho_d": 0.5, "rho_s": 0.05}
    s = parse_brdf("lambert+phong:s=64")
    assert isinstance(s, SumBRDF) and [x.kind for x in s.lobes] == ["lambert", "phong"]
    expected = {"kind": "sum", "lobes": [{"albedo": 1.0, "kind": "lambert"}, {"kind": "phong", "s": 64.0}]}
    assert brdf_to_spec(s) == expected
    assert isinstance(parse_brdf({"kind": "sum", "lobes": [{"kind": "phong", "s": 8}]}), SumBRDF)
    lf = parse_brdf({"kind": "lafortune", "diffuse": 0.2, "lobes": [[-1, 0.9, 10]]})
    assert brdf_to_spec(lf) == {"diffuse": 0.2, "kind": "lafortune", "lobes": [[-1.0, 0.9, 10.0]]}


def test_spec_json_files(tmp_path: Path) -> None:
    table = tmp_path / "lobe.json"
    table.write_text(json.dumps({"t": [0.0, 0.5, 1.0], "u": [0.0, 1.0, 2.0]}))
    lobe = parse_brdf(f"lobe1d:{table}")
    assert isinstance(lobe, Lobe1D) and lobe.u(np.array([0.75]))[0, 0] == pytest.approx(1.5)
    same_brdf(lobe, parse_brdf(brdf_to_spec(lobe)))
    spec_file = tmp_path / "mat.json"
    spec_file.write_text(json.dumps([{"kind": "lambert", "albedo": 0.3}, {"kind": "lobe1d", "path": "lobe.json"}]))
    mat = parse_brdf(spec_file)  # PathLike; relative path resolved against the JSON file's folder
    assert isinstance(mat, SumBRDF) and len(mat.lobes) == 2
    same_brdf(mat, parse_brdf(str(spec_file)))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        parse_brdf(str(bad))
    with pytest.raises(InputError, match="no such file"):
        parse_brdf(str(tmp_path / "missing.json"))


SPEC_ERRORS = [
    ("lamberto", ["unknown BRDF kind 'lamberto'", "phong", "kajiya-kay"]),
    ("phong:q=3", ["unknown key 'q'", "['s']"]),
    ("phong:s=abc", ["s must be a number", "'abc'"]),
    ("phong:s=nan", ["s must be finite", "'nan'"]),
    ("phong:s", ["expected key=value", "'s'"]),
    ("phong:s=-3", ["s must lie in", "-3"]),
    ("torrance-sparrow:alpha=0.2,fresnel=glass", ["fresnel", "'glass'"]),
    ("ward:alpha=0.1,rho_s=0.05", ["ward", "rho_d"]),
    ("lambert:albedo=0.1/0.2", ["albedo must be one number or 3", "0.1/0.2"]),
    ("phong:s=3,s=4", ["given twice"]),
    ("", ["empty BRDF spec"]),
    ("merl:", ["needs a file path"]),
    ("lambert++phong:s=2", ["empty BRDF term"]),
]


@pytest.mark.parametrize(("spec", "fragments"), SPEC_ERRORS)
def test_spec_errors(spec: str, fragments: list[str]) -> None:
    with pytest.raises(InputError) as err:
        parse_brdf(spec)
    for frag in fragments:
        assert frag in str(err.value), (frag, str(err.value))


def test_spec_dict_errors() -> None:
    with pytest.raises(InputError, match="needs a 'kind'"):
        parse_brdf({"s": 3})
    with pytest.raises(InputError, match=r"unknown key 'sigma'; valid keys are \['s'\]"):
        parse_brdf({"kind": "phong", "sigma": 3})
    with pytest.raises(InputError, match="unknown BRDF kind 'glass'"):
        parse_brdf({"kind": "glass"})
    with pytest.raises(InputError, match="must be a number"):
        parse_brdf({"kind": "phong", "s": "32"})
    with pytest.raises(InputError, match="callable"):
        brdf_to_spec(Lobe1D(lambda t: t))
