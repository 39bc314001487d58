"""relight.gl.prt (and web/shaders/prt.vert.glsl) against the CPU: the clamped cosine's zonal factors, the lighting
rotation about +Y against a rotated map, every vertex's radiance in the three modes, and whole images against
``relight.mesh_render`` (ray-cast primary hits, barycentric interpolation of the same float16 vertex data)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from relight import resources
from relight.envmap import read_envmap, resample_latlong
from relight.gl import render as gl_render
from relight.gl.prt import PrtRenderer, cosine_zonal, rotate_lighting_y
from relight.mesh import sample_mesh
from relight.mesh_render import interpolate, lighting_coefficients, surface_samples, unshadowed_transfer
from relight.sh_render import rotate_lighting
from relight.visibility import TransferSettings, compute_transfer, sh_basis

ORDER = 3


@pytest.fixture(scope="module")
def ctx() -> Iterator[Any]:
    c = gl_render.create_context()  # EGL on Mesa: `make test` installs it (an error here is a failure)
    yield c
    c.release()


@pytest.fixture(scope="module")
def lighting() -> np.ndarray:
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "courtyard.exr"))
    return lighting_coefficients(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 32), ORDER)


@pytest.fixture(scope="module")
def bunny() -> tuple[Any, dict[str, np.ndarray]]:
    mesh = sample_mesh("bunny")
    res = compute_transfer(mesh, TransferSettings(order=ORDER, rays=256, kind="diffuse_transfer"))
    return mesh, res.arrays


def test_cosine_zonal_is_the_unshadowed_transfer() -> None:
    """Closed form against mesh_render's exact polynomial integration, to order 8."""
    n = np.random.default_rng(1).standard_normal((50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    l_of = np.repeat(np.arange(9), 2 * np.arange(9) + 1)
    np.testing.assert_allclose(sh_basis(n, 8) * cosine_zonal(8)[l_of], unshadowed_transfer(n, 8), atol=1e-14)
    assert cosine_zonal(4).tolist() == pytest.approx([1.0, 2 / 3, 1 / 4, 0.0, -1 / 24])


def test_rotating_the_lighting_is_rotating_the_map() -> None:
    """A lat-long map rolled by k columns is the map turned by 2 pi k / W about +Y (exactly): its projection equals
    the rotated coefficients, and relight.sh_render's general rotation (P R P from a 3 x 3 matrix) agrees."""
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "city.exr"))
    px = resample_latlong(np.asarray(env.pixels, dtype=np.float64), 32)
    k = 11
    angle = 2.0 * np.pi * k / px.shape[1]
    rolled = np.roll(px, -k, axis=1)  # the viewer looks the map up at rotate_y(d, -a): azimuth + a
    want = lighting_coefficients(rolled, 6)
    got = rotate_lighting_y(lighting_coefficients(px, 6), angle)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())
    c, s = np.cos(angle), np.sin(angle)
    ry = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # rotate_y(d, a) of web/shaders/common.glsl
    np.testing.assert_allclose(rotate_lighting(lighting_coefficients(px, 6), ry), want, atol=1e-9 * np.abs(want).max())


def test_every_vertex_in_every_mode(ctx: Any, lighting: np.ndarray, bunny: tuple[Any, dict[str, np.ndarray]]) -> None:
    """The vertex shader's radiance per vertex against NumPy on the same float16 data (float32 arithmetic over 16
    terms: 1e-5 of the largest value)."""
    mesh, arrays = bunny
    r = PrtRenderer(mesh, transfer=arrays["transfer"], ao=arrays["ao"], order=ORDER, ctx=ctx)
    t16 = arrays["transfer"].astype(np.float16).astype(np.float64)
    ao16 = arrays["ao"].astype(np.float16).astype(np.float64)
    normals32 = mesh.normals.astype(np.float32).astype(np.float64)
    unshadowed = unshadowed_transfer(normals32, ORDER) @ lighting[:16]
    want = {"transfer": 0.8 * t16 @ lighting[:16], "unshadowed": 0.8 * unshadowed,
            "ao": 0.8 * ao16[:, None] * unshadowed}
    for mode, w in want.items():
        got = r.probe(mode, lighting, albedo=0.8)  # type: ignore[arg-type]
        np.testing.assert_allclose(got, w, rtol=0, atol=1e-5 * np.abs(w).max(), err_msg=mode)
    # shadows darken: transfer below the unshadowed irradiance on average, AO in (0, 1] up to its Monte Carlo
    # error (the stratified estimate of an unoccluded vertex's 1 is off by ~1e-3 at 256 rays) and float16 rounding
    assert np.mean(want["transfer"]) < np.mean(want["unshadowed"]) and 0 < ao16.min() and ao16.max() <= 1.005
    r.release()


def test_images_match_the_cpu_renderer(ctx: Any, lighting: np.ndarray,
                                       bunny: tuple[Any, dict[str, np.ndarray]]) -> None:
    """The rasterised, Gouraud-shaded image against ``mesh_render`` (one primary ray per pixel centre, barycentric
    interpolation of the same per-vertex radiance), with the environment turned by 1 rad. Pixels whose centre the
    rasteriser and the ray caster classify differently (on an edge, within float32 rounding) may differ: at most
    0.5 % of the mesh's pixels (measured: none); the rest agree to 2e-4 of the image maximum (float32
    interpolation; measured 1.5e-5)."""
    mesh, arrays = bunny
    rotated = rotate_lighting_y(lighting, 1.0)
    r = PrtRenderer(mesh, transfer=arrays["transfer"], order=ORDER, ctx=ctx)
    view, size = np.array([0.3, 0.4, 1.0]), 96
    img = r.draw("transfer", view, rotated, size)
    samples = surface_samples(mesh.normalised(), view, size, supersample=1)
    per_vertex = arrays["transfer"].astype(np.float16).astype(np.float64) @ rotated[:16]
    want = samples.image(interpolate(samples, mesh, per_vertex))
    covered = samples.coverage == 1.0
    assert covered.sum() > 0.2 * size * size
    bad = np.abs(img - want).max(axis=2) > 2e-4 * want.max()
    assert bad[covered].mean() < 0.005, bad[covered].mean()
    assert np.any(img[samples.coverage == 0.0] != 0.0, axis=-1).mean() < 0.005  # background stays 0
    # the unshadowed image (no per-vertex data needed) is brighter: the bunny shadows itself
    assert r.draw("unshadowed", view, rotated, size)[covered].mean() > img[covered].mean()
    r.release()
