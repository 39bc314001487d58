"""Cube chains of other lobe families (``--brdf SPEC``; relight.brdf.normal_view, docs/conventions.md "Chains of
other lobes") against the dense angular brute force of the same level kernel.

The chain test's criterion (tests/relight/test_cube_chain.py): every mip level within 1 % relative RMS (Rec. 709
luminance, over all texels) of the brute force of that level's kernel at the texel directions. The reference
kernels are written here in closed form from the BRDF formulas at view = normal (not through
``relight.brdf.normal_view``): glTF's GGX at v = n is ``D(h) G1(t) F(n.h) / 4`` with ``n.h = sqrt((1 + t) / 2)``
(G1(1) = 1 and the 1 / (4 t) cancels the cosine), its Lambert ``c_diff t / pi``, Phong ``(s + 1) / (2 pi) t^s``;
at r = 0 a level-rough term is ``F0`` times the map as three's PMREM copies it (the mirror limit). Both sides integrate
the same pixels, so the difference is the chain's SH truncation alone, which the default tolerance (energy
2.5e-5) predicts at ~0.5 %: the issue's 1 % is the limit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from sky_refs import sun_sky
from test_cube_chain import LEVEL_RMS, city, rel_rms

from relight.brdf.microfacet import D_ggx, G1_smith_ggx
from relight.cap_convolution import brute_force
from relight.conventions import sample_latlong
from relight.cube_chain import prefilter_chain
from relight.envmap import cube_face_dirs
from relight.errors import InputError


class Kernel:
    """A closed-form radial kernel ``K(t)`` (RGB), the only thing :func:`brute_force` asks of a lobe."""

    def __init__(self, fn: Any, k: int) -> None:
        self.fn, self.k = fn, k

    def u(self, t: np.ndarray) -> np.ndarray:
        return np.asarray(self.fn(np.clip(t, -1.0, 1.0)), dtype=np.float64)[..., self.k:self.k + 1]


def gltf_kernel(base: np.ndarray, metallic: float, r: float) -> Any:
    c_diff = base * (1.0 - metallic)
    f0 = 0.04 * (1.0 - metallic) + base * metallic
    a = r * r

    def fn(t: np.ndarray) -> np.ndarray:
        pos = np.maximum(t, 0.0)
        nh = np.sqrt(0.5 * (1.0 + t))
        fres = f0 + (1.0 - f0) * (1.0 - nh[..., None]) ** 5
        spec = np.where(t > 0, D_ggx(nh, a) * G1_smith_ggx(np.maximum(t, 1e-12), a) / 4.0, 0.0)
        return np.asarray(spec[..., None] * fres + pos[..., None] * c_diff / np.pi)
    return fn


def reference(pixels: np.ndarray, fn: Any, mirror: np.ndarray, size: int) -> np.ndarray:
    dirs = cube_face_dirs(size).reshape(-1, 3)
    # the mirror limit as three r187's PMREM copies the map (level 0): the mean of four bilinear taps a quarter
    # texel off the centre, which are the texel centres of the cube twice as fine
    fine = sample_latlong(pixels[None], cube_face_dirs(2 * size).reshape(-1, 3))[:, 0]
    out = mirror * fine.reshape(6, size, 2, size, 2, 3).mean(axis=(2, 4)).reshape(-1, 3)
    if fn is not None:
        for k in range(3):
            out[:, k] += brute_force(pixels, Kernel(fn, k), dirs)[:, k]  # type: ignore[arg-type]
    return np.asarray(out)


BASE = np.array([0.9, 0.6, 0.2])


@pytest.mark.parametrize(("name", "pixels", "target", "metallic"), [
    ("city", lambda: city(64), "three", 0.5),
    ("sun-sky", lambda: sun_sky(32), "babylon", 1.0),
])
def test_gltf_pbr_levels_match_the_brute_force(name: str, pixels: Any, target: str, metallic: float) -> None:
    # gltf-pbr without roughness: every level takes its roughness (the mirror limit at r = 0: F0 x the map)
    px = pixels()
    chain = prefilter_chain(px, target=target, size=16, brdf=f"gltf-pbr:base=0.9/0.6/0.2,metallic={metallic:g}")
    assert chain.brdf is not None and len(chain.levels) == 5
    f0 = 0.04 * (1.0 - metallic) + BASE * metallic
    for lv in chain.levels:
        if lv.roughness == 0.0:
            lam = BASE * (1 - metallic)
            fn = (lambda t, lam=lam: np.maximum(t, 0.0)[..., None] * lam / np.pi) if metallic < 1 else None
            ref = reference(px, fn, f0, lv.size)
        else:
            ref = reference(px, gltf_kernel(BASE, metallic, lv.roughness), np.zeros(3), lv.size)
        faces = lv.faces.reshape(-1, 3).astype(np.float64)
        err = rel_rms(faces, ref)
        assert err <= LEVEL_RMS, (name, lv.level, lv.roughness, lv.method, err)
        # the colour is the material's: the chain's channel ratios follow the reference's (no grey kernel)
        np.testing.assert_allclose(faces.mean(axis=0), ref.mean(axis=0), rtol=LEVEL_RMS)


def test_fixed_parameters_hold_at_every_level() -> None:
    # phong has no roughness, and lambert + a ggx-ld with a given roughness keep theirs: every level the same lobe
    px = sun_sky(32)
    s = 64.0
    chain = prefilter_chain(px, target="gltf", size=16, brdf="phong:s=64 + lambert:albedo=0.25")
    for lv in chain.levels:
        ref = reference(px, lambda t: (np.maximum(t, 0.0) ** s * (s + 1) / (2 * np.pi)
                                       + 0.25 * np.maximum(t, 0.0) / np.pi)[..., None] * np.ones(3),
                        np.zeros(3), lv.size)
        err = rel_rms(lv.faces.reshape(-1, 3).astype(np.float64), ref)
        assert err <= LEVEL_RMS, (lv.level, lv.method, err)


def test_ggx_ld_is_the_default_chain_and_bad_specs_are_refused() -> None:
    px = city(64)
    default = prefilter_chain(px, target="three", size=8)
    same = prefilter_chain(px, target="three", size=8, brdf="ggx-ld")
    assert all(np.array_equal(a.faces, b.faces) for a, b in zip(default.levels, same.levels, strict=True))
    fixed = prefilter_chain(px, target="three", size=8, levels=2, brdf="ggx-ld:roughness=0.5")
    assert fixed.levels[0].method != "sample"  # level 0 keeps the given roughness: no mirror
    np.testing.assert_allclose(fixed.levels[0].faces.mean(), fixed.levels[1].faces.mean(), rtol=0.02)
    for bad, match in [("kajiya-kay:s=8", "tangent"), ("nope:x=1", "unknown BRDF kind"),
                       ("gltf-pbr:metallic=2", "metallic"), ("ward:alpha_x=0.1,alpha_y=0.3,rho_d=0,rho_s=1",
                                                             "anisotropic")]:
        with pytest.raises(InputError, match=match):
            prefilter_chain(px, target="three", size=4, brdf=bad)
