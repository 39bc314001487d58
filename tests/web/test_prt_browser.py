"""The viewer's diffuse PRT in a real browser (Chromium + SwiftShader WebGL2) against a live relight server.

A mesh uploaded like any other (the sample bunny's OBJ), its visibility job (``diffuse_transfer``) requested from
the Shadows panel and followed to its end; then the canvas of the shadowed bunny for a fixed orthographic camera,
with the environment turned, against the CPU evaluation of the very float16 data the page downloaded:
``relight.mesh_render`` (one primary ray per pixel centre, barycentric interpolation of the per-vertex radiance
``albedo T . L``) with L the real SH of the float16 map the page shows (``relight.sh.project(weights="area")``,
the page's own quadrature) rotated by ``relight.gl.prt.rotate_lighting_y``, through the same display transform.

Tolerances: the page's lighting vector equals the CPU's to 1e-5 (float64 on both sides; the page's float32
uniforms round it to 6e-8). Pixels: 2 levels of 8 bits as the SHRM canvas test (test_viewer_browser.py: the same
float16 inputs, float32 arithmetic, the ACES curve's steepest part), mean below 0.2 level (measured 0.10: unlike
the sphere's per-pixel shading, Gouraud interpolation across triangles also sees the rasteriser's snapping of
vertex positions to its sub-pixel grid); pixels whose centre the rasteriser and the ray caster classify
differently (silhouettes, occlusion boundaries) may differ by more, at most 0.5 % of them (measured 0.16 %).
"""

from __future__ import annotations

from typing import Any

import httpx
import numpy as np
import pytest

from relight import sh
from relight.envmap import tonemap
from relight.gl.prt import rotate_lighting_y
from relight.mesh import geometry
from relight.mesh_render import interpolate, surface_samples
from relight.resources import mesh_dir
from tests.service.conftest import Server
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(600)]

VIEW = (0.3, 0.4, 1.0)
SIZE = 128
ROTATION = 0.7
ALBEDO = 0.8  # PrtObject.albedo


def canvas(page: Any, rotation: float, mode: str) -> np.ndarray:
    res = page.evaluate("""([view, size, rotation, mode]) => {
        const v = window.relight.viewer;
        window.relight.prt.setMode(mode);
        v.setFixedSize([size, size]);
        v.setFixedView({view, orthographic: true});
        v.setOptions({exposure: 0, tonemap: 'aces', background: false, rotation});
        v.render();
        const px = v.readPixels();
        return {w: px.width, h: px.height, data: Array.from(px.data)};
    }""", [list(VIEW), SIZE, rotation, mode])
    assert (res["w"], res["h"]) == (SIZE, SIZE)
    return np.asarray(res["data"], dtype=np.uint8).reshape(SIZE, SIZE, 4)[..., :3]


def test_shadowed_bunny_canvas_matches_the_cpu(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    envmap_id = upload_map(page, tmp_path)
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        r = http.post("/meshes?name=bunny.obj", content=(mesh_dir() / "bunny.obj").read_bytes())
        assert r.status_code in (200, 201), r.text
        info = r.json()
    page.evaluate("(id) => window.relight.refreshMeshes().then(() => window.relight.showMesh(id))", info["id"])
    page.fill("#prt-order", "3")
    page.fill("#prt-rays", "128")
    page.select_option("#prt-mesh", info["id"])
    page.click("#prt-compute")
    page.wait_for_function("window.relight.prtJobId && window.relight.prt.modes().includes('transfer')",
                           timeout=300_000)
    assert page.evaluate("document.getElementById('prt-progress').value") == 1
    job_id = page.evaluate("window.relight.prtJobId")
    screenshot(page, "prt_shadowed_bunny")

    got = canvas(page, ROTATION, "transfer")
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        manifest = http.get(f"/visibility/{job_id}").raise_for_status().json()
        mesh = geometry.from_bytes(http.get(f"/meshes/{info['id']}/geometry.bin").content, info["vertices"],
                                   info["faces"])
        tex = manifest["files"]["transfer.bin"]["texture"]
        bits = np.frombuffer(http.get(f"/visibility/{job_id}/files/transfer.bin").content, dtype="<f2")
        env = http.get(f"/envmaps/{envmap_id}/texture.bin?rows=256")
        shape = [int(x) for x in env.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(env.content, dtype="<f2").astype(np.float64).reshape(shape)
    transfer = bits.astype(np.float64).reshape(-1, 4)[: mesh.n_vertices * tex["texels_per_vertex"]]
    transfer = transfer.reshape(mesh.n_vertices, -1)[:, : tex["values_per_vertex"]]
    lighting = rotate_lighting_y(np.asarray(sh.to_real(sh.project(px16, 3, weights="area"), 3).T), ROTATION)
    page_light = np.asarray(page.evaluate("window.relight.prt.currentLighting()"))
    np.testing.assert_allclose(page_light, lighting, rtol=0, atol=1e-5 * np.abs(lighting).max())

    samples = surface_samples(mesh.normalised(), np.asarray(VIEW), SIZE, supersample=1)
    linear = samples.image(interpolate(samples, mesh, ALBEDO * transfer @ lighting))
    want = tonemap(linear, exposure=0.0, operator="aces")
    covered = samples.coverage == 1.0
    diff = np.abs(got.astype(int) - want.astype(int)).max(axis=2)
    assert covered.sum() > 0.2 * SIZE * SIZE
    edge = diff > 2  # measured: 9 of 5755 pixels, all on silhouettes or occlusion boundaries
    assert edge[covered].mean() < 0.005 and diff[covered & ~edge].mean() < 0.2, (edge[covered].sum(),
                                                                                diff[covered & ~edge].mean())
    assert (got[~covered].max(axis=1) > 0).mean() < 0.005  # the background is off: black around the mesh

    # rotating the environment re-lights the frame without a new job; the shadows darken the unshadowed image
    assert np.abs(canvas(page, 0.0, "transfer").astype(int) - got.astype(int))[covered].mean() > 1.0
    assert page.evaluate("window.relight.prtJobId") == job_id
    flat = canvas(page, ROTATION, "unshadowed")
    ao = canvas(page, ROTATION, "ao")
    assert flat[covered].mean() > got[covered].mean() and flat[covered].mean() > ao[covered].mean()


COMPARE_SIZE, COMPARE_SPP = 64, 64


def mesh_comparison(page: Any, mode: str) -> dict[str, Any]:
    """Click "Compare with Mitsuba" in ``mode``; the numbers and images the page computed."""
    page.evaluate("(mode) => { window.relight.prt.setMode(mode); window.relight.lastMeshComparison = null; }", mode)
    page.click("#prt-compare")
    page.wait_for_function("window.relight.lastMeshComparison !== null", timeout=300_000)
    res = page.evaluate("""() => {
        const c = window.relight.lastMeshComparison;
        return {mode: c.mode, rms: c.rms, noise: c.noise, pixels: c.pixels, view: c.view, rotation: c.rotation,
                ours: Array.from(c.ours), reference: Array.from(c.reference), mask: Array.from(c.mask)};
    }""")
    assert res["mode"] == mode
    n = COMPARE_SIZE
    res["ours"] = np.asarray(res["ours"], dtype=np.float64).reshape(n, n, 3)
    res["reference"] = np.asarray(res["reference"], dtype=np.float64).reshape(n, n, 3)
    res["mask"] = np.asarray(res["mask"], dtype=bool).reshape(n, n)
    return res


def test_viewer_compares_the_shadowed_bunny_with_mitsuba(page: Any, viewer_server: Server) -> None:
    """Issue 13 item 5: Mitsuba's image beside the viewer's, with a false-colour difference.

    The page's Mitsuba image is the service's ``GET /meshes/{id}/reference.exr``; it must be Mitsuba's render of
    the same mesh, map, rotation and camera: equal to ``relight.mitsuba_mesh`` called here (deterministic for a
    seed; the page's view and rotation reach the server with 6 decimals, which moves no pixel centre across an edge
    at 64 x 64: allowance 1e-3 relative RMS), and much farther from the viewer's image when the map is not turned.
    The page's error number is the project's metric recomputed here from the same arrays (float32 sums: 1e-5).
    The SH-transfer shadows must be closer to Mitsuba than unshadowed irradiance overall and on the pixels where
    Mitsuba's shadows change the unshadowed value by more than 10 % (city.exr: a low sun, the ears shadow the back).
    The noise the page shows beside the error is checked against two independent Mitsuba renders.
    """
    from relight import resources
    from relight.conventions import luminance
    from relight.envmap import read_envmap, resample_latlong
    from relight.mitsuba_mesh import render_mesh_mitsuba

    path = resources.package_dir(resources.DATA, "envmaps", "city.exr")
    upload_map(page, None, name="city.exr", data=path.read_bytes())
    with httpx.Client(base_url=viewer_server.url, timeout=120) as http:
        r = http.post("/meshes?name=bunny.obj", content=(mesh_dir() / "bunny.obj").read_bytes())
        assert r.status_code in (200, 201), r.text
        info = r.json()
        mesh = geometry.from_bytes(http.get(f"/meshes/{info['id']}/geometry.bin").content, info["vertices"],
                                   info["faces"])
    page.evaluate("(id) => window.relight.refreshMeshes().then(() => window.relight.showMesh(id))", info["id"])
    page.fill("#prt-order", "3")
    page.fill("#prt-rays", "256")
    page.select_option("#prt-mesh", info["id"])
    page.click("#prt-compute")
    page.wait_for_function("window.relight.prtJobId && window.relight.prt.modes().includes('transfer')",
                           timeout=300_000)
    page.fill("#compare-size", str(COMPARE_SIZE))
    page.fill("#prt-spp", str(COMPARE_SPP))
    page.evaluate("(r) => window.relight.viewer.setOptions({rotation: r})", ROTATION)

    shadowed = mesh_comparison(page, "transfer")
    screenshot(page, "prt_mitsuba_comparison")
    flat = mesh_comparison(page, "unshadowed")
    mask = shadowed["mask"]
    assert mask.sum() > 0.15 * COMPARE_SIZE**2 and np.array_equal(mask, flat["mask"])
    ref = shadowed["reference"]
    assert np.array_equal(ref, flat["reference"])  # the same request: the server's cached image

    # the page's Mitsuba image is Mitsuba's render of this scene
    env = read_envmap(path)
    px = np.asarray(resample_latlong(np.asarray(env.pixels, dtype=np.float64), 64), dtype=np.float32)
    view = np.asarray(shadowed["view"])

    def direct(rotation: float) -> np.ndarray:
        out = render_mesh_mitsuba(mesh.normalised(), px, view=view, size=COMPARE_SIZE, spp=COMPARE_SPP,
                                  albedo=ALBEDO, env_rotation=rotation)
        return np.asarray(luminance(out.rgb))

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.sqrt(np.sum((a - b)[mask] ** 2) / np.sum(b[mask] ** 2)))

    y_ref, y_ours, y_flat = luminance(ref), luminance(shadowed["ours"]), luminance(flat["ours"])
    assert rel(y_ref, direct(ROTATION)) < 1e-3
    assert rel(y_ours, direct(0.0)) > 2.0 * rel(y_ours, y_ref), (rel(y_ours, direct(0.0)), rel(y_ours, y_ref))

    # the page's numbers are the metric of these arrays
    assert abs(shadowed["rms"] - rel(y_ours, y_ref)) < 1e-5 and abs(flat["rms"] - rel(y_flat, y_ref)) < 1e-5
    # Mitsuba's relative noise, reported beside the error (from its moment integrator), against the spread of two
    # independent renders: sum (a - b)^2 / 2 estimates sum var over the 4096 pixels (a factor 1.5 allows the
    # heavy tail of a map with a sun)
    def render(seed: int) -> np.ndarray:
        return np.asarray(luminance(render_mesh_mitsuba(mesh.normalised(), px, view=view, size=COMPARE_SIZE,
                                                        spp=COMPARE_SPP, albedo=ALBEDO, env_rotation=ROTATION,
                                                        seed=seed).rgb))

    a, b = render(1), render(2)
    spread = float(np.sqrt(np.sum((a - b) ** 2) / 2 / np.sum(a**2)))
    assert spread / 1.5 < shadowed["noise"] < 1.5 * spread, (shadowed["noise"], spread)

    # shadows bring the viewer toward Mitsuba, above all where Mitsuba's shadows matter
    assert shadowed["rms"] < flat["rms"], (shadowed["rms"], flat["rms"])
    dark = mask & (np.abs(y_ref - y_flat) > 0.1 * y_flat)
    assert dark.sum() >= 20, dark.sum()
    on = {k: float(np.sqrt(np.mean((y - y_ref)[dark] ** 2))) for k, y in (("transfer", y_ours), ("flat", y_flat))}
    assert on["transfer"] < on["flat"], on
