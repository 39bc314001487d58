"""``gltf-pbr`` (relight.brdf.gltf_pbr) against the glTF 2.0 specification's BRDF (Appendix B), written out here
from the specification's formulas: ``c_diff / pi + F D V`` with ``F = F0 + (1 - F0)(1 - VoH)^5``,
``D = a^2 / (pi ((NoH)^2 (a^2 - 1) + 1)^2)`` and the separable Smith ``V`` (module docstring); the preset leaves
out the spec's ``(1 - F)`` diffuse weight (documented), so that is the one difference allowed for."""

from __future__ import annotations

import numpy as np
import pytest

from relight.brdf.models import GGX, SumBRDF
from relight.brdf.radial import Lambert
from relight.brdf.spec import brdf_to_spec, parse_brdf
from relight.errors import InputError


def _gltf_spec_f(wi: np.ndarray, wo: np.ndarray, base: np.ndarray, metallic: float, rough: float) -> np.ndarray:
    n = np.array([0.0, 0.0, 1.0])
    a = rough * rough
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    nol, nov, noh, voh = wi @ n, wo @ n, h @ n, np.sum(wo * h, axis=-1)
    f0 = 0.04 * (1 - metallic) + base * metallic
    f = f0 + (1 - f0) * ((1 - voh) ** 5)[:, None]
    d = a * a / (np.pi * (noh * noh * (a * a - 1) + 1) ** 2)
    v = 1 / ((nol + np.sqrt(a * a + (1 - a * a) * nol * nol)) * (nov + np.sqrt(a * a + (1 - a * a) * nov * nov)))
    c_diff = base * (1 - metallic)
    return np.asarray(c_diff / np.pi + f * (d * v)[:, None])


def _lobe_sum(lobes: list[object], wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    n = np.broadcast_to([0.0, 0.0, 1.0], wi.shape)
    total = np.zeros((wi.shape[0], 3))
    for lobe in lobes:
        if isinstance(lobe, Lambert):
            total += np.array(lobe.albedo) / np.pi  # the lobe is albedo / pi max(n.l, 0): the BRDF is albedo / pi
        else:
            assert isinstance(lobe, GGX)
            total += lobe.f(wi, wo, n)
    return total


@pytest.mark.parametrize(("base", "metallic", "rough"), [((0.9, 0.6, 0.2), 0.0, 0.4), ((0.9, 0.6, 0.2), 1.0, 0.15),
                                                         ((0.5, 0.5, 0.5), 0.3, 0.8)])
def test_preset_is_the_gltf_brdf(base: tuple[float, float, float], metallic: float, rough: float) -> None:
    spec = f"gltf-pbr:base={base[0]}/{base[1]}/{base[2]},metallic={metallic},roughness={rough}"
    brdf = parse_brdf(spec)
    lobes: list[object] = list(brdf.lobes) if isinstance(brdf, SumBRDF) else [brdf]  # one lobe comes bare
    rng = np.random.default_rng(42)
    wi, wo = rng.normal(size=(2, 400, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])  # upper hemisphere
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    np.testing.assert_allclose(_lobe_sum(lobes, wi, wo), _gltf_spec_f(wi, wo, np.array(base), metallic, rough),
                               rtol=1e-10)
    # the dict form and the canonical spec rebuild the same lobes
    again = parse_brdf({"kind": "gltf-pbr", "base": list(base), "metallic": metallic, "roughness": rough})
    assert brdf_to_spec(again) == brdf_to_spec(brdf) == brdf_to_spec(parse_brdf(brdf_to_spec(brdf)))
    assert (metallic == 1.0) == (len(lobes) == 1)  # a pure metal has no diffuse lobe


def test_bad_values_name_the_key() -> None:
    for bad, key in (("gltf-pbr:roughness=0", "roughness"), ("gltf-pbr:metallic=1.5", "metallic"),
                     ("gltf-pbr:base=2", "base"), ("gltf-pbr:shine=1", "shine")):
        with pytest.raises(InputError, match=key):
            parse_brdf(bad)
