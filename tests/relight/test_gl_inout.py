"""In-out PRT on the GPU (relight/gl/inout.py, web/shaders/inout.vert.glsl) against the CPU reference
(relight/inout_prt.shade) on the same float16 transport: the shader's float32 acos/atan and sums against float64.

Per vertex the allowance is 3e-4 of ``sum_k |sigma_k h_k| |T_k . L|`` plus 1e-6: GLSL leaves the precision of
acos, atan, sin and cos to the implementation (ES 3.0 §8.1 gives no bound), and the angles feed cos(m phi) (m up to
11) and the theta interpolation of profiles that change by up to ~10x their value per radian; measured on Mesa
llvmpipe: at most 9e-5 of that sum at every vertex (6.5e-5 of the largest radiance). A wrong term, sign, pair or
row would be off by O(1). The image: the GPU's rasterised Gouraud colours
against the CPU vertex colours interpolated with the primary-ray barycentrics (relight.mesh_render, pixel for pixel
the same camera), as tests/relight/test_gl_prt.py; shadows darken the image against V = 1.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

import relight.gl.render as gl_render
from relight.brdf.spec import parse_brdf
from relight.gl.inout import InOutRenderer
from relight.inout_factors import build_factors
from relight.inout_prt import mesh_transport, shade
from relight.mesh.load import sample_mesh
from relight.mesh_render import interpolate, surface_samples
from relight.tangent_frames import azimuthal_frames

VIEW = np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0])


@pytest.fixture(scope="module")
def ctx() -> Iterator[Any]:
    c = gl_render.create_context()
    yield c
    c.release()


@pytest.fixture(scope="module")
def bunny() -> dict[str, Any]:
    mesh = sample_mesh("bunny").normalised()
    f = build_factors(parse_brdf("torrance-sparrow:alpha=0.4,fresnel=none"), energy=0.99)
    rng = np.random.default_rng(3)
    light = rng.normal(size=(25, 3)) * 0.3
    light[0] += 3.0
    return {"mesh": mesh, "factors": f, "light": light,
            "shadowed": mesh_transport(mesh, f, 4, rays=256)["transport"],
            "unshadowed": mesh_transport(mesh, f, 4, rays=256, shadows=False)["transport"]}


def test_gpu_vertices_match_the_cpu(ctx: Any, bunny: dict[str, Any]) -> None:
    mesh, f, light = bunny["mesh"], bunny["factors"], bunny["light"]
    r = InOutRenderer(mesh, f, bunny["shadowed"], ctx=ctx)
    gpu = r.probe(light, VIEW)
    frames = azimuthal_frames(mesh.normals)
    cpu = shade(f, r.uploaded, light, frames, VIEW)
    vl = np.einsum("pij,j->pi", frames, VIEW)
    scale = np.einsum("pk,pkc->pc", np.abs(f.sigma * f.evaluate("h", vl)),
                      np.abs(np.einsum("pkj,jc->pkc", r.uploaded, light)))
    assert np.abs(cpu).max() > 0.1 and (cpu == 0).any()  # lit, and back-facing vertices are 0
    assert np.all(np.abs(gpu - cpu) <= 3e-4 * scale + 1e-6), float(np.abs(gpu - cpu).max())
    # the viewer's K slider: fewer terms summed from the same texture (stride of all stored terms)
    short = f.truncated(8)
    gpu8 = r.probe(light, VIEW, terms=short.terms)
    cpu8 = shade(short, r.uploaded[:, : short.terms], light, frames, VIEW)
    assert np.abs(cpu8 - cpu).max() > 0.01 * np.abs(cpu).max()  # truncation changes the result ...
    assert np.all(np.abs(gpu8 - cpu8) <= 3e-4 * scale + 1e-6)  # ... and the GPU follows it
    r.release()


def test_gpu_image_matches_the_cpu_and_shadows_darken(ctx: Any, bunny: dict[str, Any]) -> None:
    mesh, f, light = bunny["mesh"], bunny["factors"], bunny["light"]
    size = 64
    r = InOutRenderer(mesh, f, bunny["shadowed"], ctx=ctx)
    img = r.draw(light, VIEW, size)
    samples = surface_samples(mesh, VIEW, size, supersample=1)
    want = samples.image(interpolate(samples, mesh, shade(f, r.uploaded, light, azimuthal_frames(mesh.normals),
                                                          VIEW)))
    covered = samples.coverage == 1.0
    assert covered.sum() > 0.2 * size * size
    bad = np.abs(img - want).max(axis=2) > 2e-4 * want.max()  # rasteriser vs ray barycentrics (test_gl_prt.py)
    assert bad[covered].mean() < 0.005, bad[covered].mean()
    lit = InOutRenderer(mesh, f, bunny["unshadowed"], ctx=ctx).draw(light, VIEW, size)
    assert lit[covered].mean() > 1.05 * img[covered].mean()  # the bunny shadows itself
    r.release()
