"""The Gaussian-lobe GLSL (web/shaders/gaussian*.glsl through relight.gl.gaussian, moderngl on Mesa) against the CPU
evaluation (relight.sg_render, relight.sg_shadow) of the same float16 data: sphere and bunny, every visibility mode."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import cache
from typing import Any

import numpy as np
import pytest

from relight import resources
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.brdf.models import TorranceSparrow
from relight.envmap import read_envmap, resample_latlong
from relight.errors import InputError
from relight.gaussian_chain import GaussianChain, build_chain
from relight.gl.gaussian import MAX_GRID_ROWS, GaussianRenderer, LobeTable, half_chain, half_material, lobe_grid
from relight.gl.render import create_context
from relight.mesh import sample_mesh
from relight.mesh.model import TriangleMesh
from relight.sg_render import render_mesh_gaussian, render_sphere_gaussian
from relight.sgfit import FitSettings, fit_gaussian_lobes
from relight.visibility import TransferSettings, compute_transfer

VIEW = np.array([0.3, 0.4, 1.0])
SIZE = 64
#: Largest difference per pixel relative to the pixel's largest channel: both sides read the same float16 texels;
#: the GPU computes in float32 (llvmpipe's bilinear weights, acos, log of the level) where the CPU uses float64.
#: Measured 8.7e-4 (sphere) and 8.0e-4 (bunny, every mode); the median 5e-5.
REL_TOL = 2e-3


@cache
def data() -> tuple[GaussianLobes, GaussianChain, TriangleMesh, np.ndarray]:
    env = read_envmap(resources.package_dir(resources.DATA, "envmaps", "sunset.exr"))
    px = np.asarray(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 64), dtype=np.float64)
    fit = fit_gaussian_lobes(TorranceSparrow(0.2, fresnel="none"), FitSettings(elevations=6))
    chain = build_chain(px, sigma0=math.pi / 128, ratio=math.sqrt(2), epsilon=1e-4, uniform_size=True)
    mesh = sample_mesh("bunny").normalised()
    vis = compute_transfer(mesh, TransferSettings(order=3, rays=256)).arrays["visibility"]
    # the vertex attributes are float32: the CPU reads the same values
    return half_material(fit), half_chain(chain), mesh, np.asarray(vis, dtype=np.float32).astype(np.float64)


@pytest.fixture(scope="module")
def renderer() -> Iterator[GaussianRenderer]:
    ctx = create_context()  # EGL on Mesa: `make test` installs it (an error here is a failure)
    mat, chain, _, _ = data()
    r = GaussianRenderer(mat, chain, ctx=ctx)
    yield r
    r.release()
    ctx.release()


def _compare(gl: np.ndarray, cpu: np.ndarray) -> float:
    on_gl, on_cpu = np.any(gl > 0, axis=2), np.any(cpu > 0, axis=2)
    # the same pixels are covered: the sphere's test and the rasteriser's coverage match the CPU's ray casts
    assert np.array_equal(on_gl, on_cpu), int((on_gl ^ on_cpu).sum())
    d = np.abs(gl - cpu)[on_cpu].max(axis=1) / cpu[on_cpu].max(axis=1)
    return float(d.max())


def test_sphere_matches_the_cpu(renderer: GaussianRenderer) -> None:
    mat, chain, _, _ = data()
    for view in (VIEW, np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])):
        err = _compare(renderer.render(view, SIZE), render_sphere_gaussian(mat, chain, view, SIZE))
        assert err < REL_TOL, (view, err)


@pytest.mark.parametrize("mode", ["none", "ao", "sh", "sh-lobe"])
def test_bunny_matches_the_cpu(renderer: GaussianRenderer, mode: str) -> None:
    mat, chain, mesh, vis = data()
    bufs = renderer.mesh_buffers(mesh, vis)
    gl = renderer.render(VIEW, SIZE, mesh=bufs, mode=mode)
    cpu, report = render_mesh_gaussian(mat, chain, mesh, VIEW, SIZE, supersample=1, visibility=vis, mode=mode)
    assert _compare(gl, cpu) < REL_TOL
    if mode != "none":  # the visibility really darkens the image (the comparison would pass without it otherwise)
        plain = renderer.render(VIEW, SIZE, mesh=bufs)
        assert float(np.sum(gl)) < 0.97 * float(np.sum(plain)), (mode, float(np.sum(gl)) / float(np.sum(plain)))


@pytest.mark.parametrize(("mode", "order"), [("sh", 1), ("sh-lobe", 2)])
def test_bunny_truncated_visibility_matches_the_cpu(renderer: GaussianRenderer, mode: str, order: int) -> None:
    """The viewer's 4 and 9 coefficients: the shader's per-order branches against the CPU's truncation."""
    mat, chain, mesh, vis = data()
    bufs = renderer.mesh_buffers(mesh, vis)
    gl = renderer.render(VIEW, SIZE, mesh=bufs, mode=mode, order=order)
    cpu, _ = render_mesh_gaussian(mat, chain, mesh, VIEW, SIZE, supersample=1, visibility=vis, mode=mode,
                                  order=order)
    assert _compare(gl, cpu) < REL_TOL
    # the truncation is seen: order 3 gives another image (the comparison above could not tell otherwise)
    full = renderer.render(VIEW, SIZE, mesh=bufs, mode=mode, order=3)
    assert _compare(full, cpu) > 10 * REL_TOL, _compare(full, cpu)


def test_plain_lookup_and_errors(renderer: GaussianRenderer) -> None:
    from relight.conventions import sample_latlong
    from relight.shrm import sphere_geometry

    _, chain, mesh, _ = data()
    img = renderer.render(VIEW, 32, plain=True)
    v = VIEW / np.linalg.norm(VIEW)
    n, mask = sphere_geometry(v, 32)
    nv = np.clip(n[mask] @ v, 0.0, 1.0)
    r = 2.0 * nv[:, None] * n[mask] - v
    want = sample_latlong(np.asarray(chain.levels[0].map, dtype=np.float64)[None], r)[:, 0]
    # the sharpest level rings (values near 0 and below, clamped by neither side): absolute to the image's peak
    np.testing.assert_allclose(img[mask], want, rtol=REL_TOL, atol=REL_TOL * float(np.abs(want).max()))
    with pytest.raises(InputError, match="mesh"):
        renderer.render(VIEW, 8, mode="sh")
    with pytest.raises(InputError, match="visibility mode"):
        renderer.render(VIEW, 8, mesh=renderer.mesh_buffers(mesh), mode="exact")
    uneven: Any = GaussianChain(chain.sigma0, chain.ratio, [chain.levels[0], chain.levels[1]])
    uneven.levels[1] = type(chain.levels[1])(sigma=chain.levels[1].sigma, map=chain.levels[1].map[::2, ::2],
                                             orders={})
    with pytest.raises(InputError, match="one size"):
        GaussianRenderer(data()[0], uneven, ctx=renderer.ctx)


def _uneven_material() -> GaussianLobes:
    """The test material's parameters at elevations on no even grid (:func:`lobe_grid` finds none within
    MAX_GRID_ROWS): the shader bisects them."""
    fit = data()[0]
    at = np.array([0.0, 0.1234567, 0.5, 0.61, 0.9, 1.3, 1.5])
    mu, sigma, weight = fit.params_at(at)
    return GaussianLobes(at, mu, sigma, weight)


def test_lobe_grid_finds_the_coarsest_even_grid() -> None:
    # relight fit's elevations: 15 even ones, an interval bisected twice
    step = math.radians(87.0) / 14
    fit_like = np.sort(np.r_[step * np.arange(15), step * 6.5, step * 6.25])
    theta0, grid_step, rows = lobe_grid(fit_like)  # type: ignore[misc]
    assert (theta0, rows) == (0.0, 57) and math.isclose(grid_step, step / 4)
    assert lobe_grid(np.array([0.0, 0.3, 0.55, 1.2]))[2] == 25  # type: ignore[index]  # gap 0.25 / 5
    assert lobe_grid(np.array([0.0, 0.5, 0.75, 1.5]))[2] == 7  # type: ignore[index]  # gap 0.25
    assert lobe_grid(np.array([0.2])) is None
    assert lobe_grid(np.array([0.0, 1e-4, 1.0])) is None  # 10 001 rows > MAX_GRID_ROWS
    assert lobe_grid(_uneven_material().elevations) is None
    # float32 elevations of a float64 grid are on it (GRID_TOLERANCE)
    assert lobe_grid(fit_like.astype(np.float32).astype(np.float64))[2] == 57  # type: ignore[index]
    assert MAX_GRID_ROWS >= 4 * 14 * 16 + 1  # relight fit at most bisects 4 levels deep (sgfit_refine.MAX_DEPTH)


@pytest.mark.parametrize("uneven", [False, True])
def test_lobe_table_keeps_the_materials_parameters(uneven: bool) -> None:
    """The table's rows interpolate to the material's piecewise-linear parameters: bit for bit at the material's
    elevations, and between them within the float16 rounding of the inserted rows (half an ulp, 2^-11 relative,
    of a value no larger than its neighbours); the words hold those float16 values; the table is idempotent."""
    fit = _uneven_material() if uneven else fit_gaussian_lobes(TorranceSparrow(0.2, fresnel="none"),
                                                                FitSettings(elevations=15, max_lobes=3))
    table = LobeTable(fit)
    rounded = GaussianLobes(fit.elevations.astype(np.float32).astype(np.float64), *(
        np.asarray(x).astype(np.float16).astype(np.float64) for x in (fit.mu, fit.sigma, fit.weight)))
    if uneven:
        assert table.grid is None and table.rows == fit.elevations.size
        assert table.defines()["GAUSSIAN_SEARCH_STEP"] == 4
    else:
        assert fit.elevations.size > 15  # the fit inserted elevations: uneven, yet on a grid
        assert table.grid is not None and table.rows > fit.elevations.size and "GAUSSIAN_GRID" in table.defines()
    theta = np.linspace(-0.1, 1.6, 4001)
    for got, want in zip(table.material.params_at(theta), rounded.params_at(theta), strict=True):
        scale = np.max(np.abs(want), axis=0, keepdims=True)
        assert np.all(np.abs(got - want) <= 2.0**-11 * scale + 1e-12)
    # the rows at the material's elevations hold its values
    rows = np.arange(table.rows) if table.grid is None else np.rint(
        (rounded.elevations - table.grid[0]) * table.grid[1]).astype(int)
    assert np.all(np.abs(table.material.elevations[rows] - rounded.elevations) < 1e-6)
    for got, want in zip((table.material.mu, table.material.sigma, table.material.weight),
                         (rounded.mu, rounded.sigma, rounded.weight), strict=True):
        np.testing.assert_array_equal(got[rows], want)
    halves = table.words().view(np.float16).reshape(table.rows, -1).astype(np.float64)
    k = fit.n_lobes
    per_lobe = halves[:, : 4 * k].reshape(table.rows, k, 4)
    np.testing.assert_array_equal(per_lobe[..., 0], table.material.mu)
    np.testing.assert_array_equal(per_lobe[..., 1], table.material.sigma)
    np.testing.assert_array_equal(per_lobe[..., 2:], table.material.weight[..., :2])
    np.testing.assert_array_equal(halves[:, 4 * k : 5 * k], table.material.weight[..., 2])
    assert not np.any(halves[:, 5 * k :])
    again = LobeTable(table.material)
    assert again.rows == table.rows and again.grid == table.grid
    np.testing.assert_array_equal(again.words(), table.words())
    held = half_material(fit)
    for got, want in zip((held.elevations, held.mu, held.sigma, held.weight),
                         (table.material.elevations, table.material.mu, table.material.sigma, table.material.weight),
                         strict=True):
        np.testing.assert_array_equal(got, want)


def test_sphere_on_unevenly_spaced_elevations_matches_the_cpu(renderer: GaussianRenderer) -> None:
    """The shader's other interval path (a branchless bisection over u_elevations) against the CPU."""
    _, chain, _, _ = data()
    mat = half_material(_uneven_material())
    r = GaussianRenderer(mat, chain, ctx=renderer.ctx)
    try:
        assert "GAUSSIAN_SEARCH_STEP" in r.defines("sphere")
        for view in (VIEW, np.array([0.0, 0.0, 1.0])):
            err = _compare(r.render(view, SIZE), render_sphere_gaussian(mat, chain, view, SIZE))
            assert err < REL_TOL, (view, err)
    finally:
        r.release()
