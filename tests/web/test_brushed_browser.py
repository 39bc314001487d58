"""The brushed-metal panel (web/src/brushed_panel.js; seed 003 §4-§6) in a real browser (Debian Chromium, WebGL2 on
SwiftShader), end to end against the viewer's server: an ``sh_table`` job (anisotropic Ashikhmin–Shirley) and a
``shadow_matrix`` visibility job for the bunny, the environment turned about +Y plus two circular area lights,
Hann-windowed, view and lighting both set by the test. Compared with the CPU on the same data:

* the page's world lighting = ``relight.sh_render`` (the float16 map the page shows projected with exact pixel
  solid angles, ``rotate_lighting`` with the world rotation matrix, ``cap_light``, ``window_lighting``): float64 on
  both sides, sums in another order: 1e-9 of the largest coefficient; the window cost printed on the page is
  ``window_lighting``'s;
* the tangent field = ``relight.tangent_frames.projected_frames`` of the geometry's normals (float32 storage: 1e-6);
* every mode's per-vertex radiance (general, fixed lighting, fixed view: ``relight.sh_render.shade``; PRT shadows:
  ``relight.sh_prt.shade_prt`` with ``folded_transfer`` of the job's float16 world matrices) on the job's float16
  table. Tolerance per vertex as tests/web/test_sh_table_browser.py: the fixed-point sub-texel weight (2^-9 of the
  change over the 2 x 2 footprint) times |L_local|, the float32 rotation error (1e-5 per band, the issue's GPU
  target) times the band norms, float32 sums (1e-6 of sum |L_local| |c|); x 1.5;
* the shadows are visible in the numbers (transfer differs from the unshadowed general mode by far more than the
  tolerance); the frame time and Table 1's ratios are shown for all four modes; the tangent overlay draws.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import numpy as np

from relight import sh
from relight.brdf.spec import parse_frame_brdf
from relight.indexing import full_block
from relight.mesh import geometry
from relight.resources import mesh_dir
from relight.sh_prt import folded_transfer, shade_prt
from relight.sh_render import cap_light, rotate_lighting, shade, window_lighting
from relight.sh_rotation import local_rotations, rotate_coefficients
from relight.sh_table import SHTable, build_table
from relight.tangent_frames import azimuthal_frames, projected_frames
from relight.view_maps import view_to_texel
from tests.service.conftest import Server
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

ROT_TOL, FILTER_STEP, SLACK = 1e-5, 2.0**-9, 1.5
BRDF = "ashikhmin-shirley:nu=24,nv=8,rs=0.6,rd=0.05"
ORDER, RES = 4, 16
DIRECTION = (1.0, 0.3, 0.2)
ROTATION, VIEW_AZ, VIEW_EL = 0.7, 0.9, 0.3
CAPS = [  # (on, azimuth deg, elevation deg, solid angle, colour hex, radiance)
    (True, 40, 35, 0.3, "#ffd9a0", 8.0), (True, -120, 10, 1.0, "#a0c8ff", 3.0)]


def set_controls(page: Any) -> None:
    page.uncheck("#brushed-spin-light")
    page.uncheck("#brushed-spin-view")
    page.select_option("#brushed-window", "hann")
    for k, (on, az, el, sr, colour, radiance) in enumerate(CAPS):
        (page.check if on else page.uncheck)(f"#brushed-cap{k}-on")
        for name, value in (("az", az), ("el", el), ("sr", sr), ("colour", colour), ("radiance", radiance)):
            page.fill(f"#brushed-cap{k}-{name}", str(value))


def cpu_lighting(px16: np.ndarray) -> tuple[np.ndarray, float]:
    env = np.asarray(sh.to_real(sh.project(px16, ORDER, weights="area"), ORDER).T)
    c, s = np.cos(ROTATION), np.sin(ROTATION)
    # the viewer looks the map up at rotate_y(d, -a) = R^-1 d with R = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    light = rotate_lighting(env, [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    for on, az, el, sr, colour, radiance in CAPS:
        if on:
            a, e = np.radians(az), np.radians(el)
            rgb = radiance * np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)]) / 255.0
            light = light + cap_light([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)], sr, rgb, ORDER)
    return window_lighting(light, "hann")


def tolerance(table: SHTable, local: np.ndarray, vl: np.ndarray) -> np.ndarray:
    coef = table.lookup(vl, exact_azimuth=False)
    x, y = view_to_texel(table.layout, table.resolution, vl)
    x0 = np.clip(np.floor(x).astype(int), 0, table.resolution - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, table.resolution - 2)
    quad = np.stack([table.coefficients[y0 + i, x0 + j] for i in (0, 1) for j in (0, 1)])
    band = sum(np.linalg.norm(local[:, full_block(l)], axis=1) * np.linalg.norm(coef[:, full_block(l)], axis=1)
               for l in range(table.order + 1))
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", np.abs(local), quad.max(0) - quad.min(0))
                   + ROT_TOL * band + 1e-6 * np.einsum("nic,nic->nc", np.abs(local), np.abs(coef)))
    return np.asarray(np.where((vl[:, 2] > 0)[:, None], tol, 0.0) + 1e-6)


def test_brushed_bunny_all_modes_and_shadows_match_cpu(page: Any, viewer_server: Server, tmp_path: Path) -> None:
    envmap_id = upload_map(page, tmp_path)
    # the single test worker may still be calibrating the cost model (a minute under load): a patient upload
    with httpx.Client(base_url=viewer_server.url, timeout=300) as http:
        r = http.post("/meshes?name=bunny.obj", content=(mesh_dir() / "bunny.obj").read_bytes())
        assert r.status_code in (200, 201), r.text
        info = r.json()
    page.evaluate("() => window.relight.brushed.refreshObjects()")
    page.select_option("#brushed-object", info["id"])
    page.fill("#brushed-brdf", BRDF)
    page.select_option("#brushed-order", str(ORDER))
    page.fill("#brushed-resolution", str(RES))
    page.fill("#brushed-direction", ",".join(map(str, DIRECTION)))
    page.select_option("#brushed-prt", "shadows")
    page.fill("#brushed-rays", "64")
    set_controls(page)
    page.click("#brushed-load")
    page.wait_for_function("window.relight.brushed.ready === true || "
                           "document.getElementById('brushed-error').textContent !== ''", timeout=300_000)
    assert page.evaluate("document.getElementById('brushed-error').textContent") == ""
    got = page.evaluate("""(a) => {
      const b = window.relight.brushed;
      b.rotation = a.rotation; b.viewAz = a.az; b.viewEl = a.el;
      const out = { light: Array.from(b.lighting()), view: b.view(), cost: b.windowCost,
        tangents: Array.from(b.object.tangents), normals: Array.from(b.object.normals), table: b.tableJob,
        transfer: b.transferJob, mode: b.mode, probes: {} };
      for (const m of ['general', 'fixed-light', 'fixed-view', 'transfer']) {
        out.probes[m] = Array.from(b.probe(m));
      }
      return out;
    }""", {"rotation": ROTATION, "az": VIEW_AZ, "el": VIEW_EL})
    assert got["mode"] == "transfer" and got["transfer"]
    page.wait_for_function("document.getElementById('brushed-frame').textContent.includes('ms per frame')")
    screenshot(page, "brushed_bunny_shadows")

    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        env = http.get(f"/envmaps/{envmap_id}/texture.bin?rows=256")
        shape = [int(x) for x in env.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(env.content, dtype="<f2").astype(np.float64).reshape(shape)
        raw = np.frombuffer(http.get(f"/jobs/{got['table']}/files/table.bin").content, dtype="<f2")
        man = http.get(f"/visibility/{got['transfer']}").raise_for_status().json()
        bits = np.frombuffer(http.get(f"/visibility/{got['transfer']}/files/shadow_matrix.bin").content, "<f2")
        mesh = geometry.from_bytes(http.get(f"/meshes/{info['id']}/geometry.bin").content, info["vertices"],
                                   info["faces"])

    light, cost = cpu_lighting(px16)
    page_light = np.asarray(got["light"]).reshape(-1, 3)
    assert np.abs(page_light - light).max() <= 1e-9 * np.abs(light).max(), np.abs(page_light - light).max()
    assert abs(got["cost"] - cost) <= 1e-9 and cost > 0.01
    assert f"{100 * cost:.3g} %" in page.evaluate("document.getElementById('brushed-window-cost').textContent")

    normals = np.asarray(got["normals"]).reshape(-1, 3)
    assert np.array_equal(normals, mesh.normals.astype(np.float32).astype(np.float64))
    frames = projected_frames(normals, DIRECTION)
    assert np.abs(np.asarray(got["tangents"]).reshape(-1, 4)[:, :3] - frames[:, 0]).max() < 1e-6

    n = (ORDER + 1) ** 2
    reference = build_table(parse_frame_brdf(BRDF), order=ORDER, resolution=RES)  # views and valid of the map
    same = SHTable(raw.astype(np.float64).reshape(n, RES, RES, 1).transpose(1, 2, 0, 3), reference.views,
                   reference.valid, ORDER, "parabolic", {})
    view = np.asarray(got["view"])
    vl = np.einsum("nij,j->ni", frames, view)
    local = rotate_coefficients(local_rotations(frames, ORDER), light[None])
    tol = tolerance(same, local, vl)
    cpu = shade(same, light, frames, view, exact_azimuth=False)
    assert np.abs(cpu).max() > 0.1 and (vl[:, 2] > 0).sum() > 500
    for mode in ("general", "fixed-light", "fixed-view"):
        gpu = np.asarray(got["probes"][mode]).reshape(-1, 3)
        assert np.all(np.abs(gpu - cpu) <= tol), (mode, float(np.abs(gpu - cpu).max()))

    tex = man["files"]["shadow_matrix.bin"]["texture"]
    world = bits.astype(np.float64).reshape(-1, 4)[: mesh.n_vertices * tex["texels_per_vertex"]]
    world = world.reshape(mesh.n_vertices, -1)[:, : n * n].reshape(-1, n, n)
    folded = folded_transfer(frames, world, ORDER)
    shadowed = shade_prt(same, light, frames, view, folded, exact_azimuth=False)
    t_local = np.einsum("vij,jc->vic", folded, light)
    t_tol = tolerance(same, t_local, vl)
    gpu = np.asarray(got["probes"]["transfer"]).reshape(-1, 3)
    assert np.all(np.abs(gpu - shadowed) <= t_tol), float(np.abs(gpu - shadowed).max())
    assert np.abs(shadowed - cpu).max() > 20 * t_tol.max()  # the shadows are in what the page draws

    # Table 1: every mode timed in one run, with its ratio to the general mode
    table1 = page.evaluate("window.relight.brushed.timeModes(3)")
    assert set(table1["ms"]) == {"general", "fixed-light", "fixed-view", "transfer"}
    assert all(v > 0 for v in table1["ms"].values()) and table1["vertices"] == mesh.n_vertices
    assert "fixed-view" in page.evaluate("document.getElementById('brushed-table1').textContent")

    # the tangent overlay draws green segments over the object
    def green(overlay: bool) -> int:
        return int(page.evaluate("""(on) => {
          const b = window.relight.brushed;
          document.getElementById('brushed-tangents').checked = on;
          b.busy = true; b.frame('general');
          const gl = b.gl; const px = new Uint8Array(4 * 320 * 320);
          gl.readPixels(0, 0, 320, 320, gl.RGBA, gl.UNSIGNED_BYTE, px);
          b.busy = false;
          let k = 0;
          for (let i = 0; i < px.length; i += 4) { if (px[i + 1] > 200 && px[i] < 60 && px[i + 2] < 130) k += 1; }
          return k;
        }""", overlay))
    assert green(True) > 200 + green(False)

    # shadows off: the mode goes back to general
    page.select_option("#brushed-prt", "off")
    page.click("#brushed-load")
    page.wait_for_function("window.relight.brushed.transferJob === null && window.relight.brushed.mode === "
                           "'general'", timeout=120_000)


def test_order_window_grid_draws_the_cpu_result(page: Any, viewer_server: Server, tmp_path: Path) -> None:
    """Fig. 6's grid (web/src/sh_order_grid.js): two materials x (F = 2, 4, 6, 8, 8 with Hann); every cell's
    per-vertex radiance through the shader that drew it equals ``shade`` on the first (F+1)^2 layers of the job's
    float16 F = 8 table with the lighting truncated to F (and windowed in the last column); tolerance as above."""
    envmap_id = upload_map(page, tmp_path)
    materials = ["ashikhmin-shirley:nu=12,nv=4,rs=0.05,rd=0", "ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0"]
    page.fill("#order-grid-materials", "\n".join(materials))
    page.fill("#order-grid-resolution", "12")
    page.click("#order-grid-run")
    page.wait_for_function("window.relight.orderGrid.ready === true || "
                           "document.getElementById('order-grid-error').textContent !== ''", timeout=300_000)
    assert page.evaluate("document.getElementById('order-grid-error').textContent") == ""
    got = page.evaluate("""() => {
      const g = window.relight.orderGrid;
      return { lighting: Array.from(g.lighting), costs: g.costs, normals: Array.from(g.sphere.normals),
        tangents: Array.from(g.sphere.tangents), view: g.view, canvases: document.querySelectorAll(
          '#order-grid canvas').length, text: document.getElementById('order-grid').textContent,
        cells: g.cells.map((c, k) => ({ order: c.order, window: c.window, job: c.job, row: c.row,
          probe: Array.from(g.probe(k)) })) };
    }""")
    screenshot(page, "order_window_grid")
    assert got["canvases"] == 5 + 2 * 5 and len(got["cells"]) == 10
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        env = http.get(f"/envmaps/{envmap_id}/texture.bin?rows=256")
        shape = [int(x) for x in env.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(env.content, dtype="<f2").astype(np.float64).reshape(shape)
        tables = {c["job"]: np.frombuffer(http.get(f"/jobs/{c['job']}/files/table.bin").content, "<f2")
                  for c in got["cells"]}
    full = np.asarray(sh.to_real(sh.project(px16, 8, weights="area"), 8).T)
    assert np.abs(np.asarray(got["lighting"]).reshape(-1, 3) - full).max() <= 1e-9 * np.abs(full).max()
    hann_cost = window_lighting(full, "hann")[1]
    assert abs(got["costs"][4] - hann_cost) <= 1e-9 and got["costs"][:4] == [0, 0, 0, 0]
    assert f"cost {100 * hann_cost:.3g} %" in got["text"]

    normals = np.asarray(got["normals"]).reshape(-1, 3)
    frames = azimuthal_frames(normals)
    assert np.abs(np.asarray(got["tangents"]).reshape(-1, 4)[:, :3] - frames[:, 0]).max() < 1e-6
    view = np.asarray(got["view"], dtype=np.float64)
    vl = np.einsum("nij,j->ni", frames, view)
    res = 12
    maps = build_table(parse_frame_brdf(materials[0]), order=2, resolution=res)  # the map's views and valid
    renders = {}
    for cell in got["cells"]:
        order, n = cell["order"], (cell["order"] + 1) ** 2
        c8 = tables[cell["job"]].astype(np.float64).reshape(81, res, res, 1).transpose(1, 2, 0, 3)
        same = SHTable(c8[:, :, :n], maps.views, maps.valid, order, "parabolic", {})
        light, _ = window_lighting(full[:n], cell["window"])
        local = rotate_coefficients(local_rotations(frames, order), light[None])
        cpu = shade(same, light, frames, view, exact_azimuth=False)
        gpu = np.asarray(cell["probe"]).reshape(-1, 3)
        tol = tolerance(same, local, vl)
        assert np.all(np.abs(gpu - cpu) <= tol), (cell["row"], order, float(np.abs(gpu - cpu).max()))
        renders[(cell["row"], order, cell["window"])] = cpu
    # the columns are different truncations (the windowed one too), not one image five times
    for r in (0, 1):
        top = renders[(r, 8, "none")]
        for other in (renders[(r, 2, "none")], renders[(r, 8, "hann")]):
            assert np.abs(top - other).max() > 0.05 * np.abs(top).max()


def test_interreflections_on_the_teapot_match_cpu(page: Any, viewer_server: Server, tmp_path: Path) -> None:
    """Shadows + interreflections (an ``sh_transfer`` job: ``relight.sh_prt_bounce.vertex_transfer`` with the BRDF
    fixed, one bounce) on the teapot: the page's transfer-mode radiance equals ``shade_prt`` with the job's float16
    world matrices folded on the CPU (tolerance as above), and differs from the shadow-only matrices of the same
    job by far more than the tolerance: the bounce is in what the page draws. Bad requests are 422s naming the
    field."""
    upload_map(page, tmp_path)
    brdf = "ashikhmin-shirley:nu=24,nv=8,rs=0.6,rd=0.1"
    with httpx.Client(base_url=viewer_server.url, timeout=300) as http:
        r = http.post("/meshes?name=teapot.obj", content=(mesh_dir() / "teapot.obj").read_bytes())
        assert r.status_code in (200, 201), r.text
        info = r.json()
        base = {"mesh": info["id"], "brdf": brdf, "order": 2, "resolution": 8}
        for change, field in (({"bounces": 9}, "bounces"), ({"tangent": {"kind": "project"}}, "direction"),
                              ({"brdf": "ashikhmin-shirley:nu=-1,nv=8"}, "nu")):
            bad = http.post("/jobs", json={"kind": "sh_transfer", "request": {**base, **change}})
            assert bad.status_code == 422 and field in bad.text, (change, bad.text)
    page.evaluate("() => window.relight.brushed.refreshObjects()")
    page.select_option("#brushed-object", info["id"])
    page.fill("#brushed-brdf", brdf)
    page.select_option("#brushed-order", str(ORDER))
    page.fill("#brushed-resolution", str(RES))
    page.fill("#brushed-direction", ",".join(map(str, DIRECTION)))
    page.select_option("#brushed-prt", "interreflections")
    page.fill("#brushed-bounces", "1")
    page.fill("#brushed-rays", "64")
    set_controls(page)
    page.click("#brushed-load")
    page.wait_for_function("window.relight.brushed.ready === true || "
                           "document.getElementById('brushed-error').textContent !== ''", timeout=300_000)
    assert page.evaluate("document.getElementById('brushed-error').textContent") == ""
    got = page.evaluate("""(a) => {
      const b = window.relight.brushed;
      b.rotation = a.rotation; b.viewAz = a.az; b.viewEl = a.el;
      return { light: Array.from(b.lighting()), view: b.view(), normals: Array.from(b.object.normals),
        transfer: b.transferJob, table: b.tableJob, probe: Array.from(b.probe('transfer')) };
    }""", {"rotation": ROTATION, "az": VIEW_AZ, "el": VIEW_EL})
    screenshot(page, "brushed_teapot_interreflections")
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        result = http.get(f"/jobs/{got['transfer']}/result").raise_for_status().json()
        raw = np.frombuffer(http.get(f"/jobs/{got['table']}/files/table.bin").content, dtype="<f2")
        mats = {}
        for name in ("direct.bin", "transfer.bin"):
            tex = result["textures"][name]
            bits = np.frombuffer(http.get(f"/jobs/{got['transfer']}/files/{name}").content, "<f2")
            flat = bits.astype(np.float64).reshape(-1, 4)[: tex["vertices"] * tex["texels_per_vertex"]]
            mats[name] = flat.reshape(tex["vertices"], -1)[:, : tex["values_per_vertex"]]
    assert result["bounces"] == 1 and result["vertices"] == info["vertices"]
    n = (ORDER + 1) ** 2
    normals = np.asarray(got["normals"]).reshape(-1, 3)
    frames = projected_frames(normals, DIRECTION)
    light = np.asarray(got["light"]).reshape(-1, 3)
    view = np.asarray(got["view"])
    reference = build_table(parse_frame_brdf(brdf), order=ORDER, resolution=RES)
    same = SHTable(raw.astype(np.float64).reshape(n, RES, RES, 1).transpose(1, 2, 0, 3), reference.views,
                   reference.valid, ORDER, "parabolic", {})
    vl = np.einsum("nij,j->ni", frames, view)
    folded = folded_transfer(frames, mats["transfer.bin"].reshape(-1, n, n), ORDER)
    cpu = shade_prt(same, light, frames, view, folded, exact_azimuth=False)
    tol = tolerance(same, np.einsum("vij,jc->vic", folded, light), vl)
    gpu = np.asarray(got["probe"]).reshape(-1, 3)
    assert np.abs(cpu).max() > 0.05 and (vl[:, 2] > 0).sum() > 100
    assert np.all(np.abs(gpu - cpu) <= tol), float(np.abs(gpu - cpu).max())
    direct = shade_prt(same, light, frames, view, folded_transfer(frames, mats["direct.bin"].reshape(-1, n, n), ORDER),
                       exact_azimuth=False)
    assert np.abs(direct - cpu).max() > 10 * tol.max()
