"""Glossy shadows of seed 002 (eq. 7; relight.sg_shadow, relight.sg_render.render_mesh_gaussian): the lobe-weighted
visibility against quadrature, and the shadowed bunny against Mitsuba 3's path tracer (direct light only)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from relight import resources
from relight.brdf.models import TorranceSparrow
from relight.brdf.vmf import sigma_to_kappa, vmf, vmf_transfer
from relight.conventions import latlong_dirs, luminance, pixel_solid_angles
from relight.envmap import read_envmap, resample_latlong
from relight.errors import InputError
from relight.gaussian_chain import build_chain
from relight.mesh import sample_mesh
from relight.mesh_render import surface_samples
from relight.mitsuba_compare import block_mean, block_rms
from relight.mitsuba_mesh import render_mesh_mitsuba
from relight.mitsuba_twin import twin
from relight.raycast import RayCaster
from relight.sg_render import render_mesh_gaussian
from relight.sg_shadow import lobe_visibility, vmf_band_factors
from relight.sgfit import FitSettings, fit_gaussian_lobes
from relight.shrm import Y00
from relight.visibility import TransferSettings, compute_transfer, sh_basis

TS = TorranceSparrow(0.2, fresnel="none")


def test_band_factors_match_the_scalar_transfer() -> None:
    sig = np.array([1e-4, 0.01, 0.2, 1.0, 1.5])
    got = vmf_band_factors(sig, 6)
    want = np.stack([vmf_transfer(float(sigma_to_kappa(s)), 6) for s in sig])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-300)


def test_lobe_weighted_visibility_is_the_convolution() -> None:
    """``sum a_l v_lm Yr_lm(c)`` against the quadrature ``int G(c.w) V_F(w) dw`` of the order-3 SH function."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(4, 16))
    c = rng.normal(size=(4, 2, 3))
    c /= np.linalg.norm(c, axis=-1, keepdims=True)
    sigma = np.array([[0.15, 0.4]] * 4)
    vis, raw = lobe_visibility(v, c, sigma, "sh-lobe")
    h = 400
    d = latlong_dirs(h, 2 * h).reshape(-1, 3)
    dw = pixel_solid_angles(h, 2 * h).repeat(2 * h)
    vf = sh_basis(d, 3) @ v.T  # (M, 4) the truncated visibility functions
    for p in range(4):
        for k in range(2):
            g = vmf(d @ c[p, k], sigma_to_kappa(sigma[p, k]))
            # the midpoint rule on 400 x 800 pixels (0.45 degrees) resolves a lobe of 8.6 degrees to ~1e-5
            assert raw[p, k] == pytest.approx(float(np.sum(g * vf[:, p] * dw)), rel=2e-4, abs=2e-5)
    assert np.all((vis >= 0.0) & (vis <= 1.0))
    np.testing.assert_array_equal(vis, np.clip(raw, 0.0, 1.0))


def test_modes_on_a_constant_visibility() -> None:
    """V = 1 over the upper hemisphere's worth (v_0 = 2 pi Y00: half the sphere visible): AO = 1; a full sphere
    (v_0 = 4 pi Y00) reads 2 before clamping; point and lobe modes give V_0 = v_0 Y00 everywhere."""
    c = np.tile(np.array([0.0, 0.0, 1.0]), (2, 3, 1))
    v = np.zeros((2, 16))
    v[0, 0], v[1, 0] = 2 * math.pi * Y00, 4 * math.pi * Y00
    ao, ao_raw = lobe_visibility(v, c, np.full((2, 3), 0.2), "ao")
    np.testing.assert_allclose(ao_raw[:, 0], [1.0, 2.0], rtol=1e-12)
    np.testing.assert_allclose(ao, 1.0)
    for mode in ("sh", "sh-lobe"):
        _, raw = lobe_visibility(v, c, np.full((2, 3), 0.2), mode)
        np.testing.assert_allclose(raw, [[0.5] * 3, [1.0] * 3], rtol=1e-12)
    with pytest.raises(InputError, match="mode"):
        lobe_visibility(v, c, np.ones((2, 3)), "spherical")
    with pytest.raises(InputError, match=r"\(F\+1\)\^2"):
        lobe_visibility(v[:, :5], c, np.ones((2, 3)), "sh")


@cache
def bunny_images() -> tuple[dict[str, np.ndarray], np.ndarray, float, dict[str, dict[str, float]]]:
    size, spp = 48, 256
    view = np.array([0.3, 0.4, 1.0])
    mesh = sample_mesh("bunny").normalised()
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "sunset.exr"))
    px = np.asarray(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 64), dtype=np.float64)
    fit = fit_gaussian_lobes(TS, FitSettings(elevations=8, max_lobes=3))
    chain = build_chain(px, sigma0=math.pi / 128, ratio=math.sqrt(2), epsilon=1e-4)
    mitsuba = render_mesh_mitsuba(mesh, px, view=view, size=size, spp=spp, bsdf=twin(TS))
    vis = compute_transfer(mesh, TransferSettings(order=3, rays=1024)).arrays["visibility"].astype(np.float64)
    caster = RayCaster(mesh.positions, mesh.faces)
    images, reports = {}, {}
    for name, mode, order in [("none", "none", None), ("ao", "ao", None), ("sh16", "sh", 3),
                              ("lobe16", "sh-lobe", 3)]:
        images[name], reports[name] = render_mesh_gaussian(fit, chain, mesh, view, size, visibility=vis, mode=mode,
                                                           order=order, caster=caster)
    full = block_mean(surface_samples(mesh, view, size, 2, caster).coverage, 2) == 1.0
    truth, sigma = mitsuba.blocks(2)
    noise = float(np.sqrt(np.sum(sigma[full] ** 2) / np.sum(truth[full] ** 2)))
    blocks = {k: block_mean(luminance(img), 2)[full] for k, img in images.items()}
    return blocks, truth[full], noise, reports


def test_shadowed_bunny_against_mitsuba() -> None:
    """The issue's ordering on the 2 x 2 blocks where Mitsuba's shadows change the image by more than 10 % (Mitsuba
    against the unshadowed Gaussian render, whose own error is the fit's, a few %): sunset.exr's low sun makes
    large shadows of the glossy reflection (bunny 1839 vertices, TS Beckmann alpha 0.2, K = 3, order-3 visibility,
    Mitsuba 256 spp)."""
    blocks, truth, noise, reports = bunny_images()
    shadowed = np.abs(truth - blocks["none"]) > 0.1 * blocks["none"]
    on = {k: block_rms(b[shadowed], truth[shadowed]) for k, b in blocks.items()}
    overall = {k: block_rms(b, truth) for k, b in blocks.items()}
    print(f"shadowed blocks {shadowed.sum()} of {truth.size}, noise {noise:.4f}; on them {on}; all blocks {overall}; "
          f"unclamped visibility {[(k, r.unclamped_min, r.unclamped_max) for k, r in reports.items()]}")
    assert shadowed.sum() >= 10 and noise < 0.05  # enough blocks, and noise that leaves room to fail
    # measured on the shadowed blocks (Mitsuba seeds 0 / 1): unshadowed 0.333 / 0.280, AO 0.197 / 0.165, SH16
    # 0.056 / 0.086, lobe-weighted 0.047 / 0.077 -- margins of 1.7x or more between neighbours, against a noise of
    # 0.023. (city.exr's small sun: the same order within Mitsuba's noise, 0.21 / 0.10 / 0.09; studio.exr's area
    # lights: no block where shadows beat the noise.)
    assert on["sh16"] < on["ao"] < on["none"], on
    assert on["lobe16"] < on["ao"], on
    # the point value darkens unshadowed glossy reflections where the truncated visibility dips below 1 near the
    # horizon; the lobe-weighted one less (all blocks: measured 0.097 vs 0.063; unshadowed 0.049, AO 0.088)
    assert overall["lobe16"] < overall["sh16"], overall
    # the order-3 truncation rings: the unclamped values leave [0, 1] (reported; the clamp keeps V in range)
    hi, lo = reports["sh16"].unclamped_max, reports["sh16"].unclamped_min
    assert hi is not None and lo is not None and hi > 1.0 and lo < 0.05
