"""The GPU side of seed 003 (relight/gl/sh_table.py, web/shaders/sh_rotation.glsl, sh_table.vert.glsl) against the
CPU (relight.sh_rotation, relight.sh_render.shade), on Mesa's llvmpipe through moderngl (EGL).

Tolerances (why they are what they are):

* Rotation: the issue's target, 1e-5 in float32 up to l = 8, applied to band-normalised coefficient vectors (so it
  bounds the spectral error of each band matrix). float32's unit roundoff is 6e-8; the recursion's error grows
  with l (measured ~1e-6 at l = 8), so 1e-5 leaves room for other GPUs' fused/unfused arithmetic.
* Shading (same float16 table data on both sides): a lookup may differ by the GPU's fixed-point sub-texel weight
  (2^-9 of the change across the 2 x 2 footprint, as tests/relight/test_gl_render.py) times |L_local,i|, plus the
  rotation error (1e-5 per band, times the band norms of the lighting and of the coefficients), plus float32 sums.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import relight.gl.render as gl_render
import relight.gl.sh_rotation_glsl as sh_rotation_glsl
from relight.brdf.spec import parse_frame_brdf
from relight.gl.sh_table import MODES, TableRenderer
from relight.indexing import full_block
from relight.mesh.load import sample_mesh
from relight.sh_render import shade
from relight.sh_rotation import local_rotations, rotate_coefficients
from relight.sh_table import SHTable, build_table
from relight.tangent_frames import projected_frames
from relight.view_maps import view_to_texel

ROT_TOL = 1e-5
FILTER_STEP = 2.0**-9
SLACK = 1.5


@pytest.fixture(scope="module")
def ctx() -> Any:
    c = gl_render.create_context()
    yield c
    c.release()


def hard_frames(rng: np.random.Generator, count: int) -> np.ndarray:
    """Random projected-tangent frames, half mirrored (glTF w = -1), plus normals exactly on and within 1e-8 of
    +-z (the Euler-angle singularities a zyz method would hit)."""
    n = rng.normal(size=(count, 3))
    n[:4] = [[0, 0, 1], [0, 0, -1], [1e-8, 0, 1], [0, -1e-8, -1]]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    f = projected_frames(n, (0.3, 0.2, 0.9))
    f[1::2, 1] *= -1.0
    return f


def band_normalised(rng: np.random.Generator, order: int) -> np.ndarray:
    c = rng.normal(size=((order + 1) ** 2, 3))
    for l in range(order + 1):
        c[full_block(l)] /= np.linalg.norm(c[full_block(l)], axis=0)
    return c


@pytest.mark.parametrize("order", [1, 4, 8])
def test_glsl_rotation_matches_numpy(ctx: Any, order: int) -> None:
    rng = np.random.default_rng(order)
    frames = hard_frames(rng, 300)
    light = band_normalised(rng, order)
    r = TableRenderer(np.zeros((2, 2, (order + 1) ** 2, 1)), "parabolic", ctx=ctx)
    geo = r.geometry(np.zeros((300, 3)), frames[:, 2], frames)
    r.prepare("fixed-light", geo, view=(0, 0, 1), lighting=light)
    gpu = r.vertex_data()[: 300 * light.shape[0]].reshape(300, -1, 3)
    cpu = rotate_coefficients(local_rotations(frames, order), light[None])
    assert np.abs(gpu - cpu).max() <= ROT_TOL
    r.release()


def test_glsl_rotation_matrix_entries_l8(ctx: Any) -> None:
    """Every column of every band matrix at l <= 8: rotate basis vectors (three per pass, one per channel)."""
    order, n = 8, 81
    rng = np.random.default_rng(7)
    frames = hard_frames(rng, 24)
    r = TableRenderer(np.zeros((2, 2, n, 1)), "hemi-octahedral", ctx=ctx)
    geo = r.geometry(np.zeros((24, 3)), frames[:, 2], frames)
    blocks = local_rotations(frames, order)
    worst = 0.0
    for j0 in range(0, n, 3):
        basis = np.zeros((n, 3))
        for ch in range(3):
            if j0 + ch < n:
                basis[j0 + ch, ch] = 1.0
        r.prepare("fixed-light", geo, view=(0, 0, 1), lighting=basis)
        gpu = r.vertex_data()[: 24 * n].reshape(24, n, 3)
        worst = max(worst, float(np.abs(gpu - rotate_coefficients(blocks, basis[None])).max()))
    assert worst <= ROT_TOL
    r.release()


def footprint_range(table: SHTable, views: np.ndarray) -> np.ndarray:
    """Per point and coefficient, max - min over the 2 x 2 texels a bilinear lookup reads (N, n, C)."""
    x, y = view_to_texel(table.layout, table.resolution, views)
    res = table.resolution
    x0 = np.clip(np.floor(x).astype(int), 0, res - 1)
    y0 = np.clip(np.floor(y).astype(int), 0, res - 1)
    x1, y1 = np.minimum(x0 + 1, res - 1), np.minimum(y0 + 1, res - 1)
    quad = np.stack([table.coefficients[y0, x0], table.coefficients[y0, x1], table.coefficients[y1, x0],
                     table.coefficients[y1, x1]])
    return np.asarray(quad.max(axis=0) - quad.min(axis=0))


def check_modes(ctx: Any, coefficients: np.ndarray, layout: str, order: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    frames = hard_frames(rng, 600)
    view = np.array([0.25, 0.55, 0.8])  # neither the view nor the tangent direction is mirror-symmetric
    view /= np.linalg.norm(view)
    light = rng.normal(size=((order + 1) ** 2, 3)) * 0.3
    light[0] += 3.0
    r = TableRenderer(coefficients, layout, ctx=ctx)
    res = r.uploaded.shape[0]  # the CPU reference reads the uploaded float16 values (as float64)
    half = SHTable(r.uploaded, np.zeros((res, res, 3)), np.ones((res, res), bool), order, layout, {})
    cpu = shade(half, light, frames, view, exact_azimuth=False)
    vl = np.einsum("nij,j->ni", frames, view)
    local = rotate_coefficients(local_rotations(frames, order), light[None])
    coef = half.lookup(vl, exact_azimuth=False)
    band_norm = np.zeros(cpu.shape)
    for l in range(order + 1):
        band_norm += np.linalg.norm(local[:, full_block(l)], axis=1) * np.linalg.norm(coef[:, full_block(l)], axis=1)
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", np.abs(local), footprint_range(half, vl))
                   + ROT_TOL * band_norm + 1e-6 * np.einsum("nic,nic->nc", np.abs(local), np.abs(coef)))
    tol = np.where((vl[:, 2] > 0)[:, None], tol, 0.0) + 1e-7
    assert np.abs(cpu).max() > 0.1  # the comparison sees real shading
    for mode in MODES:
        gpu = r.probe(mode, frames[:, 2], frames, view, light)
        excess = np.abs(gpu - cpu) - tol
        assert excess.max() <= 0.0, (mode, float(np.abs(gpu - cpu).max()), int(np.argmax(excess.max(axis=1))))
    r.release()


def test_three_modes_match_cpu_anisotropic_parabolic(ctx: Any) -> None:
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0"), resolution=48)
    check_modes(ctx, table.coefficients, "parabolic", 4, 1)


def test_three_modes_match_cpu_rgb_hemi_octahedral(ctx: Any) -> None:
    table = build_table(parse_frame_brdf("torrance-sparrow:alpha_u=0.15,alpha_v=0.45,distribution=ggx,fresnel=none"),
                        resolution=40, layout="hemi-octahedral", order=2)
    tint = np.array([1.0, 0.7, 0.4])
    check_modes(ctx, table.coefficients * tint, "hemi-octahedral", 2, 2)


def test_mesh_images_agree_across_modes(ctx: Any) -> None:
    """The bunny drawn in each mode: the same per-vertex values through the same rasteriser, so the images agree
    to float32 (up to the rotation tolerance); pixels off the mesh stay at the background."""
    mesh = sample_mesh("bunny").normalised()
    frames = projected_frames(mesh.normals, (1.0, 0.3, 0.2))
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0"), resolution=32)
    rng = np.random.default_rng(3)
    light = rng.normal(size=(25, 3)) * 0.2
    light[0] += 2.0
    view = np.array([0.3, 0.4, 0.87])
    r = TableRenderer(table.coefficients, "parabolic", ctx=ctx)
    geo = r.geometry(mesh.positions, mesh.normals, frames, mesh.faces)
    images = {}
    for mode in MODES:
        r.prepare(mode, geo, view=view, lighting=light)
        images[mode] = r.draw(mode, geo, view, light, 96, background=-1.0)
    on = images["general"][..., 0] != -1.0
    assert 0.2 < on.mean() < 0.9
    for mode in MODES[1:]:
        assert np.array_equal(images[mode][..., 0] != -1.0, on)
        assert np.abs(images[mode] - images["general"]).max() <= 1e-4 * np.abs(images["general"][on]).max()
    r.release()


def test_generated_rotation_glsl_is_current() -> None:
    assert Path(sh_rotation_glsl.GENERATED).read_text(encoding="utf-8") == sh_rotation_glsl.glsl(), (
        "web/shaders/generated/sh_rotation_bands.glsl is stale: run python -m relight.gl.sh_rotation_glsl --write")
