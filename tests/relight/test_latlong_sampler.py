"""Tests for the one lat-long sampler (relight.conventions: latlong_dirs, dirs_to_pixel, bilinear_latlong,
sample_latlong) against closed forms: exact values at pixel centres, exact reproduction of functions that are
bilinear in the pixel coordinates, wrap-around in phi and clamping at the poles; and the upsampling of
relight.envmap.resample, which is the same sampler on a grid."""

from __future__ import annotations

import numpy as np

from relight.conventions import bilinear_latlong, dirs_to_pixel, latlong_dirs, sample_latlong
from relight.envmap import resample_latlong

H, W = 6, 12


def test_pixel_centres_round_trip_and_return_the_texels() -> None:
    rng = np.random.default_rng(3)
    maps = rng.normal(size=(2, H, W, 3))
    dirs = latlong_dirs(H, W).reshape(-1, 3)
    y, x = dirs_to_pixel(dirs, H, W)
    np.testing.assert_allclose(y.reshape(H, W), np.repeat(np.arange(H)[:, None], W, 1), atol=1e-12)
    np.testing.assert_allclose(x.reshape(H, W), np.repeat(np.arange(W)[None, :], H, 0), atol=1e-12)
    out = sample_latlong(maps, dirs)  # (H W, 2, 3)
    np.testing.assert_allclose(out.reshape(H, W, 2, 3), np.moveaxis(maps, 0, 2), atol=1e-12)


def test_bilinear_functions_are_reproduced_between_centres() -> None:
    """f(y, x) = a + b y + c x + d x y is reproduced exactly inside a cell (no wrap, no clamp)."""
    yy, xx = np.meshgrid(np.arange(H, dtype=float), np.arange(W, dtype=float), indexing="ij")
    image = (1.0 + 0.5 * yy - 0.25 * xx + 0.125 * xx * yy)[..., None]
    rng = np.random.default_rng(4)
    y = rng.uniform(0, H - 1, 200)
    x = rng.uniform(0, W - 1, 200)
    want = 1.0 + 0.5 * y - 0.25 * x + 0.125 * x * y
    np.testing.assert_allclose(bilinear_latlong(image, y, x)[:, 0], want, rtol=1e-13)


def test_columns_wrap_and_rows_clamp() -> None:
    image = np.arange(H * W, dtype=float).reshape(H, W)
    # halfway between the last and the first column: their mean
    np.testing.assert_allclose(bilinear_latlong(image, np.array([2.0]), np.array([W - 0.5])),
                               0.5 * (image[2, -1] + image[2, 0]))
    np.testing.assert_allclose(bilinear_latlong(image, np.array([2.0]), np.array([-0.5])),
                               0.5 * (image[2, -1] + image[2, 0]))
    # beyond the first / last row centre (towards the poles): the row itself
    np.testing.assert_allclose(bilinear_latlong(image, np.array([-0.4, H - 0.6]), np.array([3.0, 3.0])),
                               [image[0, 3], image[-1, 3]])


def test_resample_upsampling_is_the_sampler_on_the_new_grid() -> None:
    """Upsampling to height h: every output pixel is the bilinear lookup at its own centre direction."""
    rng = np.random.default_rng(5)
    src = rng.uniform(0.0, 2.0, size=(H, W, 3))
    up = resample_latlong(src, 2 * H + 1)
    want = sample_latlong(src[None], latlong_dirs(2 * H + 1, 4 * H + 2).reshape(-1, 3))[:, 0]
    np.testing.assert_allclose(up.reshape(-1, 3), want, rtol=2e-7)  # float32 output: half an ulp is 6e-8
