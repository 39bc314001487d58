"""The viewer's In-out PRT panel in a real browser (Chromium + SwiftShader WebGL2) against a live relight server.

An ``inout_prt`` job for the bunny (Phong s = 8, 95 % of the energy, order 3, shadows) requested from the panel and
followed to its end; the canvas for a fixed orthographic camera, with the environment turned, against the CPU
evaluation (``relight.inout_prt.shade``) of the very float16 transport and float32 factor rows the page downloaded,
lit by the real SH of the page's float16 map (``relight.sh.project(weights="area")``, the page's own quadrature)
rotated by ``relight.gl.prt.rotate_lighting_y``, interpolated with the primary-ray barycentrics and tone-mapped.

Tolerances (same float16 inputs, float32 arithmetic, ACES; the shader's acos/atan add ~1e-4 relative:
test_gl_inout.py): every pixel within 2 levels of 8 bits plus its largest difference to a 4-neighbour in the CPU
image (the rasteriser's sub-pixel vertex snapping shifts the interpolation; this glossy image is steep), mean below 1
level. The K slider sums fewer
terms of the same data (the image changes, whole pairs); the charts come from factorization jobs: the hemisphere
K (99 %) of Phong s = 30 is the paper's 75 (Fig. 6), every chart is drawn with its points.
"""

from __future__ import annotations

from typing import Any

import httpx
import numpy as np
import pytest

from relight import sh
from relight.envmap import tonemap
from relight.gl.prt import rotate_lighting_y
from relight.inout_factors import InOutFactors
from relight.inout_prt import shade
from relight.mesh import geometry
from relight.mesh_render import interpolate, surface_samples
from relight.resources import mesh_dir
from relight.tangent_frames import azimuthal_frames
from relight.vertex_texture import unpack_float16
from tests.service.conftest import Server
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(900)]

VIEW = (0.3, 0.4, 1.0)
SIZE = 128
ROTATION = 0.7


def canvas(page: Any, rotation: float) -> np.ndarray:
    res = page.evaluate("""([view, size, rotation]) => {
        const v = window.relight.viewer;
        v.setFixedSize([size, size]);
        v.setFixedView({view, orthographic: true});
        v.setOptions({exposure: 0, tonemap: 'aces', background: false, rotation});
        v.render();
        const px = v.readPixels();
        return {w: px.width, h: px.height, data: Array.from(px.data)};
    }""", [list(VIEW), SIZE, rotation])
    assert (res["w"], res["h"]) == (SIZE, SIZE)
    return np.asarray(res["data"], dtype=np.uint8).reshape(SIZE, SIZE, 4)[..., :3]


def test_inout_bunny_canvas_matches_the_cpu_and_charts(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    envmap_id = upload_map(page, tmp_path)
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        r = http.post("/meshes?name=bunny.obj", content=(mesh_dir() / "bunny.obj").read_bytes())
        assert r.status_code in (200, 201), r.text
        info = r.json()
    page.evaluate("() => window.relight.refreshInOut()")
    page.select_option("#inout-mesh", info["id"])
    page.fill("#inout-brdf", "phong:s=8")
    page.fill("#inout-energy", "0.95")
    page.fill("#inout-order", "3")
    page.fill("#inout-rays", "1024")
    page.click("#inout-compute")
    page.wait_for_function("window.relight.inoutJobId && window.relight.inout", timeout=300_000)
    job_id = page.evaluate("window.relight.inoutJobId")
    screenshot(page, "inout_bunny")

    got = canvas(page, ROTATION)
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        res = http.get(f"/jobs/{job_id}/result").raise_for_status().json()
        mesh = geometry.from_bytes(http.get(f"/meshes/{info['id']}/geometry.bin").content, info["vertices"],
                                   info["faces"])
        lay = res["transport_texture"]
        bits = np.frombuffer(http.get(f"/jobs/{job_id}/files/transport.bin").content, dtype="<f2")
        rows = np.frombuffer(http.get(f"/jobs/{job_id}/files/factors.bin").content, dtype="<f4")
        env = http.get(f"/envmaps/{envmap_id}/texture.bin?rows=256")
        shape = [int(x) for x in env.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(env.content, dtype="<f2").astype(np.float64).reshape(shape)
    k = res["terms"]
    transport = unpack_float16(bits.reshape(lay["height"], lay["width"], 4), lay).astype(np.float64)
    rows = rows.reshape(k, -1).astype(np.float64)
    n_tab = rows.shape[1] - 2
    f = InOutFactors(np.ones(k), rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64), np.zeros((k, n_tab)),
                     rows[:, 2:], np.linspace(0.0, 0.5 * np.pi, n_tab), True, res["captured"], "page")
    lighting = rotate_lighting_y(np.asarray(sh.to_real(sh.project(px16, 3, weights="area"), 3).T), ROTATION)
    page_light = np.asarray(page.evaluate("window.relight.inout.currentLighting()"))
    np.testing.assert_allclose(page_light, lighting, rtol=0, atol=1e-5 * np.abs(lighting).max())

    v = np.asarray(VIEW) / np.linalg.norm(VIEW)
    per_vertex = shade(f, transport, lighting, azimuthal_frames(mesh.normals), v)
    samples = surface_samples(mesh.normalised(), np.asarray(VIEW), SIZE, supersample=1)
    want = tonemap(samples.image(interpolate(samples, mesh, per_vertex)), exposure=0.0, operator="aces")
    covered = samples.coverage == 1.0
    diff = np.abs(got.astype(int) - want.astype(int)).max(axis=2)
    assert covered.sum() > 0.2 * SIZE * SIZE
    # the rasteriser snaps vertices to its sub-pixel grid, shifting the Gouraud interpolation by a fraction of a
    # pixel: a pixel may differ by its largest difference to a 4-neighbour of the CPU image (measured: none beyond
    # that + 2 levels; 5 % of the pixels of this glossy, high-contrast image are beyond 2 levels alone)
    near = np.zeros(diff.shape)
    for axis in (0, 1):
        for step in (1, -1):
            near = np.maximum(near, np.abs(want.astype(int) - np.roll(want.astype(int), step, axis=axis)).max(axis=2))
    assert np.all(diff[covered] <= 2 + near[covered]), int((diff > 2 + near)[covered].sum())
    assert diff[covered].mean() < 1.0, diff[covered].mean()  # measured 0.6
    # a new lighting is a new frame, not a new job; fewer terms (the slider) change the image
    assert np.abs(canvas(page, 0.0).astype(int) - got.astype(int))[covered].mean() > 1.0
    used = page.evaluate("""() => { const s = document.getElementById('inout-terms'); s.value = '1';
        s.dispatchEvent(new Event('input')); return window.relight.inout.terms; }""")
    assert used == 1 and "K = 1 of" in page.inner_text("#inout-terms-label")
    assert np.abs(canvas(page, ROTATION).astype(int) - got.astype(int))[covered].mean() > 1.0

    page.click("#inout-charts-show")
    page.wait_for_function("window.relight.inoutCharts || document.getElementById('inout-error').textContent",
                           timeout=300_000)
    assert not page.inner_text("#inout-error"), page.inner_text("#inout-error")
    charts = page.evaluate("window.relight.inoutCharts")
    assert [p["hemisphere"] for p in charts["phong"] if p["s"] == 30] == [75]
    for chart, cls in (("chart-phong", "measured-hemisphere"), ("chart-sigma", "sigma"), ("chart-lstar", "ts")):
        assert page.evaluate(f"document.querySelectorAll('#{chart} .{cls}').length") > 0, chart
    assert page.evaluate("document.querySelectorAll('#chart-phong .current').length") == 1  # phong:s=8 marked
    assert page.evaluate("document.querySelectorAll('#chart-sigma .f-l').length") == 1  # F_l of the radial lobe
