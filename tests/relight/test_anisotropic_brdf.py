"""Tests of the tangent-frame BRDF interface (relight.brdf.frame), the anisotropic models (relight.brdf.anisotropic)
and their spec strings.

References: Mitsuba 3's ``roughconductor`` through ``BSDF.eval`` (float32 inside Mitsuba, see the tolerance there),
the isotropic relight models for
alpha_u = alpha_v (same formulas, 1e-12), closed forms written out independently in spherical angles, and
reciprocity.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from relight import mitsuba_twin
from relight.brdf.anisotropic import AnisotropicTorranceSparrow, AshikhminShirley, WardAnisotropic
from relight.brdf.frame import FrameSum, LobeAdapter, as_frame_brdf
from relight.brdf.models import KajiyaKay, TorranceSparrow, WardIsotropic
from relight.brdf.radial import Phong
from relight.brdf.spec import brdf_to_spec, parse_brdf, parse_frame_brdf
from relight.errors import InputError
from relight.tangent_frames import projected_frames

F64 = NDArray[np.float64]
Z = np.array([0.0, 0.0, 1.0])


def upper_dirs(n: int, seed: int, grazing: bool = False) -> F64:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) * (0.02 if grazing else 1.0)
    return np.asarray(v / np.linalg.norm(v, axis=1, keepdims=True))


@pytest.mark.parametrize("dist", ["beckmann", "ggx"])
@pytest.mark.parametrize("alphas", [(0.1, 0.4), (0.5, 0.15), (0.3, 0.3)])
def test_torrance_sparrow_is_mitsubas_roughconductor(dist: str, alphas: tuple[float, float]) -> None:
    brdf = AnisotropicTorranceSparrow(*alphas, distribution=dist)
    bsdf = mitsuba_twin.twin(brdf)
    assert bsdf == {"type": "roughconductor", "distribution": dist, "alpha_u": alphas[0], "alpha_v": alphas[1],
                    "material": "none"}
    # Mitsuba computes in float32. Away from grazing: 1e-5 relative (measured <= 5e-6: exp(-x) with x up to ~50
    # carries ~x 2^-24). Within ~2 degrees of the horizon the float32 rounding of the directions themselves is
    # amplified by the 1/cos factors and the steep G1: 1e-4 (measured <= 4e-5).
    for grazing, tol in ((False, 1e-5), (True, 1e-4)):
        wi = upper_dirs(3000, 1, grazing)  # toward the viewer
        wl = upper_dirs(3000, 2, grazing)  # toward the light
        ref = mitsuba_twin.bsdf_eval(bsdf, wi, wl)[:, 0]  # f_r cos(theta_light)
        ours = brdf.fcos_local(wl, wi)[:, 0]
        scale = np.maximum(np.abs(ref), 1e-3 * np.abs(ref).max())
        assert np.max(np.abs(ours - ref) / scale) < tol, grazing


@pytest.mark.parametrize("dist", ["beckmann", "ggx"])
def test_isotropic_limits(dist: str) -> None:
    wi, wo = upper_dirs(500, 5), upper_dirs(500, 6)
    a = AnisotropicTorranceSparrow(0.27, 0.27, distribution=dist, fresnel="schlick", f0=[0.9, 0.5, 0.1])
    b = TorranceSparrow(0.27, dist, "schlick", f0=[0.9, 0.5, 0.1])
    assert np.abs(a.f_local(wi, wo) - b.f(wi, wo, Z)).max() < 1e-12 * np.abs(b.f(wi, wo, Z)).max()
    w1 = WardAnisotropic(0.2, 0.2, rho_d=0.1, rho_s=0.4)
    w2 = WardIsotropic(rho_d=0.1, rho_s=0.4, alpha=0.2)
    assert np.allclose(w1.f_local(wi, wo), w2.f(wi, wo, Z), rtol=1e-12, atol=0)


def test_ashikhmin_shirley_closed_form_and_reciprocity() -> None:
    wi, wo = upper_dirs(400, 7), upper_dirs(400, 8)
    nu, nv, rs, rd = 48.0, 16.0, 0.05, 0.3
    brdf = AshikhminShirley(nu, nv, rs, rd)
    # AS 2000 eqs. 4-5 in spherical angles of h: exponent nu cos^2(phi_h) + nv sin^2(phi_h)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    th_h, ph_h = np.arccos(h[:, 2]), np.arctan2(h[:, 1], h[:, 0])
    kh = np.sum(h * wi, axis=1)
    spec = (np.sqrt((nu + 1) * (nv + 1)) / (8 * np.pi) * np.cos(th_h) ** (nu * np.cos(ph_h) ** 2 +
            nv * np.sin(ph_h) ** 2) / (kh * np.maximum(wi[:, 2], wo[:, 2])) * (rs + (1 - rs) * (1 - kh) ** 5))
    diff = 28 * rd / (23 * np.pi) * (1 - rs) * (1 - (1 - wi[:, 2] / 2) ** 5) * (1 - (1 - wo[:, 2] / 2) ** 5)
    assert np.allclose(brdf.f_local(wi, wo)[:, 0], spec + diff, rtol=1e-12, atol=0)
    assert np.allclose(brdf.f_local(wi, wo), brdf.f_local(wo, wi), rtol=1e-12, atol=0)
    # anisotropy: swapping nu and nv is a 90-degree turn of the frame about n
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(AshikhminShirley(nv, nu, rs, rd).f_local(wi @ turn.T, wo @ turn.T), brdf.f_local(wi, wo),
                       rtol=1e-12)
    # mirror-image directions (h exactly along n) give the finite limit, no NaN
    v = np.array([[0.3, 0.1, np.sqrt(0.9)]])
    assert np.all(np.isfinite(brdf.f_local(v * [-1, -1, 1], v)))
    # below the horizon: 0
    assert brdf.f_local(np.array([[0.0, 0.6, -0.8]]), v)[0, 0] == 0.0


def test_world_frame_evaluation_equals_local() -> None:
    rng = np.random.default_rng(9)
    n = rng.normal(size=(300, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    frames = projected_frames(n, [0.2, 0.9, 0.1])
    wi, wo = upper_dirs(300, 10), upper_dirs(300, 11)
    wi_w, wo_w = np.einsum("nij,ni->nj", frames, wi), np.einsum("nij,ni->nj", frames, wo)  # F^T u
    brdf = AshikhminShirley(24, 8)
    assert np.allclose(brdf.f(wi_w, wo_w, frames), brdf.f_local(wi, wo), rtol=1e-12, atol=1e-14)


def test_adapter_reproduces_relight_lobes() -> None:
    wi, wo = upper_dirs(300, 12), upper_dirs(300, 13)
    ts = TorranceSparrow(0.2)
    a = as_frame_brdf(ts)
    assert isinstance(a, LobeAdapter) and a.isotropic
    assert np.array_equal(a.f_local(wi, wo), ts.f(wi, wo, Z))
    assert np.allclose(a.fcos_local(wi, wo), ts.f(wi, wo, Z) * wi[:, 2:3], rtol=1e-15)
    # a radial lobe about R: u(R . wi) with R the mirror of wo, not clipped at the horizon (seed 000's lobe)
    ph = as_frame_brdf(Phong(8.0))
    r = wo * [-1, -1, 1]
    below = wi * [1, 1, -1]
    assert np.allclose(ph.fcos_local(below, wo)[:, 0], 9 / (2 * np.pi) * np.clip(np.sum(r * below, 1), 0, 1) ** 8)
    # Kajiya–Kay's tangent is the frame's tangent x
    kk = as_frame_brdf(KajiyaKay(4.0))
    assert not kk.isotropic
    ti, to = np.arccos(wi[:, 0]), np.arccos(wo[:, 0])
    assert np.allclose(kk.fcos_local(wi, wo)[:, 0], np.clip(np.cos(ti - to), 0, None) ** 4, atol=1e-12)


SPECS = {
    "torrance-sparrow:alpha_u=0.1,alpha_v=0.4,distribution=ggx,fresnel=none": AnisotropicTorranceSparrow,
    "ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0": AshikhminShirley,
    "ward:alpha_x=0.1,alpha_y=0.3,rho_d=0.1,rho_s=0.5": WardAnisotropic,
}


@pytest.mark.parametrize("spec", sorted(SPECS))
def test_spec_strings_round_trip(spec: str) -> None:
    b = parse_frame_brdf(spec)
    assert isinstance(b, SPECS[spec])
    again = parse_frame_brdf(brdf_to_spec(b))
    wi, wo = upper_dirs(50, 14), upper_dirs(50, 15)
    assert np.array_equal(again.f_local(wi, wo), b.f_local(wi, wo))
    with pytest.raises(InputError, match="anisotropic"):
        parse_brdf(spec)


def test_isotropic_specs_unchanged_and_sums() -> None:
    assert isinstance(parse_brdf("ward:alpha=0.1,rho_s=0.05,rho_d=0.5"), WardIsotropic)
    assert isinstance(parse_brdf("torrance-sparrow:alpha=0.2"), TorranceSparrow)
    s = parse_frame_brdf("lambert:albedo=0.5+ashikhmin-shirley:nu=12,nv=4")
    assert isinstance(s, FrameSum) and not s.isotropic and len(s.terms) == 2
    d = parse_frame_brdf({"kind": "sum", "lobes": [{"kind": "phong", "s": 8},
                                                   {"kind": "ward", "alpha_x": 0.1, "alpha_y": 0.2,
                                                    "rho_d": 0, "rho_s": 1}]})
    assert isinstance(d, FrameSum)


@pytest.mark.parametrize(("spec", "field"), [
    ("torrance-sparrow:alpha_u=0,alpha_v=0.2", "alpha_u"),
    ("torrance-sparrow:alpha_u=0.1,alpha_v=nan", "alpha_v"),
    ("torrance-sparrow:alpha_u=0.1", "alpha_v"),
    ("torrance-sparrow:alpha=0.1,alpha_u=0.1,alpha_v=0.2", "alpha_u"),
    ("ashikhmin-shirley:nu=-1,nv=4", "nu"),
    ("ashikhmin-shirley:nu=4,nv=0", "nv"),
    ("ashikhmin-shirley:nu=4,nv=4,rs=1.5", "rs"),
    ("ashikhmin-shirley:nu=4,nv=4,rd=-0.1", "rd"),
    ("ashikhmin-shirley:nu=4", "nv"),
    ("ashikhmin-shirley:nu=4,nv=4,speed=3", "speed"),
    ("ward:alpha_x=0.1,alpha_y=-0.2,rho_d=0,rho_s=1", "alpha_y"),
])
def test_invalid_parameters_name_the_field(spec: str, field: str) -> None:
    with pytest.raises(InputError, match=field):
        parse_frame_brdf(spec)
