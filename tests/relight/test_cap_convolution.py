"""The near sum of a lobe that vanishes beyond a cap (relight.cap_convolution.angular_convolution) against the
dense reference (brute_force: the whole sphere on a finer grid, not normalised), the reference's own accuracy,
the limit of a lobe narrower than a pixel, the windowed near and far parts against the lobe itself, and the grid
path (the same sum on a half-pixel grid, interpolated) against the direct sum."""

from __future__ import annotations

import numpy as np
import pytest
from sky_refs import sun_sky
from test_cube_chain import city, octant_map, rel_rms

from relight.brdf.radial import Phong
from relight.brdf.splitsum import GGXSplitSum
from relight.cap_convolution import (
    GRID_K,
    GRID_MIN_HALF_WIDTH,
    GRID_MIN_RATIO,
    WindowedLobe,
    angular_convolution,
    brute_force,
    cap_mass,
    cell_means,
    grid_pays,
    half_width,
)
from relight.conventions import latlong_dirs, pixel_solid_angles, sample_latlong
from relight.envmap import cube_face_dirs


def directions() -> np.ndarray:
    # cube texel centres, the exact poles and the seam at phi = +-pi
    dirs = np.concatenate([cube_face_dirs(4).reshape(-1, 3),
                           [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 1e-9], [-1.0, 0.3, -1e-9]]])
    return np.asarray(dirs / np.linalg.norm(dirs, axis=1, keepdims=True))


@pytest.mark.parametrize(("roughness", "theta1_pixels"), [(0.15, 3.0), (0.15, 12.0), (0.15, 40.0), (0.08, 4.0),
                                                          (0.4, 8.0)])
def test_near_sum_equals_the_dense_reference(roughness: float, theta1_pixels: float) -> None:
    # Lobes from a twelfth of a pixel (r = 0.08: half width 0.008 rad, pixels 0.098 rad) to a few pixels, caps from
    # 3 pixels to one covering a pole (40 px of 32 rows). The near sum's midpoint rule samples the lobe's scale at
    # least twice per sub-cell; the test bounds its error at 1 % and 1e-3 of the largest value (sun 1e4 x sky).
    px = sun_sky(32)
    h = px.shape[0]
    theta1 = theta1_pixels * np.pi / h
    lobe = WindowedLobe(GGXSplitSum(roughness), 0.5 * theta1, theta1, near=True)
    dirs = directions()[:: 4 if roughness < 0.1 else 1]  # the reference's cost grows as 1 / half width^2
    ref = brute_force(px, lobe, dirs)
    got = angular_convolution(px, lobe, dirs, theta1)
    # r = 0.08 is narrower than the finest sub-cells (pixel / 8): the mass they sample sits up to a sixteenth of a
    # pixel off the lobe's, which beside the sun (1e4 over one pixel) moves a texel by up to ~ 2 %
    rtol = 2e-2 if roughness < 0.1 else 1e-2
    np.testing.assert_allclose(got, ref, rtol=rtol, atol=1e-3 * np.abs(ref).max())
    # the reference is not normalised: its weights on a constant map are its quadrature of the lobe's mass.
    # Away from the poles a 2-D Gauss rule with 3 nodes per half width (4th order: below the 5e-4 a midpoint rule
    # at that spacing gave); on a pole the rings make it a 1-D rule in theta, held to the midpoint's ~ (1/3)^2 / 24
    # |hw^2 u''/u| ~ 5e-3 of the mass.
    ones = brute_force(np.ones_like(px), lobe, dirs)
    np.testing.assert_allclose(ones[:-4], cap_mass(lobe, theta1), rtol=5e-4)
    np.testing.assert_allclose(ones[-4:], cap_mass(lobe, theta1), rtol=5e-3)


def test_reference_sees_an_unnormalised_pixel_sum() -> None:
    # The defect this reference exists for: the plain pixel-centre sum of a lobe narrower than a pixel weights
    # the nearest pixel by the peak times a whole pixel's solid angle. On a constant map the reference gives the
    # lobe's mass (1) and the pixel-centre sum (the old reference) does not.
    px = np.ones((32, 64, 3))
    lobe = GGXSplitSum(0.08)
    dirs = cube_face_dirs(2).reshape(-1, 3)
    assert np.abs(brute_force(px, lobe, dirs) - 1.0).max() < 1e-3
    centres = latlong_dirs(32, 64).reshape(-1, 3)
    pixel_sum = lobe.u(dirs @ centres.T)[..., 0] @ np.repeat(pixel_solid_angles(32, 64), 64)
    assert np.abs(pixel_sum - 1.0).max() > 0.5


def test_a_lobe_narrower_than_a_pixel_tends_to_the_bilinear_value() -> None:
    # r = 0.002: half width 4e-6 rad against 0.1 rad pixels. The near sum is then a unit-mass average of the
    # interpolant within ~ a sub-cell (pixel / 16) of d: the bilinear value up to that displacement times its
    # gradient (a map whose neighbours differ by at most 1: |error| < 1 / 16).
    rng = np.random.default_rng(3)
    px = rng.uniform(0.0, 1.0, size=(32, 64, 3))
    theta1 = 4 * np.pi / 32
    lobe = WindowedLobe(GGXSplitSum(0.002), 0.5 * theta1, theta1, near=True)
    dirs = directions()
    got = angular_convolution(px, lobe, dirs, theta1) / cap_mass(lobe, theta1)
    want = sample_latlong(px[None], dirs)[:, 0]
    assert np.abs(got - want).max() < 1.0 / 16
    assert got.min() >= px.min() and got.max() <= px.max()


def test_cell_means_are_the_interpolants_cell_averages() -> None:
    # against the average of the bilinear interpolant over each cell on a 16 x 16 sub-grid (solid-angle weighted)
    rng = np.random.default_rng(4)
    px = rng.uniform(0.0, 1.0, size=(8, 16, 3))
    m = 16
    fine = latlong_dirs(8 * m, 16 * m)
    vals = sample_latlong(px[None], fine.reshape(-1, 3))[:, 0].reshape(8, m, 16, m, 3)
    sa = np.sin((np.arange(8 * m) + 0.5) * np.pi / (8 * m)).reshape(8, m, 1, 1, 1)
    want = (vals * sa).sum(axis=(1, 3)) / (sa.sum(axis=1)[:, 0, 0] * m)[:, None]
    np.testing.assert_allclose(cell_means(px), want, atol=2e-3)


def test_near_and_far_parts_sum_to_the_lobe() -> None:
    lobe = GGXSplitSum(0.1)
    t = np.cos(np.linspace(0.0, np.pi, 2001))
    near = WindowedLobe(lobe, 0.02, 0.04, near=True).u(t)
    far = WindowedLobe(lobe, 0.02, 0.04, near=False).u(t)
    np.testing.assert_allclose(near + far, lobe.u(t), rtol=1e-13, atol=0.0)
    assert np.all(near[np.arccos(t) > 0.04] == 0.0)


def test_near_sum_converges_as_the_cells_are_refined() -> None:
    # Phong s = 64's near part as the chain splits it on a 32-row map (window pi/4..pi/2, half width 1.5 pixels):
    # the sun (1e4 over about one pixel) sits on the window's ramp for some texels, where one-sample cells were
    # 10 % off. The near sum is a midpoint rule in the cell size h / sub (second order: doubling sub should cut
    # the error ~4x); each doubling must at least halve the error against the reference, whatever the seam
    # between one-sample and sub-divided cells. The reference (2 x 2 Gauss per fine cell, 4th order) is itself
    # checked converged: at m and 2 m fine cells per pixel it moves less than 1e-4, 4x below the finest error
    # asserted here (measured: 0.70 %, 0.14 %, 0.043 % at sub = 2, 4, 8).
    px = sun_sky(32)
    theta1 = np.pi / 2
    lobe = WindowedLobe(Phong(64.0), 0.5 * theta1, theta1, near=True)
    dirs = cube_face_dirs(4).reshape(-1, 3)
    ref = brute_force(px, lobe, dirs, oversample=4)
    assert rel_rms(brute_force(px, lobe, dirs, oversample=2), ref) < 1e-4
    errs = [rel_rms(angular_convolution(px, lobe, dirs, theta1, sub_per_scale=sub), ref) for sub in (2, 4, 8)]
    assert all(b <= 0.5 * a for a, b in zip(errs, errs[1:], strict=False)), errs
    assert errs[-1] < 1e-3, errs
    # the chain's default refinement holds the near part well inside the 1 % a chain level is held to
    assert rel_rms(angular_convolution(px, lobe, dirs, theta1), ref) < 2.5e-3


#: Near parts the grid path takes (grid_pays): half widths of 2.1 to 4.2 pixels, windows 4 px wide and more.
GRID_CASES = [("sun-sky", lambda: sun_sky(32), 0.4, 8.0), ("octant", lambda: octant_map(32), 0.4, 8.0),
              ("city", lambda: city(128), 0.2, 8.0)]


@pytest.mark.parametrize(("name", "pixels", "roughness", "theta1_pixels"), GRID_CASES)
def test_the_grid_path_is_the_direct_sum_interpolated(name: str, pixels: object, roughness: float,
                                                      theta1_pixels: float) -> None:
    # The grid path evaluates the direct sum's own weights at grid nodes (half a pixel apart) and interpolates
    # (Catmull-Rom, third order). For a lobe of half width >= 2 px and a ramp >= 3 px the node spacing is at most a
    # quarter of either feature, so the interpolation error is ~ (1/4)^3 of the local variation: held here to
    # 2e-3 relative RMS, a fifth of the 1 % a chain level is allowed (measured 0.003-0.05 %), at cube texels, both
    # poles and the seam. Against the brute force it keeps the direct sum's bounds.
    px = pixels()  # type: ignore[operator]
    h = px.shape[0]
    theta1 = theta1_pixels * np.pi / h
    lobe = WindowedLobe(GGXSplitSum(roughness), 0.5 * theta1, theta1, near=True)
    assert half_width(lobe, theta1) >= GRID_MIN_HALF_WIDTH * np.pi / h  # a case the grid path is made for
    dirs = np.concatenate([cube_face_dirs(8).reshape(-1, 3), directions()])
    direct = angular_convolution(px, lobe, dirs, theta1, method="direct")
    grid = angular_convolution(px, lobe, dirs, theta1, method="grid")
    assert rel_rms(grid, direct) < 2e-3, rel_rms(grid, direct)
    ref = brute_force(px, lobe, dirs[::5])
    np.testing.assert_allclose(grid[::5], ref, rtol=1e-2, atol=1e-3 * np.abs(ref).max())
    # the clamped interpolation keeps the range: a positive unit-mass lobe of a map in [lo, hi] stays there
    mass = cap_mass(lobe, theta1)
    assert grid.min() >= px.min() * mass * (1 - 1e-12) and grid.max() <= px.max() * mass * (1 + 1e-12)


def test_auto_takes_the_grid_only_where_it_is_accurate_and_cheaper() -> None:
    h, pixel = 512, np.pi / 512
    n_grid = (GRID_K * h + 1) * GRID_K
    assert grid_pays(3.8 * pixel, 8 * pixel, h, 6 * 128 * 128)  # city's r = 0.134 level at 128^2 faces
    assert not grid_pays(3.8 * pixel, 2 * pixel, h, 6 * 128 * 128)  # a ramp the half-pixel grid cannot follow
    assert not grid_pays(1.5 * pixel, 8 * pixel, h, 6 * 128 * 128)  # narrower than 2 px: summed per texel
    assert not grid_pays(3.8 * pixel, 8 * pixel, h, GRID_MIN_RATIO * n_grid)  # too few texels to pay for it
    # and "auto" gives what the chosen path gives
    px = sun_sky(32)
    theta1 = 8 * np.pi / 32
    lobe = WindowedLobe(GGXSplitSum(0.4), 0.5 * theta1, theta1, near=True)
    many = cube_face_dirs(32).reshape(-1, 3)  # 6144 > 4 x 130 stencils
    np.testing.assert_array_equal(angular_convolution(px, lobe, many, theta1),
                                  angular_convolution(px, lobe, many, theta1, method="grid"))
    few = directions()
    np.testing.assert_array_equal(angular_convolution(px, lobe, few, theta1),
                                  angular_convolution(px, lobe, few, theta1, method="direct"))
    with pytest.raises(ValueError, match="method"):
        angular_convolution(px, lobe, few, theta1, method="fft")  # type: ignore[arg-type]
