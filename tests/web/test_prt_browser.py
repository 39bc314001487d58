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
