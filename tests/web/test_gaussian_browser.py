"""Seed 002's Gaussian-lobe shader in a real browser (Chromium + SwiftShader WebGL2) against the CPU evaluation on
the same float16 data.

The page imports ``web/src/gaussian.js`` (the viewer's module), which assembles ``web/shaders/gaussian*.glsl`` with
``shaders.js``, uploads the lobe textures and the chain's levels as RGBA16F from the float16 bit patterns given
here, renders the unit sphere into an RGBA32F target (linear radiance) and reads it back. The reference is
``relight.sg_render.render_sphere_gaussian`` of the same rounded material and chain
(``relight.gl.gaussian.half_material`` / ``half_chain``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from relight import resources
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.models import TorranceSparrow
from relight.envmap import read_envmap, resample_latlong
from relight.gaussian_chain import build_chain
from relight.gl.gaussian import LobeTable, half_chain, half_material
from relight.sg_render import render_sphere_gaussian
from relight.sgfit import FitSettings, fit_gaussian_lobes

pytestmark = [pytest.mark.timeout(600)]

SIZE = 48
VIEW = (0.3, 0.4, 1.0)
#: Per pixel, relative to its largest channel. The GPU (SwiftShader, float32) reads the same float16 texels; what
#: differs is float32 arithmetic and the sampler's sub-texel weights. moderngl on llvmpipe measured 8.7e-4
#: (tests/relight/test_gl_gaussian.py); SwiftShader measured 2.9e-4 here (median 2.4e-5).
REL_TOL = 2e-3


def _bits(a: np.ndarray) -> list[int]:
    return [int(x) for x in np.ascontiguousarray(a, dtype=np.float16).view(np.uint16).ravel()]


@pytest.mark.parametrize("uneven", [False, True], ids=["grid", "bisection"])
def test_gaussian_sphere_matches_the_cpu(page: Any, uneven: bool) -> None:
    """Both of the shader's ways to its lobe-table rows: the fit's elevations lie on an even grid (one multiply);
    the same lobes at elevations on no grid are bisected (``LobeTable``)."""
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "sunset.exr"))
    px = np.asarray(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 32), dtype=np.float64)
    fit = fit_gaussian_lobes(TorranceSparrow(0.2, fresnel="none"), FitSettings(elevations=5))
    if uneven:
        at = np.array([0.0, 0.1234567, 0.5, 0.61, 0.9, 1.3, 1.5])
        fit = GaussianLobes(at, *fit.params_at(at))
    assert (LobeTable(fit).grid is None) == uneven
    mat = half_material(fit)
    chain = half_chain(build_chain(px, sigma0=math.pi / 64, ratio=math.sqrt(2), epsilon=1e-4, uniform_size=True))
    k, n = mat.n_lobes, mat.elevations.size
    shape = np.zeros((n, k, 4))
    shape[..., 0], shape[..., 1] = mat.mu, mat.sigma
    weight = np.zeros((n, k, 4))
    weight[..., :3] = mat.weight
    h, w = chain.levels[0].map.shape[:2]
    levels = []
    for lv in chain.levels:
        rgba = np.zeros((h, w, 4))
        rgba[..., :3] = lv.map
        levels.append(_bits(rgba))
    args = {"material": {"lobes": k, "elevations": [float(x) for x in mat.elevations], "shape": _bits(shape),
                         "weight": _bits(weight)},
            "chain": {"sigma0": float(chain.levels[0].sigma), "ratio": float(chain.levels[1].sigma
                                                                             / chain.levels[0].sigma),
                      "height": h, "width": w, "levels": levels},
            "view": list(VIEW), "size": SIZE}
    out = page.evaluate("""async (a) => {
        const m = await import('/src/gaussian.js');
        const gl = document.createElement('canvas').getContext('webgl2');
        const material = {...a.material, shape: new Uint16Array(a.material.shape),
                          weight: new Uint16Array(a.material.weight)};
        const chain = {...a.chain, levels: a.chain.levels.map((l) => new Uint16Array(l))};
        const px = await m.renderSphere(gl, material, chain, a.view, a.size, '/shaders/');
        return Array.from(px);
    }""", args)
    gl_img = np.asarray(out, dtype=np.float64).reshape(SIZE, SIZE, 4)[::-1, :, :3]
    cpu = render_sphere_gaussian(mat, chain, np.asarray(VIEW), SIZE)
    on_gl, on_cpu = np.any(gl_img > 0, axis=2), np.any(cpu > 0, axis=2)
    assert np.array_equal(on_gl, on_cpu), int((on_gl ^ on_cpu).sum())
    rel = np.abs(gl_img - cpu)[on_cpu].max(axis=1) / cpu[on_cpu].max(axis=1)
    print(f"browser vs CPU: {on_cpu.sum()} pixels, relative difference max {rel.max():.2e}, median "
          f"{np.median(rel):.2e}")
    assert float(rel.max()) < REL_TOL
