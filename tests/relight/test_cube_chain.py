"""Prefiltered cube chains (relight.cube_chain) against the dense angular brute force of the same lobe.

The issue's criterion: every mip level within 1 % relative RMS (Rec. 709 luminance, over all texels) of the
brute force of that level's split-sum GGX lobe at the texel directions. The brute force
(relight.cap_convolution.brute_force) integrates the map's bilinear interpolant on a grid finer than the lobe,
over the whole sphere and without normalisation, so a chain that mis-weights a lobe narrower than a pixel shows
against it. Maps: a synthetic sky with a 1e4 sun (the hard case), a real map, and an octant-coloured map whose
levels must stay within its range (a unit-mass positive lobe cannot leave it).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from sky_refs import sun_sky

from relight.brdf.splitsum import GGXSplitSum
from relight.cap_convolution import WindowedLobe, angular_convolution, brute_force, cap_mass, grid_pays, half_width
from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, sample_latlong
from relight.cube_chain import BABYLON_LOD_SCALE, TARGET_MAPPING, level_roughness, mirror_level, prefilter_chain
from relight.envmap import cube_face_dirs, read_envmap
from relight.envmap.cubemap import _face_uv_to_dirs
from relight.errors import InputError

ENVMAPS = Path(__file__).resolve().parents[2] / "data" / "envmaps"
#: The issue's per-level limit.
LEVEL_RMS = 0.01


@cache
def city(h: int) -> np.ndarray:
    px = np.asarray(read_envmap(ENVMAPS / "city.exr").pixels, dtype=np.float64)
    f = px.shape[0] // h
    return np.asarray(px.reshape(h, f, 2 * h, f, 3).mean(axis=(1, 3)), dtype=np.float64)


def rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    la, lb = a @ LUMINANCE_WEIGHTS, b @ LUMINANCE_WEIGHTS
    return float(np.sqrt(np.mean((la - lb) ** 2) / np.mean(lb**2)))


@pytest.mark.parametrize("mapping", ["quadratic", "linear"])
def test_level_roughness_inverts_the_engine_lod_mapping(mapping: str) -> None:
    r = level_roughness(7, mapping)  # type: ignore[arg-type]
    lod = np.arange(7) / 6
    expect = r * (2 - r) if mapping == "quadratic" else r
    np.testing.assert_allclose(expect, lod, atol=1e-15)
    assert r[0] == 0.0 and r[-1] == 1.0


def test_babylon_levels_follow_its_lod_formula() -> None:
    # Babylon's shader: lod = lodGenerationScale * log2(size * alphaG), alphaG = r^2; level 0 is the mirror
    for size in (16, 256):
        r = level_roughness(int(np.log2(size)) + 1, "log2", size)
        assert r[0] == 0.0
        lod = BABYLON_LOD_SCALE * np.log2(size * r[1:] ** 2)
        np.testing.assert_allclose(lod, np.arange(1, r.size), atol=1e-12)
        assert r[-1] ** 2 == pytest.approx(size**0.25)  # alpha > 1 at the end of the chain
    with pytest.raises(InputError, match="face size"):
        level_roughness(5, "log2")


@pytest.mark.parametrize(("name", "pixels", "size"), [("sun-sky", lambda: sun_sky(32), 16),
                                                      ("city", lambda: city(64), 16)])
@pytest.mark.parametrize("target", ["three", "gltf", "babylon"])
def test_every_level_matches_the_brute_force(name: str, pixels: object, size: int, target: str) -> None:
    px = pixels()  # type: ignore[operator]
    chain = prefilter_chain(px, target=target, size=size)
    assert [lv.size for lv in chain.levels] == [size >> i for i in range(len(chain.levels))]
    methods = {lv.method for lv in chain.levels}
    assert "sample" in methods and ("split" in methods or "sh" in methods)
    for lv in chain.levels:
        dirs = cube_face_dirs(lv.size).reshape(-1, 3)
        faces = lv.faces.reshape(-1, 3).astype(np.float64)
        if lv.method == "sample":
            assert lv.roughness == 0.0
            continue
        ref = brute_force(px, GGXSplitSum(lv.roughness, max_roughness=3.0), dirs)
        err = rel_rms(faces, ref)
        assert err <= LEVEL_RMS, (name, target, lv.level, lv.method, err)
        # App. B is a bound: it must hold (the prediction is only a heuristic)
        assert err <= lv.bound_rms + 1e-6, (name, lv.level, err, lv.bound_rms)


def octant_map(h: int) -> np.ndarray:
    d = latlong_dirs(h, 2 * h)
    return np.stack([np.where(d[..., k] > 0, 1.0, 0.05) for k in range(3)], axis=-1)


@pytest.mark.parametrize(("h", "size"), [(32, 16), (64, 64)])
def test_octant_levels_stay_within_the_maps_range(h: int, size: int) -> None:
    # values in [0.05, 1]: a normalised positive lobe keeps every texel there. Before the near part was
    # normalised, level 1 of the 64-row map at size 64 (r = 0.087, a lobe a tenth of a pixel wide) reached 3.47.
    # The near part alone is held to the exact range (its weights are positive and sum to its mass); the whole
    # level may ring by its SH part's truncation (the far part, or the whole lobe on "sh" levels: predicted 0.5 %
    # relative RMS, so 2 % of the range at a texel, four times that); and every level within 1 % of the brute force.
    px = octant_map(h)
    chain = prefilter_chain(px, target="three", size=size)
    assert any(lv.method == "split" and lv.roughness < 0.15 for lv in chain.levels)  # a lobe < 1/4 pixel
    for lv in chain.levels:
        faces = lv.faces.reshape(-1, 3).astype(np.float64)
        assert faces.max() <= 1.0 + 0.02 * 0.95 and faces.min() >= 0.05 - 0.02 * 0.95, (lv.level, lv.method)
        if lv.method == "sample":
            continue
        dirs = cube_face_dirs(lv.size).reshape(-1, 3)
        lobe = GGXSplitSum(lv.roughness, max_roughness=3.0)
        if lv.method == "split":
            near = WindowedLobe(lobe, 0.5 * lv.near_angle, lv.near_angle, near=True)
            part = angular_convolution(px, near, dirs, lv.near_angle) / cap_mass(near, lv.near_angle)
            assert part.max() <= 1.0 + 1e-12 and part.min() >= 0.05 - 1e-12, lv.level
        assert rel_rms(faces, brute_force(px, lobe, dirs)) <= LEVEL_RMS, lv.level


def test_level_zero_is_the_map_itself() -> None:
    px = sun_sky(32)
    chain = prefilter_chain(px, target="filament", size=32, levels=1)
    lv = chain.levels[0]
    # texel centres at the map's pixel centres reproduce the pixels: check the +Y face centre against the top rows
    assert lv.method == "sample" and lv.faces.shape == (6, 32, 32, 3)
    top = px[0].mean(axis=0)
    np.testing.assert_allclose(lv.faces[2, 15:17, 15:17].mean(axis=(0, 1)), top, rtol=0.05)


@pytest.mark.parametrize(("h", "size"), [(8, 4), (32, 16), (64, 128)])
def test_level_zero_is_the_four_tap_copy(h: int, size: int) -> None:
    # the compiled level 0 against its definition written with the library's own pieces: the face directions a
    # quarter texel off each centre and the lat-long sampler, averaged (agreement to rounding: the compiled loop
    # takes the angles of the unnormalised directions)
    px = np.random.default_rng(h).uniform(0.0, 4.0, size=(h, 2 * h, 3))
    g = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    quarter = 0.5 / size
    want = np.zeros((6 * size * size, 3))
    for db in (-quarter, quarter):
        for da in (-quarter, quarter):
            dirs = _face_uv_to_dirs(g[None, :, None] + db, g[None, None, :] + da, np.arange(6)[:, None, None])
            want += 0.25 * sample_latlong(px[None], dirs.reshape(-1, 3))[:, 0]
    np.testing.assert_allclose(mirror_level(px, size), want, rtol=1e-12, atol=1e-13)


def test_bad_arguments_are_refused() -> None:
    px = sun_sky(16)
    with pytest.raises(InputError, match="target"):
        prefilter_chain(px, target="unreal")
    with pytest.raises(InputError, match="power of two"):
        prefilter_chain(px, size=48)
    with pytest.raises(InputError, match="levels"):
        prefilter_chain(px, size=16, levels=6)
    assert set(TARGET_MAPPING) == {"three", "filament", "gltf", "babylon"}


def test_a_level_summed_on_the_grid_matches_the_brute_force() -> None:
    # city.exr at 256 rows (its sun 8e3 x the mean over a pixel), filament's 4 levels at 64^2: level 1 (r = 0.184,
    # half width 3.5 px) is split and its near part (window 16 px, 6144 texels) is summed on the grid
    # (relight.cap_convolution.grid_pays). 400 seeded texels against the brute force, held to the 1 %.
    # Before the far part was held to epsilon on its own energy this level measured 1.24 % (its far part, at
    # epsilon / share capped at 0.05, rang beside the sun).
    px = city(256)
    chain = prefilter_chain(px, target="filament", size=64, levels=4)
    lv = chain.levels[1]
    assert lv.method == "split"
    near = WindowedLobe(GGXSplitSum(lv.roughness, max_roughness=3.0), 0.5 * lv.near_angle, lv.near_angle, near=True)
    assert grid_pays(half_width(near, lv.near_angle), 0.5 * lv.near_angle, 256, 6 * lv.size**2)
    dirs = cube_face_dirs(lv.size).reshape(-1, 3)
    pick = np.random.default_rng(7).choice(dirs.shape[0], 400, replace=False)
    ref = brute_force(px, GGXSplitSum(lv.roughness, max_roughness=3.0), dirs[pick])
    err = rel_rms(lv.faces.reshape(-1, 3)[pick].astype(np.float64), ref)
    assert err <= LEVEL_RMS and err <= lv.bound_rms, (err, lv.bound_rms)
