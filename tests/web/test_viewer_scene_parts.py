"""A scene whose objects use three representations, drawn together in the viewer's 3-D view (issue 16 item 4: "the
viewer draws the whole scene, each object with its chosen representation"), in a real browser (Chromium +
SwiftShader) against a live server and real workers.

The scene: a Phong sphere (seed 000: ``reflection_map``, the object's SHRM texture), the same material on a sphere
edited live (seed 002: ``gaussian_lobes``, the plan's fit and chain: ``web/src/scene_parts.js`` GaussianPart) and a
Lambertian bunny with shadows (``diffuse_transfer``: the object's ``{name}.prt.json``, geometry and float16 transfer
texture, PrtPart). The bunny is nearest, so the viewer (at the origin) looks at it, the spheres left and right.
Checks:

* each object is drawn, alone where its projected bounding sphere is (the page's own camera matrices);
* the Gaussian part against its CPU twin, ``relight.sg_render.shade_gaussian`` of the very float16 fit and chain the
  page downloaded, at the normals of the page's own sphere triangles interpolated by ``relight.mesh_render`` (the
  rasteriser's barycentric interpolation): linear radiance within the Gaussian panel's 2e-3 of the pixel's magnitude
  (tests/web/test_gaussian_browser.py: same float16 data, float32 arithmetic, sub-texel weights) plus 1/16 pixel of
  the image's gradient (the vertex placement GLES 3.0 guarantees), on every pixel both cover but 0.5 % (the
  rasteriser and the ray caster may classify a silhouette pixel differently);
* the shadowed bunny against ``albedo T . L`` on the CPU (tests/web/test_prt_browser.py's reference and display
  tolerances: 2 levels, mean under 0.2, 0.5 % of pixels off at occlusion boundaries), and its unshadowed form
  (``relight.mesh_render.unshadowed_transfer``) the same way; where the CPU says the bunny shadows itself (shadowed
  below 0.8 of unshadowed), the page's shadowed pixels are darker than its unshadowed ones.

A second scene draws a glossy bunny with shadows by seed 004's in-out PRT (InOutPart) against its CPU twin.
"""

from __future__ import annotations

import json
from typing import Any

import httpx
import numpy as np
import pytest

from relight import sh
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.envmap import tonemap
from relight.gaussian_chain import ChainLevel, GaussianChain
from relight.gl.prt import rotate_lighting_y
from relight.inout_factors import InOutFactors
from relight.inout_prt import shade
from relight.mesh import geometry
from relight.mesh.model import TriangleMesh
from relight.mesh_render import interpolate, surface_samples, unshadowed_transfer
from relight.sg_render import shade_gaussian
from relight.tangent_frames import azimuthal_frames
from relight.vertex_texture import unpack_float16
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(600)]

SIZE = 96
VIEW = (0.3, 0.4, 1.0)
ROTATION = 0.7
#: tests/web/test_gaussian_browser.py: relative to a pixel's largest channel (float16 inputs on both sides)
GAUSSIAN_REL_TOL = 2e-3
SCENE = {
    "name": "three-representations", "epsilon": 0.2, "size": 16, "material_edits": ["edited"],
    "objects": [
        {"name": "ball", "shape": "sphere", "size": 1, "distance": 4, "material": {"kind": "phong", "s": 16},
         "view": [0.75, 0, 1]},
        {"name": "edited", "shape": "sphere", "size": 1, "distance": 4, "material": {"kind": "phong", "s": 16},
         "view": [-0.75, 0, 1]},
        {"name": "bunny", "shape": "bunny", "size": 1, "distance": 3.5, "material": {"kind": "lambert"},
         "view": [0, 0.1, 1], "shadows": "exact"},
    ],
}
PARTS = """() => window.relight.viewer.sceneObjects.map((o) => ({name: o.name, kind: o.representation || 'shrm',
    center: o.center.toArray(), radius: o.radius, visible: o.mesh.visible}))"""


def scene_files(server: Any, pub: dict[str, Any]) -> dict[str, bytes]:
    with httpx.Client(base_url=server.url, timeout=60) as http:
        return {name: http.get(f"/scenes/{pub['id']}/files/{name}").raise_for_status().content
                for name in pub["files"]}


def gaussian_twin(pub: dict[str, Any], files: dict[str, bytes]) -> tuple[GaussianLobes, GaussianChain]:
    """The fit and chain exactly as the page uploads them (float16 lobes.bin and levels)."""
    jobs = {j["kind"]: j for j in pub["result"]["jobs"]}
    fit, chain = jobs["gaussian_fit"], jobs["gaussian_chain"]
    spec = json.loads(files[next(f for f in fit["files"] if f.endswith(".json"))])
    n, k = fit["summary"]["elevations"], fit["summary"]["lobes"]
    lobes = np.frombuffer(files[next(f for f in fit["files"] if f.endswith(".lobes.bin"))], dtype="<f2")
    lobes = lobes.astype(np.float64).reshape(n, k, 8)
    material = GaussianLobes([e["theta_o"] for e in spec["elevations"]], lobes[..., 0], lobes[..., 1],
                             lobes[..., 4:7])
    levels = []
    for lv in chain["summary"]["levels"]:
        raw = files[next(f for f in chain["files"] if f.endswith("." + lv["file"]))]
        half = np.frombuffer(raw, dtype="<f2").reshape(lv["height"], lv["width"], 3)
        levels.append(ChainLevel(sigma=float(lv["sigma"]), map=half.astype(np.float32), orders=lv["orders"]))
    return material, GaussianChain(sigma0=float(chain["summary"]["sigma0"]), ratio=float(chain["summary"]["ratio"]),
                                   levels=levels)


def part_linear(page: Any, name: str, mode: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    res = page.evaluate("""async ([name, view, size, rotation, mode]) => {
        const m = await import('/src/scene_parts.js');
        const v = window.relight.viewer;
        const part = v.sceneObjects.find((o) => o.name === name);
        if (mode) part.setMode(mode);
        v.setOptions({rotation});
        const out = m.renderPartLinear(v, part, view, size);
        if (mode) part.setMode('transfer');
        return {rgb: Array.from(out.rgb), coverage: Array.from(out.coverage)};
    }""", [name, list(VIEW), SIZE, ROTATION, mode])
    return (np.asarray(res["rgb"], dtype=np.float64).reshape(SIZE, SIZE, 3),
            np.asarray(res["coverage"], dtype=bool).reshape(SIZE, SIZE))


def test_scene_with_three_representations(page: Any, tmp_path: Any, viewer_server: Any) -> None:
    env = upload_map(page, tmp_path, name="scene-parts-sky.exr")
    page.fill("#scene-json", json.dumps({**SCENE, "environment": env}))
    page.click("#scene-run")
    page.wait_for_function("window.relight.sceneShown && window.relight.viewer.sceneObjects.length === 3"
                           " || document.getElementById('scene-error').textContent", timeout=300_000)
    assert page.inner_text("#scene-error") == ""
    assert page.evaluate("window.relight.sceneErrors") == []
    pub = page.evaluate("window.relight.scene")
    chosen = {o["name"]: [r["representation"] for r in o["representations"]] for o in pub["plan"]["objects"]}
    assert chosen == {"ball": ["reflection_map"], "edited": ["gaussian_lobes"], "bunny": ["diffuse_transfer"]}, chosen
    parts = page.evaluate(PARTS)
    assert [(p["name"], p["kind"], p["visible"]) for p in parts] == [
        ("ball", "shrm", True), ("edited", "gaussian_lobes", True), ("bunny", "diffuse_transfer", True)], parts
    assert "lobes: phong → gaussian_lobes (seed 002)" in page.inner_text(".scene-object-plan[data-name=edited]")

    # ---- each object drawn where it is: alone, its lit pixels inside its projected bounding sphere, and many
    frames = page.evaluate("""(size) => {
        const v = window.relight.viewer;
        v.setFixedSize([size, size]);
        v.setOptions({exposure: 0, tonemap: 'aces', background: false, rotation: 0});
        const grab = () => { v.render(); return Array.from(v.readPixels().data); };
        const all = grab();
        const alone = v.sceneObjects.map((o) => {
            const keep = v.sceneObjects.map((p) => p.mesh.visible);
            v.sceneObjects.forEach((p) => { p.mesh.visible = p === o; });
            const px = grab();
            v.sceneObjects.forEach((p, k) => { p.mesh.visible = keep[k]; });
            return px;
        });
        return {all, alone, vp: Array.from(v.uniforms.u_view_projection.value.elements),
                eye: v.camera.position.toArray()};
    }""", 128)
    vp = np.asarray(frames["vp"]).reshape(4, 4).T
    eye = np.asarray(frames["eye"])
    full = np.asarray(frames["all"], dtype=np.uint8).reshape(128, 128, 4)[..., :3].astype(int)
    # every pixel centre's ray from the page's own matrices (as tests/web/test_viewer_tradeoff_scene.py's cpu_scene)
    ndc = (np.arange(128) + 0.5) / 64 - 1.0
    x, y = np.meshgrid(ndc, -ndc)
    far = np.stack([x, y, np.ones_like(x), np.ones_like(x)], axis=-1) @ np.linalg.inv(vp).T
    ray = far[..., :3] / far[..., 3:] - eye
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    pixel_angle = np.arccos(np.clip(np.sum(ray[64, 64] * ray[64, 65]), -1, 1))
    for p, px in zip(parts, frames["alone"], strict=True):
        img = np.asarray(px, dtype=np.uint8).reshape(128, 128, 4)[..., :3].astype(int)
        lit = img.max(axis=2) > 0
        to_c = np.asarray(p["center"]) - eye
        d = np.linalg.norm(to_c)
        # inside the cone of the bounding sphere (half-angle asin(r / d)), with 1.5 pixels for rasterisation
        angle = np.arccos(np.clip(ray @ (to_c / d), -1, 1))
        inside = angle <= np.arcsin(p["radius"] / d) + 1.5 * pixel_angle
        assert lit.sum() > 200, (p["name"], int(lit.sum()))
        assert not (lit & ~inside).any(), (p["name"], int((lit & ~inside).sum()))
        assert np.array_equal(full[lit], img[lit]), p["name"]  # not covered by another: the scene shows it
    page.evaluate("() => { const v = window.relight.viewer; v.setFixedSize(null); v.setOptions({background: true});"
                  " v.render(); }")
    screenshot(page, "viewer-scene-three-representations")

    files = scene_files(viewer_server, pub)
    # ---- the Gaussian lobes against the CPU, on the page's own sphere triangles
    material, chain = gaussian_twin(pub, files)
    tri = page.evaluate("""() => {
        const g = window.relight.viewer.sceneObjects.find((o) => o.name === 'edited').mesh.geometry;
        return {p: Array.from(g.getAttribute('position').array), n: Array.from(g.getAttribute('normal').array),
                i: Array.from(g.getIndex().array)};
    }""")
    pos = np.asarray(tri["p"], dtype=np.float64).reshape(-1, 3)
    sphere = TriangleMesh(pos, np.asarray(tri["i"], dtype=np.int64).reshape(-1, 3),
                          np.asarray(tri["n"], dtype=np.float64).reshape(-1, 3), np.zeros((len(pos), 4)), "none")
    got, covered = part_linear(page, "edited")
    samples = surface_samples(sphere, np.asarray(VIEW), SIZE, supersample=1)
    on_cpu = samples.coverage == 1.0
    normals = interpolate(samples, sphere, sphere.normals)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    view = np.asarray(VIEW) / np.linalg.norm(VIEW)
    c, s = np.cos(-ROTATION), np.sin(-ROTATION)  # the environment turned: N and V into its frame (sh.js rotateY)
    turn = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    want = samples.image(shade_gaussian(material, chain, normals @ turn.T, turn @ view))
    both = covered & on_cpu
    assert (covered ^ on_cpu).mean() < 0.005 and both.sum() > 0.5 * np.pi / 4 * SIZE * SIZE
    # float16 data: 2e-3 of the pixel's magnitude, at least of the mean magnitude (the chain's SH-synthesised levels
    # ring below zero, and a sum near 0 keeps the rounding of its terms); plus the rasteriser's placement: GLES 3.0
    # guarantees vertex positions to 1/16 pixel (SUBPIXEL_BITS >= 4), so the interpolated normal may belong to a
    # point up to 1/16 pixel away, |grad L| / 16 (the CPU image's own gradient, per pixel)
    scale = np.maximum(np.abs(want).max(axis=2), np.abs(want[both]).mean())
    gy, gx = np.gradient(want, axis=(0, 1))
    allowed = GAUSSIAN_REL_TOL * scale + np.hypot(gx, gy).max(axis=2) / 16
    ratio = (np.abs(got - want).max(axis=2) / allowed)[both]
    print(f"Gaussian part vs CPU: {both.sum()} pixels, error / allowed: max {ratio.max():.2f}, median "
          f"{np.median(ratio):.3f}, {int((ratio > 1).sum())} over")
    assert (ratio > 1).mean() < 0.005, int((ratio > 1).sum())

    # ---- the shadowed bunny against albedo T . L, and darker than unshadowed where it shadows itself
    prt = json.loads(files["bunny.prt.json"])
    lay = prt["geometry"]
    mesh = geometry.from_bytes(files[lay["name"]], lay["vertices"], lay["faces"])
    tex = prt["files"]["transfer.bin"]["texture"]
    bits = np.frombuffer(files[prt["files"]["transfer.bin"]["name"]], dtype="<f2").astype(np.float64)
    transfer = bits.reshape(-1, 4)[: mesh.n_vertices * tex["texels_per_vertex"]]
    transfer = transfer.reshape(mesh.n_vertices, -1)[:, : tex["values_per_vertex"]]
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        texture = http.get(f"/envmaps/{env}/texture.bin?rows=256")
        shape = [int(x) for x in texture.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(texture.content, dtype="<f2").astype(np.float64).reshape(shape)
    order = prt["order"]
    lighting = rotate_lighting_y(np.asarray(sh.to_real(sh.project(px16, order, weights="area"), order).T), ROTATION)
    shadowed, cov = part_linear(page, "bunny")
    page_light = np.asarray(page.evaluate("""() => window.relight.viewer.sceneObjects
        .find((o) => o.name === 'bunny').prt.currentLighting()"""))
    np.testing.assert_allclose(page_light, lighting, rtol=0, atol=1e-5 * np.abs(lighting).max())
    flat, _ = part_linear(page, "bunny", "unshadowed")
    albedo = page.evaluate("window.relight.viewer.sceneObjects.find((o) => o.name === 'bunny').prt.albedo")
    assert albedo == 1.0  # the plan's Lambertian lobe (albedo 1)
    samples = surface_samples(mesh.normalised(), np.asarray(VIEW), SIZE, supersample=1)
    on_cpu = samples.coverage == 1.0
    cpu_shadowed = samples.image(interpolate(samples, mesh, albedo * transfer @ lighting))
    cpu_flat = samples.image(interpolate(samples, mesh, albedo * unshadowed_transfer(mesh.normals, order) @ lighting))
    for page_img, cpu_img, what in ((shadowed, cpu_shadowed, "shadowed"), (flat, cpu_flat, "unshadowed")):
        a = tonemap(page_img, exposure=0.0, operator="aces").astype(int)
        b = tonemap(cpu_img, exposure=0.0, operator="aces").astype(int)
        diff = np.abs(a - b).max(axis=2)
        edge = diff > 2
        print(f"bunny {what} vs CPU: {int(edge[on_cpu].sum())} pixels over 2 levels, mean "
              f"{diff[on_cpu & ~edge].mean():.3f}")
        assert on_cpu.sum() > 0.2 * SIZE * SIZE and (cov ^ on_cpu).mean() < 0.005
        assert edge[on_cpu].mean() < 0.005 and diff[on_cpu & ~edge].mean() < 0.2, what
    lum = np.array([0.2126, 0.7152, 0.0722])
    occluded = on_cpu & cov & (cpu_shadowed @ lum < 0.8 * (cpu_flat @ lum))
    assert occluded.sum() > 100, int(occluded.sum())  # the bunny does shadow itself here
    ratio = (shadowed @ lum)[occluded] / (flat @ lum)[occluded]
    print(f"bunny: {occluded.sum()} self-shadowed pixels, page shadowed / unshadowed median {np.median(ratio):.3f}")
    assert np.median(ratio) < 0.8 and (ratio < 1.0).mean() > 0.99


def test_scene_with_in_out_prt(page: Any, tmp_path: Any, viewer_server: Any) -> None:
    """A glossy bunny with shadows (Phong s = 4: K = 6 in-out terms, seed 004) drawn from the plan's shared
    ``inout_transport`` job (InOutPart), against ``relight.inout_prt.shade`` of the very float16 transport and float32
    factor rows the page downloaded, with tests/web/test_inout_browser.py's tolerances (same data path: 2 levels plus
    the CPU image's largest difference to a 4-neighbour, for the rasteriser's sub-pixel snapping; mean under 1)."""
    env = upload_map(page, tmp_path, name="scene-inout-sky.exr")
    scene = {"name": "glossy-bunny", "environment": env, "epsilon": 0.2, "size": 16, "objects": [
        {"name": "glossy", "shape": "bunny", "size": 1, "distance": 4, "material": {"kind": "phong", "s": 4},
         "view": [0, 0, 1], "shadows": "exact"}]}
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function("window.relight.sceneShown === window.relight.scene?.id"
                           " || document.getElementById('scene-error').textContent", timeout=300_000)
    assert page.inner_text("#scene-error") == ""
    assert page.evaluate("window.relight.sceneErrors") == []
    pub = page.evaluate("window.relight.scene")
    assert [r["representation"] for r in pub["plan"]["objects"][0]["representations"]] == ["inout_prt"]
    assert [(p["name"], p["kind"]) for p in page.evaluate(PARTS)] == [("glossy", "inout_prt")]
    got, cov = part_linear(page, "glossy")

    files = scene_files(viewer_server, pub)
    run = next(j for j in pub["result"]["jobs"] if j["kind"] == "inout_transport")
    res = json.loads(files[next(f for f in run["files"] if f.endswith(".inout.json"))])
    lay, geo = res["transport_texture"], res["geometry"]
    mesh = geometry.from_bytes(files[geo["name"]], geo["vertices"], geo["faces"])
    bits = np.frombuffer(files[lay["name"]], dtype="<f2")
    transport = unpack_float16(bits.reshape(lay["height"], lay["width"], 4), lay).astype(np.float64)
    k = res["terms"]
    rows = np.frombuffer(files[res["factors_texture"]["name"]], dtype="<f4").reshape(k, -1).astype(np.float64)
    n_tab = rows.shape[1] - 2
    f = InOutFactors(np.ones(k), rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64), np.zeros((k, n_tab)),
                     rows[:, 2:], np.linspace(0.0, 0.5 * np.pi, n_tab), True, res["captured"], "page")
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        texture = http.get(f"/envmaps/{env}/texture.bin?rows=256")
        shape = [int(x) for x in texture.headers["X-Texture-Shape"].split(",")]
        px16 = np.frombuffer(texture.content, dtype="<f2").astype(np.float64).reshape(shape)
    order = res["order"]
    lighting = rotate_lighting_y(np.asarray(sh.to_real(sh.project(px16, order, weights="area"), order).T), ROTATION)
    page_light = np.asarray(page.evaluate("""() => window.relight.viewer.sceneObjects[0].inout.currentLighting()"""))
    np.testing.assert_allclose(page_light, lighting, rtol=0, atol=1e-5 * np.abs(lighting).max())
    v = np.asarray(VIEW) / np.linalg.norm(VIEW)
    per_vertex = shade(f, transport, lighting, azimuthal_frames(mesh.normals), v)
    samples = surface_samples(mesh.normalised(), np.asarray(VIEW), SIZE, supersample=1)
    covered = samples.coverage == 1.0
    want = tonemap(samples.image(interpolate(samples, mesh, per_vertex)), exposure=0.0, operator="aces").astype(int)
    a = tonemap(got, exposure=0.0, operator="aces").astype(int)
    diff = np.abs(a - want).max(axis=2)
    near = np.zeros(diff.shape)
    for axis in (0, 1):
        for step in (1, -1):
            near = np.maximum(near, np.abs(want - np.roll(want, step, axis=axis)).max(axis=2))
    assert covered.sum() > 0.2 * SIZE * SIZE and (cov ^ covered).mean() < 0.005
    print(f"in-out part vs CPU: {int((diff > 2 + near)[covered].sum())} pixels beyond, mean {diff[covered].mean():.2f}")
    assert np.all(diff[covered] <= 2 + near[covered]), int((diff > 2 + near)[covered].sum())
    assert diff[covered].mean() < 1.0, diff[covered].mean()
