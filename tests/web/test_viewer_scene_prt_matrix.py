"""A scene's shadowed anisotropic object drawn by seed 003's PRT (SH table on transferred lighting, Kautz, Sloan &
Snyder 2002 §5) in the viewer's 3-D view (issue 16 item 4: "the viewer draws the whole scene, each object with its
chosen representation"), in a real browser (Chromium + SwiftShader) against a live server and real workers.

The scene: a brushed bunny (Ashikhmin-Shirley nu = 24, nv = 8, brushed along x: ``tangent`` project [1, 0, 0]) with
exact shadows, which the planner gives ``prt_matrix`` (the only option for an anisotropic lobe with shadows): a
shared ``sh_table`` job and a shared ``shadow_matrix`` job on the bunny. The worker stores the table's viewer form
(``P.table.bin``, ``P.table.json``) and the matrices' (``P.shadow_matrix.bin`` in the ``visibility`` kind's
shadow_matrix.bin layout, ``P.geometry.bin``, ``P.prt_matrix.json``: ``relight.worker.scene_prt.add_matrix_texture``);
the page draws them with ``web/src/scene_table_parts.js`` PrtMatrixPart (sh_table.vert.glsl, 'transfer' mode with
TRANSFER_WORLD). Checks:

* the page's tangent field is the object's (``relight.tangent_frames.projected_frames`` of the job mesh's normals,
  away from the field's singular points) and its lighting is the environment's SH projection turned by the viewer's
  rotation;
* the drawn linear radiance against ``relight.sh_prt.shade_prt`` (with ``folded_transfer``) of the very float16
  table and float16 matrices the page downloaded, per vertex of the job's mesh, interpolated barycentrically
  (``relight.mesh_render``: the rasteriser's Gouraud interpolation), within the bound derived at
  :func:`vertex_tolerance` plus the rasteriser's sub-pixel vertex placement (:func:`triangle_gradient`), on
  every pixel both cover but 0.5 %;
* the shadows are drawn: the same table without the transfer (``relight.sh_render.shade``) differs by far more.
"""

from __future__ import annotations

import json
from typing import Any

import httpx
import numpy as np
import pytest

from relight import sh
from relight.gl.prt import rotate_lighting_y
from relight.indexing import full_block
from relight.mesh import geometry
from relight.mesh_render import camera_up, interpolate, surface_samples
from relight.sh_prt import folded_transfer, shade_prt
from relight.sh_render import shade
from relight.sh_table import SHTable
from relight.tangent_frames import projected_frames
from relight.vertex_texture import unpack_float16
from relight.view_maps import view_to_texel
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map
from tests.web.test_viewer_scene_parts import ROTATION, SIZE, VIEW, part_linear, scene_files

pytestmark = [pytest.mark.timeout(900)]

#: tests/web/test_sh_table_browser.py's GPU error model: the SH rotation in float32 to 1e-5 per band (the issue's GPU
#: target, measured there), the fixed-point bilinear weights of the table lookup to 2^-9, a slack of 1.5
ROT_TOL, FILTER_STEP, SLACK = 1e-5, 2.0**-9, 1.5
#: float32 unit round-off: the GPU's products and sums (the CPU's float64 rounding is far below it)
F32 = 2.0**-24
BRUSHED = "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0"
DIRECTION = (1.0, 0.0, 0.0)


def vertex_tolerance(table: SHTable, world: np.ndarray, light: np.ndarray, frames: np.ndarray,
                     view: np.ndarray) -> np.ndarray:
    """A bound (N, 3) of |GPU - CPU| per vertex for the same float16 table and matrices.

    Both sides read the same float16 bytes (the CPU decodes exactly the values the GPU samples), so the float16
    rounding of the table and of the matrices is common to both and does not enter; the comparison is on the
    float32 linear target (``renderPartLinear``), so the canvas's 8-bit quantisation (1/255 of the tone-mapped
    range) does not enter either. What differs is the GPU's arithmetic:

    * ``T_p L'`` in float32, n terms per row: each entry within ``n 2^-24 sum_j |T_ij| |L_j|`` (the dot-product
      bound, Higham 2002 §3.1), carried through the band rotation (orthogonal: a band's error norm is kept) and
      the table's coefficients: ``sum_l ||e_l|| ||c_l||``;
    * the band rotation of ``T_p L'`` into the vertex's frame (sh_rotation.glsl) to ``ROT_TOL`` per band:
      ``ROT_TOL sum_l ||L_loc,l|| ||c_l||``;
    * the table's bilinear weights quantised to ``FILTER_STEP``: ``FILTER_STEP sum_i |L_loc,i| (max - min of
      c_i over the 2 x 2 footprint)``;
    * the final dot product's float32 sums: ``1e-6 sum_i |L_loc,i| |c_i|`` (n <= 25 terms: n 2^-24 < 1.5e-6 is
      covered with the slack);

    times ``SLACK``; 0 where the vertex faces away (both sides write 0 there), plus 1e-6 absolute."""
    order = table.order
    n = (order + 1) ** 2
    vl = np.einsum("nij,j->ni", frames, view)
    folded = folded_transfer(frames, world, order)
    local = np.einsum("vij,jc->vic", folded, light[:n])
    coef = table.lookup(vl, exact_azimuth=False)
    x, y = view_to_texel(table.layout, table.resolution, vl)
    x0 = np.clip(np.floor(x).astype(int), 0, table.resolution - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, table.resolution - 2)
    quad = np.stack([table.coefficients[y0 + i, x0 + j] for i in (0, 1) for j in (0, 1)])
    product = n * F32 * np.einsum("vij,jc->vic", np.abs(world[:, :n, :n]), np.abs(light[:n]))
    bands = [full_block(l) for l in range(order + 1)]
    cnorm = [np.linalg.norm(coef[:, b], axis=1) for b in bands]
    rotation = sum(np.linalg.norm(local[:, b], axis=1) * c for b, c in zip(bands, cnorm, strict=True))
    products = sum(np.linalg.norm(product[:, b], axis=1) * c for b, c in zip(bands, cnorm, strict=True))
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", np.abs(local), quad.max(0) - quad.min(0))
                   + ROT_TOL * rotation + products + 1e-6 * np.einsum("nic,nic->nc", np.abs(local), np.abs(coef)))
    return np.asarray(np.where((vl[:, 2] > 0)[:, None], tol, 0.0) + 1e-6)


def triangle_gradient(samples: Any, positions: np.ndarray, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per pixel (size, size, C): |grad| in pixels of the hit triangle's linear interpolant of the per-vertex
    ``values`` on the screen of ``relight.mesh_render.surface_samples`` (supersample 1); inf on an edge-on
    triangle (its interpolant has no bounded gradient on the screen), 0 where nothing is hit."""
    size = samples.size
    v = np.asarray(VIEW, dtype=np.float64) / np.linalg.norm(VIEW)
    up = camera_up(v)
    right = np.cross(up, v)
    right /= np.linalg.norm(right)
    up_img = np.cross(v, right)
    xy = np.stack([(positions @ right + 1.0) * size / 2, (1.0 - positions @ up_img) * size / 2], axis=1)
    prim = samples.prim.reshape(-1)
    hit = prim >= 0
    tri = faces[prim[hit]]
    edges = np.stack([xy[tri[:, 1]] - xy[tri[:, 0]], xy[tri[:, 2]] - xy[tri[:, 0]]], axis=1)  # (H, 2, 2)
    dv = np.stack([values[tri[:, 1]] - values[tri[:, 0]], values[tri[:, 2]] - values[tri[:, 0]]], axis=1)
    det = np.linalg.det(edges)
    flat = np.abs(det) < 1e-9
    edges[flat] = np.eye(2)
    grad = np.linalg.norm(np.linalg.solve(edges, dv), axis=1)  # (H, C)
    grad[flat] = np.inf
    out = np.zeros((prim.size, values.shape[1]))
    out[hit] = grad
    return out.reshape(size, size, -1)


def test_scene_with_prt_matrix(page: Any, tmp_path: Any, viewer_server: Any) -> None:
    env = upload_map(page, tmp_path, name="scene-prt-matrix-sky.exr")
    scene = {"name": "brushed-bunny", "environment": env, "epsilon": 0.2, "size": 16, "objects": [
        {"name": "brushed", "shape": "bunny", "size": 1, "distance": 4, "material": BRUSHED, "view": [0, 0, 1],
         "tangent": {"kind": "project", "direction": list(DIRECTION)}, "shadows": "exact"}]}
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function("window.relight.sceneShown === window.relight.scene?.id"
                           " || document.getElementById('scene-error').textContent", timeout=600_000)
    assert page.inner_text("#scene-error") == ""
    assert page.evaluate("window.relight.sceneErrors") == []
    pub = page.evaluate("window.relight.scene")
    assert [r["representation"] for r in pub["plan"]["objects"][0]["representations"]] == ["prt_matrix"]
    parts = page.evaluate("() => window.relight.viewer.sceneObjects.map((o) => [o.name, o.representation])")
    assert parts == [["brushed", "prt_matrix"]]
    page.evaluate("() => window.relight.viewer.render()")
    screenshot(page, "viewer-scene-prt-matrix")
    got, covered = part_linear(page, "brushed")

    files = scene_files(viewer_server, pub)
    jobs = {j["kind"]: j for j in pub["result"]["jobs"]}
    man = json.loads(files[next(f for f in jobs["sh_table"]["files"] if f.endswith(".table.json"))])
    entry = man["files"]["table.bin"]
    assert entry["float16_clamped"] == 0
    n, rows, cols, channels = entry["shape"]
    half = np.frombuffer(files[entry["name"]], dtype="<f2").astype(np.float64).reshape(n, rows, cols, channels)
    coefficients = np.broadcast_to(np.transpose(half, (1, 2, 0, 3)), (rows, cols, n, 3))
    order = int(man["order"])
    assert n == (order + 1) ** 2 and order >= 2
    table = SHTable(np.asarray(coefficients), np.zeros((rows, cols, 3)), np.ones((rows, cols), bool), order,
                    man["layout"], {})
    prt = json.loads(files[next(f for f in jobs["shadow_matrix"]["files"] if f.endswith(".prt_matrix.json"))])
    assert prt["order"] == order and prt["job"] == jobs["shadow_matrix"]["id"]
    geo = prt["geometry"]
    mesh = geometry.from_bytes(files[geo["name"]], geo["vertices"], geo["faces"])
    lay = prt["files"]["shadow_matrix.bin"]["texture"]
    assert lay["clamped"] == 0 and lay["value_shape"] == [n, n] and lay["vertices"] == mesh.n_vertices
    bits = np.frombuffer(files[prt["files"]["shadow_matrix.bin"]["name"]], dtype="<f2")
    world = unpack_float16(bits.reshape(lay["height"], lay["width"], 4), lay).astype(np.float64)

    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        texture = http.get(f"/envmaps/{env}/texture.bin?rows=256")
        shape = [int(x) for x in texture.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(texture.content, dtype="<f2").astype(np.float64).reshape(shape)
    lighting = rotate_lighting_y(np.asarray(sh.to_real(sh.project(px16, order, weights="area"), order).T), ROTATION)
    page_light = np.asarray(page.evaluate("() => window.relight.viewer.sceneObjects[0].currentLighting()"))
    np.testing.assert_allclose(page_light, lighting, rtol=0, atol=1e-5 * np.abs(lighting).max())

    drawn = page.evaluate("""() => {
        const g = window.relight.viewer.sceneObjects[0].mesh.geometry;
        return {p: Array.from(g.getAttribute('position').array), n: Array.from(g.getAttribute('normal').array),
                t: Array.from(g.getAttribute('a_tangent').array), i: Array.from(g.getIndex().array)};
    }""")
    # the page draws the job's own mesh, in its canonical vertex order (gl_VertexID indexes the matrices)
    assert np.array_equal(np.asarray(drawn["p"]).reshape(-1, 3), mesh.positions.astype(np.float32))
    assert np.array_equal(np.asarray(drawn["i"]).reshape(-1, 3), mesh.faces)
    normals = np.asarray(drawn["n"], dtype=np.float64).reshape(-1, 3)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    tangents = np.asarray(drawn["t"], dtype=np.float64).reshape(-1, 4)
    regular = np.abs(normals @ np.asarray(DIRECTION)) < 0.999
    np.testing.assert_allclose(tangents[regular, :3], projected_frames(normals, DIRECTION)[regular, 0], atol=1e-5)
    t = tangents[:, :3] / np.linalg.norm(tangents[:, :3], axis=1, keepdims=True)
    frames = np.stack([t, tangents[:, 3:] * np.cross(normals, t), normals], axis=1)  # as sh_table.vert.glsl

    view = np.asarray(VIEW) / np.linalg.norm(VIEW)
    per_vertex = shade_prt(table, page_light, frames, view, folded_transfer(frames, world, order),
                           exact_azimuth=False)
    samples = surface_samples(mesh.normalised(), np.asarray(VIEW), SIZE, supersample=1)
    on_cpu = samples.coverage == 1.0
    want = samples.image(interpolate(samples, mesh, per_vertex))
    # per vertex, interpolated like the values (|sum_k w_k e_k| <= sum_k w_k tol_k), plus the rasteriser's vertex
    # placement: GLES 3.0 places vertices to 1/16 pixel in x and y (SUBPIXEL_BITS >= 4), so the pixel's value is
    # the triangle's at a point up to sqrt(2)/16 pixel away: |grad L| sqrt(2) / 16 with the gradient of the hit
    # triangle's own linear interpolant on the screen (exact, per channel)
    tol = samples.image(interpolate(samples, mesh, vertex_tolerance(table, world, page_light, frames, view)))
    both = covered & on_cpu
    # silhouette pixels may be classified differently by the rasteriser and the ray caster
    assert (covered ^ on_cpu).mean() < 0.005 and both.sum() > 0.2 * SIZE * SIZE
    assert np.abs(want[both]).max() > 0.05
    allowed = tol + triangle_gradient(samples, mesh.normalised().positions, mesh.faces, per_vertex) * np.sqrt(2) / 16
    ratio = (np.abs(got - want)[both] / allowed[both]).max(axis=1)
    print(f"PRT part vs shade_prt (order {order}, {rows} x {cols} {man['layout']}, {prt['rays']} rays, "
          f"{mesh.n_vertices} vertices): {both.sum()} pixels, error / allowed: max {ratio.max():.2f}, median "
          f"{np.median(ratio):.3f}, {int((ratio > 1).sum())} over; largest |error| "
          f"{np.abs(got - want)[both].max():.2e} of {np.abs(want[both]).max():.3f}")
    # where two layers of the mesh meet (folds, the ears against the head) the rasteriser and the ray caster may take
    # different triangles for one pixel: 0.5 % of the pixels, as tests/web/test_viewer_scene_parts.py's bunny
    assert (ratio > 1).mean() < 0.005, int((ratio > 1).sum())
    # the shadows are drawn: without the transfer (the same table, 'general' mode) the comparison above would fail
    # on a quarter of the pixels or more, and by far more than its tolerance where the bunny shadows itself
    flat = samples.image(interpolate(samples, mesh, shade(table, page_light, frames, view, exact_azimuth=False)))
    beyond = (np.abs(flat - want)[both] / allowed[both]).max(axis=1)
    print(f"unshadowed vs shadowed: error / allowed over 1 on {(beyond > 1).mean():.1%} of the pixels, over 20 on "
          f"{(beyond > 20).mean():.1%}")
    assert (beyond > 1).mean() > 0.25 and (beyond > 20).mean() > 0.02  # 50x the 0.5 % let through above
