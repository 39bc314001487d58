"""The moderngl renderer (relight/gl) against the CPU evaluation of seed 000 eq. 12 and eq. 6 (relight.shrm).

The shaders are the browser viewer's (web/shaders); the CPU side is ``relight.shrm`` (render_sphere, view_map,
relight.conventions.sample_latlong, real_harmonics, local_view_angles), written independently from the paper.

Tolerances (why they are what they are):

* Per-texel sums (the per-frame eq. 12 map, no filtering): the coefficient texture is float16 like
  ``coefficients.bin``; rounding a value to binary16 changes it by at most 2^-11 of its magnitude, so
  ``|gl - cpu| <= 2^-11 sum_k |w_k| |B_k|`` plus float32 arithmetic (~1e-6 relative). The distant path sums
  global layers (eq. 8 applied once to the float16 local layers, then stored as float16 again): the second
  rounding adds ``2^-11 sum_k |Yr_k(V)| |B~_k|``, and the first one, carried through the rotation (orthogonal
  within each band p), at most ``2^-11 sum_p |Yr_p(V)|_2 |B_p|_2`` with ``|Yr_p|_2 = sqrt((2p + 1) / 4 pi)``
  (addition theorem). We allow 1.5 x the bound.
* Images (bilinear lookups): GPU texture units interpolate with a fixed-point sub-texel weight (8 bits is
  common; llvmpipe's error measured here stays below 1/1400 of a texel step), so a lookup may also differ by up to
  2^-9 of the change across its 2 x 2 texel footprint. Per pixel we allow
  ``1.5 (2^-11 sum_k |w_k| |B_k|(C) + 2^-9 sum_k |w_k| range_k(C)) + 1e-6``.
  With S ~ 10 F (seed 000 §5.2), texel steps are small and the half-float term dominates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import relight.gl.layout as gl_layout
import relight.gl.render as gl_render
import relight.gl.shaders as gl_shaders
from relight import indexing, sh, shrm
from relight.conventions import dirs_to_angles, dirs_to_pixel, latlong_dirs, sample_latlong

# relight.sh's Legendre recursion warns (harmlessly) at the exact poles
pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered in multiply:RuntimeWarning")

HALF_EPS = 2.0**-11  # binary16 unit roundoff
FILTER_STEP = 2.0**-9  # half of an 8-bit sub-texel weight step
SLACK = 1.5
VIEWS = [(0.0, 0.0, 1.0), (0.3, 0.8, -0.5), (-0.7, -0.2, 0.4), (0.0, 1.0, 0.0)]


@pytest.fixture(scope="module")
def ctx() -> Any:
    c = gl_render.create_context()  # EGL on Mesa: `make test` installs it (an error here is a failure)
    yield c
    c.release()


def smooth_maps(rng: np.random.Generator, count: int, order: int, rows: int, offset: float = 2.0) -> np.ndarray:
    """``count`` random real RGB maps band-limited to ``order`` on a rows x 2 rows grid, (count, S, 2S, 3)."""
    l, m = indexing.healpy_lm(order)
    out = []
    for _ in range(count):
        alm = rng.normal(size=(3, indexing.healpy_size(order))) + 1j * rng.normal(size=(3, indexing.healpy_size(order)))
        alm[:, m == 0] = alm[:, m == 0].real
        alm /= np.sqrt(l + 1.0)
        out.append(sh.synthesize(alm, order, rows) + offset)
    return np.stack(out)


@pytest.fixture(scope="module")
def synthetic() -> shrm.SHRM:
    """Every structure and centre: general R-centred (P = 3), radial N-centred, azimuthal T-centred (P = 2)."""
    rng = np.random.default_rng(42)
    f, s = 4, 40  # S ~ 10 F (seed 000 §5.2)
    comps = [
        shrm.SHRMComponent("R", "general", f, 3, shrm.terms_for("general", 3), smooth_maps(rng, 16, f, s), {}),
        shrm.SHRMComponent("N", "radial", f, 0, [(0, 0)], smooth_maps(rng, 1, f, s), {}),
        shrm.SHRMComponent("T", "azimuthal", f, 2, shrm.terms_for("azimuthal", 2), smooth_maps(rng, 3, f, s), {}),
    ]
    return shrm.SHRM(comps)


def renderer_for(ctx: Any, model: shrm.SHRM, frame: str) -> Any:
    manifest, stack = gl_layout.layers_from_shrm(model, frame=frame)
    return gl_render.Renderer(gl_layout.from_manifest(manifest), stack, ctx=ctx)


def unit(v: Any) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    return a / np.linalg.norm(a)


# ---------------------------------------------------------------------------------------- CPU references
def footprint(maps: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|maps| sampled bilinearly and the range (max - min) over each lookup's 2 x 2 texels: (n, K, 3) each."""
    _, h, w, _ = maps.shape
    y, x = dirs_to_pixel(dirs, h, w)
    y0 = np.clip(np.floor(np.clip(y, 0.0, h - 1.0)).astype(np.intp), 0, max(h - 2, 0))
    y1 = np.minimum(y0 + 1, h - 1)
    x0 = np.mod(np.floor(x).astype(np.intp), w)
    x1 = np.mod(x0 + 1, w)
    m = np.moveaxis(maps, 0, 2)
    corners = np.stack([m[y0, x0], m[y0, x1], m[y1, x0], m[y1, x1]])
    return sample_latlong(np.abs(maps), dirs), corners.max(axis=0) - corners.min(axis=0)


def band_bound(comp: shrm.SHRMComponent, centres: np.ndarray, view: np.ndarray) -> np.ndarray:
    """The extra float16 error of the distant path's global layers at the centres, (n, 3) (module docstring)."""
    mags = np.abs(sample_latlong(comp.maps, centres))  # (n, K, 3)
    bands = np.zeros(mags.shape[:1] + (comp.P + 1, 3))
    for k, (p, _) in enumerate(comp.terms):
        bands[:, p] += mags[:, k] ** 2
    norms = np.sqrt((2.0 * np.arange(comp.P + 1) + 1.0) / (4.0 * np.pi))
    out = HALF_EPS * np.einsum("npc,p->nc", np.sqrt(bands), norms)
    glob = comp.global_maps()
    y = np.abs(shrm.real_harmonics(comp.P, *dirs_to_angles(view)))
    return out + HALF_EPS * np.einsum("nkc,k->nc", np.abs(sample_latlong(glob, centres)), y[: glob.shape[0]])


def shade_cpu(model: shrm.SHRM, frame: str, normals: np.ndarray, views: np.ndarray,
              distant: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 6 (local maps) or eq. 7 (global maps) per pixel with the pixel's own view: value and tolerance, (n, 3).

    The lobe centre C of every component is looked up bilinearly (relight.conventions.sample_latlong) and weighted by
    ``Yr_pq`` of V in C's local frame (local maps) or of V's world angles (global maps). ``distant`` adds the
    rounding of the distant path's global layers (one view for all pixels). The value is clamped at 0 as the
    shader and relight.shrm.shade clamp radiance (issue 18); the clamp only shrinks differences.
    """
    value = np.zeros(normals.shape)
    bound = np.zeros(normals.shape)
    refl = shrm.reflect_dirs(normals, views)
    for comp in model.components:
        c = shrm.lobe_centres(comp.center, normals, refl)
        if frame == "global" and comp.P > 0:
            terms = [(p, q) for p in range(comp.P + 1) for q in range(-p, p + 1)]
            maps = comp.global_maps()
            theta, phi = dirs_to_angles(views)
        else:
            terms, maps = comp.terms, comp.maps
            theta, phi = shrm.local_view_angles(c, views)
        y = shrm.real_harmonics(comp.P, theta, phi)[:, [indexing.full_index(p, q) for p, q in terms]]
        value += np.einsum("nkc,nk->nc", sample_latlong(maps, c), y)
        mag, rng = footprint(maps, c)
        bound += np.einsum("nkc,nk->nc", HALF_EPS * mag + FILTER_STEP * rng, np.abs(y))
        if distant and comp.P > 0:
            bound += band_bound(comp, c, views[0])
    return np.maximum(value, 0.0), SLACK * bound + 1e-6


def perspective_rays(view: np.ndarray, size: int, distance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel (row 0 at the top) the unit-sphere hit normal, the view direction toward the eye, and the mask,
    for relight.gl.render's perspective camera."""
    right, up = gl_render.camera_basis(view)
    half = math.tan(0.5 * gl_render.perspective_fov(distance))
    c = (np.arange(size) + 0.5) * 2.0 / size - 1.0
    x, y = np.meshgrid(c, -c)
    ray = -view + half * (x[..., None] * right + y[..., None] * up)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    eye = distance * view
    b = ray @ eye
    disc = b * b - (eye @ eye - 1.0)
    mask = disc > 0.0
    t = -b - np.sqrt(np.where(mask, disc, 0.0))
    hit = eye + t[..., None] * ray
    return hit, -ray, mask


# ------------------------------------------------------------------------------------------------ tests
def test_generated_shader_constants_are_current() -> None:
    assert gl_shaders.write_generated(check=True) == [], "run: python3 -m relight.gl.shaders --write"


def test_loader_adds_version_defines_and_includes_each_file_once() -> None:
    files = {"a.glsl": '#include "b.glsl"\n#include "c.glsl"\nvoid main() {}\n', "b.glsl": '#include "c.glsl"\nB\n',
             "c.glsl": "C\n"}
    text = gl_shaders.build("a.glsl", target="300 es", defines={"X": 1, "Y": [1, 2], "Z": None, "W": 0.5},
                            read=files.__getitem__)
    assert text.splitlines() == ["#version 300 es", "precision highp float;", "precision highp int;", "#define X 1",
                                 "#define Y 1, 2", "#define Z", "#define W 0.5", "C", "B", "", "void main() {}"]
    assert gl_shaders.build("c.glsl", read=files.__getitem__).startswith("#version 330\n")
    cyclic = {"x": '#include "y"\nX\n', "y": '#include "x"\nY\n'}
    assert gl_shaders.build("x", read=cyclic.__getitem__).splitlines()[1:] == ["", "Y", "X"]


def test_sh_glsl_equals_real_harmonics(ctx: Any) -> None:
    """sh.glsl's Yr_pq (P = 8) against relight.shrm.real_harmonics, at random directions and the poles."""
    p_order = 8
    count = (p_order + 1) ** 2
    rng = np.random.default_rng(7)
    dirs = np.concatenate([rng.normal(size=(62, 3)), [[0, 1, 0], [0, -1, 0]]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    frag = """
#include "generated/constants.glsl"
#include "common.glsl"
#include "sh.glsl"
uniform vec3 u_dirs[64];
layout(location = 0) out vec4 o_color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float y[SH_COUNT];
    sh_real(sh_frame(u_dirs[px.y]), y);
    o_color = vec4(y[px.x]);
}
"""
    read = lambda name: frag if name == "test.glsl" else gl_shaders._read_file(name)  # noqa: E731
    prog = ctx.program(vertex_shader=gl_shaders.build("fullscreen.vert.glsl"),
                       fragment_shader=gl_shaders.build("test.glsl", defines={"SH_ORDER": p_order}, read=read))
    prog["u_dirs"].value = [tuple(d) for d in dirs]
    vao = ctx.vertex_array(prog, [(ctx.buffer(gl_render._FULLSCREEN.tobytes()), "2f", "a_position")])
    fbo = ctx.simple_framebuffer((count, len(dirs)), components=4, dtype="f4")
    fbo.use()
    vao.render(vertices=3)
    got = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype="<f4").reshape(len(dirs), count, 4)[..., 0]
    theta, phi = dirs_to_angles(dirs)
    with np.errstate(invalid="ignore"):  # relight.sh's recursion at the exact poles (log sin = -inf)
        want = np.nan_to_num(shrm.real_harmonics(p_order, theta, phi))
    np.testing.assert_allclose(got, want, atol=2e-6 * np.abs(want).max())


@pytest.mark.parametrize("frame", ["local", "global"])
@pytest.mark.parametrize("view", VIEWS)
def test_view_map_is_eq12_per_texel(ctx: Any, synthetic: shrm.SHRM, frame: str, view: tuple[float, ...]) -> None:
    """The per-frame map (no filtering) equals SHRMComponent.view_map to float16 precision of the layers."""
    v = unit(view)
    r = renderer_for(ctx, synthetic, frame)
    r.render_view_map(v)
    got = r.read_view_map()
    s = synthetic.height
    dirs = latlong_dirs(s, 2 * s)
    for k, comp in enumerate(synthetic.components):
        want = comp.view_map(v)
        # bound: 2^-11 sum |w| |B| with w at the texel (local frame) or V (global frame)
        if frame == "global" and comp.P > 0:
            maps = comp.global_maps()
            y = shrm.real_harmonics(comp.P, *dirs_to_angles(v))[None, None, :]
        else:
            maps = comp.maps
            y = shrm.real_harmonics(comp.P, *shrm.local_view_angles(dirs, v))
            y = y[..., [indexing.full_index(p, q) for p, q in comp.terms]]
        bound = HALF_EPS * np.einsum("khwc,hwk->hwc", np.abs(maps), np.abs(y))
        if frame == "local" and comp.P > 0:
            bound = bound + band_bound(comp, dirs.reshape(-1, 3), v).reshape(bound.shape)
        bound = SLACK * bound + 1e-6
        err = np.abs(got[k] - want)
        assert np.all(err <= bound), f"component {k}: worst error / bound = {(err / bound).max():.3f}"
    r.release()


@pytest.mark.parametrize("view", VIEWS)
@pytest.mark.parametrize("mode", ["distant", "near"])
def test_sphere_matches_render_sphere(ctx: Any, synthetic: shrm.SHRM, view: tuple[float, ...], mode: str) -> None:
    """Orthographic sphere: 'distant' is render_sphere(local=False) (eq. 12), 'near' render_sphere(local=True)."""
    v = unit(view)
    size = 64
    r = renderer_for(ctx, synthetic, "local")
    got = r.render(v, size, mode=mode)
    want = shrm.render_sphere(synthetic, v, size, local=(mode == "near"))
    n, mask = shrm.sphere_geometry(v, size)
    _, tol = shade_cpu(synthetic, "local", n[mask], np.broadcast_to(v, (mask.sum(), 3)), distant=(mode == "distant"))
    err = np.abs(got[mask] - want[mask])
    assert np.all(err <= tol), f"worst error / tolerance = {(err / tol).max():.3f}"
    assert np.all(got[~mask] == 0.0)
    r.release()


@pytest.mark.parametrize("frame", ["local", "global"])
def test_near_viewer_perspective_is_eq6_per_pixel(ctx: Any, synthetic: shrm.SHRM, frame: str) -> None:
    """A perspective camera at 2.5 radii: every pixel uses its own view direction (eq. 6 / eq. 7)."""
    v, size, distance = unit((0.4, 0.5, 0.75)), 64, 2.5
    r = renderer_for(ctx, synthetic, frame)
    got = r.render(v, size, mode="near", camera="perspective", distance=distance)
    hit, views, mask = perspective_rays(v, size, distance)
    inner = mask & (np.einsum("ijk,ijk->ij", hit, views) > 0.05)  # away from the silhouette's edge pixels
    want, tol = shade_cpu(synthetic, frame, hit[inner], views[inner])
    err = np.abs(got[inner] - want)
    assert np.all(err <= tol), f"worst error / tolerance = {(err / tol).max():.3f}"
    assert inner.sum() > 0.6 * mask.sum()
    r.release()


def test_environment_rotation_is_a_shift_of_beta(ctx: Any, synthetic: shrm.SHRM) -> None:
    """Rotating the environment by 2 pi k / W about +Y renders exactly like maps rolled by k columns."""
    k = 5
    a = 2.0 * np.pi * k / synthetic.width
    rolled = shrm.SHRM([shrm.SHRMComponent(c.center, c.structure, c.F, c.P, c.terms, np.roll(c.maps, -k, axis=2),
                                           c.lobe) for c in synthetic.components])
    v = unit((0.3, 0.8, -0.5))
    r1, r2 = renderer_for(ctx, synthetic, "local"), renderer_for(ctx, rolled, "local")
    for mode in ("distant", "near"):
        rotated = r1.render(v, 48, mode=mode, env_rotation=a)
        shifted = r2.render(v, 48, mode=mode)
        np.testing.assert_allclose(rotated, shifted, atol=2e-3 * np.abs(shifted).max())
    want = shrm.render_sphere(rolled, v, 48)
    np.testing.assert_allclose(r1.render(v, 48, env_rotation=a), want, atol=2e-3 * np.abs(want).max())
    r1.release()
    r2.release()


@pytest.mark.parametrize("obj", ["bunny", "teapot"])
def test_meshes_render_inside_the_frame(ctx: Any, synthetic: shrm.SHRM, obj: str) -> None:
    r = renderer_for(ctx, synthetic, "local")
    img = r.render((0.0, 0.3, 1.0), 64, obj=obj, background=-1.0)
    covered = img[..., 0] != -1.0
    assert np.all(np.isfinite(img))
    assert 0.1 < covered.mean() < 0.75
    assert not covered[0].any() and not covered[-1].any() and not covered[:, 0].any() and not covered[:, -1].any()
    lo = min(float(c.maps.min()) for c in synthetic.components)
    assert img[covered].min() > -50.0 * abs(lo) - 1.0
    r.release()


def test_render_result_reads_the_service_layout(ctx: Any, synthetic: shrm.SHRM) -> None:
    """From manifest + coefficients.bin bytes (float16, (layers, S, 2S, 3)), as the server's render route does."""
    manifest, stack = gl_layout.layers_from_shrm(synthetic, frame="local")
    order = np.random.default_rng(3).permutation(len(manifest["layers"]))  # layers in any manifest order
    layers = [dict(manifest["layers"][i], index=j) for j, i in enumerate(order)]
    manifest = dict(manifest, layers=layers, files={"coefficients.bin": {
        "dtype": "float16", "byte_order": "little", "shape": [len(layers), synthetic.height, synthetic.width, 3]}})
    data = stack[order].astype("<f2").tobytes()
    v = unit((0.2, 0.1, 1.0))
    got = gl_render.render_result(manifest, data, v, 48, ctx=ctx)
    want = shrm.render_sphere(synthetic, v, 48)
    np.testing.assert_allclose(got, want, atol=2e-3 * np.abs(want).max())


def test_reflection_map_manifest_is_one_plain_layer(ctx: Any) -> None:
    """A worker 'reflection_map' result (P = 0, relight.prefilter's map itself) has weight 1, N- or R-centred."""
    rng = np.random.default_rng(5)
    m = smooth_maps(rng, 1, 4, 40)
    for center in ("R", "N"):
        manifest = {"representation": "reflection_map", "center": center, "height": 40, "width": 80,
                    "layers": [{"index": 0, "name": "", "p": 0, "q": 0}]}
        lay = gl_layout.from_manifest(manifest)
        r = gl_render.Renderer(lay, m, ctx=ctx)
        v = unit((0.0, 0.2, 1.0))
        got = r.render(v, 48)
        comp = shrm.SHRMComponent(center, "radial", 4, 0, [(0, 0)], m / shrm.Y00, {})
        want = shrm.render_sphere(shrm.SHRM([comp]), v, 48)
        np.testing.assert_allclose(got, want, atol=2e-3 * np.abs(want).max())
        r.release()


def sky(height: int) -> np.ndarray:
    """A smooth sky with a small bright sun (like tests/service's sample map), (H, 2H, 3)."""
    d = latlong_dirs(height, 2 * height)
    sun = unit((0.3, 0.8, 0.52))
    glow = np.exp(40.0 * (d @ sun - 1.0))
    return (0.5 + 0.4 * d[..., 1:2]) * np.array([0.6, 0.7, 1.0]) + 20.0 * glow[..., None]


@pytest.fixture(scope="module")
def materials() -> dict[str, shrm.SHRM]:
    """SHRMs of real BRDFs from relight.shrm.create_shrm (explicit small orders, so the test stays fast)."""
    from relight.brdf import models
    env = sky(32)
    lobes = {
        "phong": models.Phong(16.0),
        "lambert+microfacet": models.SumBRDF([models.Lambert(0.5), models.Microfacet(0.3)]),
        "kajiya-kay": models.KajiyaKay(8.0),
    }
    return {name: shrm.create_shrm(env, lobe, order=6, p_order=2, size=24) for name, lobe in lobes.items()}


@pytest.mark.parametrize("name", ["phong", "lambert+microfacet", "kajiya-kay"])
def test_real_brdfs_match_eq12_and_eq6(ctx: Any, materials: dict[str, shrm.SHRM], name: str) -> None:
    """create_shrm results (radial R and N, general R with P = 2, azimuthal T) for several views, both paths."""
    model = materials[name]
    r = renderer_for(ctx, model, "local")
    for view in VIEWS[:3]:
        v = unit(view)
        n, mask = shrm.sphere_geometry(v, 48)
        for mode in ("distant", "near"):
            _, tol = shade_cpu(model, "local", n[mask], np.broadcast_to(v, (mask.sum(), 3)),
                               distant=(mode == "distant"))
            got = r.render(v, 48, mode=mode)
            want = shrm.render_sphere(model, v, 48, local=(mode == "near"))
            err = np.abs(got[mask] - want[mask])
            assert np.all(err <= tol), f"{name} {mode} {view}: worst error / tolerance = {(err / tol).max():.3f}"
    r.release()
