"""@relight/three in a real browser (Chromium + SwiftShader WebGL2, three 0.187) against a live relight server
(issue 17, item 4): relight's exports used by three's own shaders.

* Metal spheres (MeshStandardMaterial, metalness 1) at r = 0, 0.25, 0.5, 0.75, 1 lit by relight's KTX2 chain
  (GET /envmaps/{id}/ibl?target=three&size=256&levels=6, three's own layout: faces 256^2 down to 8^2; a chain
  down to 1^2 puts r = 1 on a 1^2 level, which bilinear filtering cannot interpolate: 30 % there; through the
  package's adapter) against the same spheres lit by three's
  PMREMGenerator on the same map: within 5 % relative RMS (2 % at r = 0), the issue's bound. Both are three's
  split-sum GGX (three's lod = maxLod r (2 - r)) of one map; they differ by three's sampling (256 GGX samples
  per texel on sharp levels, a 16^2 source for rough ones) and its cube size (256^2 from a 64-row map).
* An octant-coloured map: three's background drawn from the chain (level 0, `scene.background`, six cameras
  covering every face) and relight's viewer's mirror sphere (from the lat-long map) show, at every probe pixel,
  the colour of the octant of that pixel's direction (the ray, or the reflection vector): no mirrored or swapped
  faces (also pinned in web/packages/relight-three/test/environment.test.js against an OpenGL table-8.19 lookup).
* A white Lambert sphere lit by three's LightProbe from the exported SH9 equals relight's own order-2 Lambert map
  (relight.prefilter with the Lambert lobe, sampled at the pixel normals) to 0.1 %: both are the exact order-2
  irradiance of the same pixel sums; what remains is the tessellated sphere's normals (256 x 128 segments: the
  interpolated normal is off by ~ (pi / 128)^2 / 8 = 8e-5 rad), float32, and the reference map's bilinear lookup
  (256 rows: < 2e-5 of an order-2 function).
"""

from __future__ import annotations

import hashlib
import json
import time
from typing import Any

import httpx
import numpy as np
import pytest

from relight.brdf.radial import Lambert
from relight.conventions import latlong_dirs, sample_latlong
from relight.prefilter import prefilter_radial
from relight.shrm import sphere_geometry
from tests.service.conftest import Server, exr_bytes, make_envmap

pytestmark = [pytest.mark.timeout(900)]

SIZE = 64
ROUGHNESS = [0, 0.25, 0.5, 0.75, 1]
IMPORTS = ("const THREE = await import('three'); const R = await import('@relight/three');"
           "const E = await import('/src/engine_compare.js');")


def upload(server: Server, data: bytes) -> str:
    with httpx.Client(base_url=server.url, timeout=60) as http:
        resp = http.post("/envmaps", content=data, headers={"Content-Type": "application/octet-stream"})
        assert resp.status_code in (200, 201), resp.text
    return hashlib.sha256(data).hexdigest()


def export(server: Server, env_id: str, **params: Any) -> bytes:
    """GET /envmaps/{id}/ibl until the job has succeeded (202 meanwhile)."""
    with httpx.Client(base_url=server.url, timeout=60) as http:
        for _ in range(600):
            resp = http.get(f"/envmaps/{env_id}/ibl", params=params)
            if resp.status_code == 200:
                return resp.content
            assert resp.status_code == 202, resp.text
            time.sleep(0.5)
    raise AssertionError("the ibl job did not finish")


def cells(data: list[float], count: int) -> np.ndarray:
    """Float RGBA cells (row 0 at the bottom, as WebGL reads) -> (count, SIZE, SIZE, 4), row 0 at the top."""
    arr = np.asarray(data, dtype=np.float64).reshape(count, SIZE, SIZE, 4)
    return arr[:, ::-1]


def smooth_map(h: int) -> np.ndarray:
    """A sky with a broad sun glow (make_envmap without its per-pixel noise: three's PMREM low-passes a map's
    pixel noise at its sharpest levels, which relight's exact mirror level keeps; 13 % relative RMS at r = 0
    on make_envmap's noise, 0.9 % at r = 0.25)."""
    d = latlong_dirs(h, 2 * h)
    sun = np.array([0.3, 0.8, 0.52]) / np.linalg.norm([0.3, 0.8, 0.52])
    glow = np.exp(40.0 * (d @ sun - 1.0))
    return np.asarray((0.5 + 0.4 * d[..., 1:2]) * np.array([0.6, 0.7, 1.0]) + 50.0 * glow[..., None],
                      dtype=np.float32)


def test_metal_spheres_match_threes_pmrem(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    env_id = upload(viewer_server, exr_bytes(smooth_map(64), tmp_path))
    export(viewer_server, env_id, target="three", format="ktx2", size=256, levels=6)
    res = page.evaluate("""async ([id, rows, size]) => {""" + IMPORTS + """
        const api = window.relight.api;
        const tex = await api.envmapTexture(id, rows);
        const url = `/envmaps/${id}/ibl?target=three&format=ktx2&size=256&levels=6`;
        const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
        const canvas = document.createElement('canvas');
        const renderer = new THREE.WebGLRenderer({ canvas });
        const chain = R.cubeChainTexture(bytes);
        const pmrem = E.pmremTexture(renderer, new Uint16Array(tex.data), tex.height, tex.width);
        const a = E.renderMetalSpheres(renderer, chain, { size });
        const b = E.renderMetalSpheres(renderer, pmrem, { size });
        const out = { rms: E.relativeRms(a, b, E.ROUGHNESS.length, size), levels: chain.image[0].mipmaps.length,
          pmrem: !!chain.isPMREMTexture, covered: a.filter((v, i) => i % 4 === 3 && v > 0).length,
          shape: [tex.height, tex.width] };
        renderer.dispose();
        return out;
    }""", [env_id, 64, SIZE])
    assert res["shape"] == [64, 128]
    assert res["pmrem"] is True and res["levels"] == 6  # 256^2 down to 8^2, as three's own PMREM
    # every sphere covers ~ pi/4 of its cell
    assert abs(res["covered"] / (len(ROUGHNESS) * SIZE * SIZE) - np.pi / 4) < 0.02
    rms = res["rms"]
    # r = 0: the 2 %. three draws "r = 0" at roughness max(0.0525, r) plus the sphere's normal
    # derivatives (lights_physical_fragment), i.e. between levels 0 and 1 of the chain, so level 1 (r = 0.106, a
    # lobe a third of this map's pixel) counts as much as level 0 (three's cube copy, which relight's level 0
    # repeats). Measured 13 % while the near part summed pixel centres unnormalised (level 1 overshot).
    assert rms[0] <= 0.02, f"r = 0: relative RMS {rms[0]:.4f} against three's PMREM (all: {rms})"
    for r, e in zip(ROUGHNESS[1:], rms[1:], strict=True):
        assert e <= 0.05, f"r = {r}: relative RMS {e:.4f} against three's PMREM (all: {rms})"


def octant_map(h: int) -> np.ndarray:
    d = latlong_dirs(h, 2 * h)
    return np.asarray(np.stack([np.where(d[..., k] > 0, 1.0, 0.05) for k in range(3)], axis=-1), dtype=np.float32)


def octant_bits(rgb: np.ndarray, dim: float, lit: float) -> np.ndarray:
    """Which channels are lit rather than dim (midway between the two levels as the image encodes them)."""
    return np.asarray(rgb > 0.5 * (dim + lit))


#: Camera directions of the background views: one per face, tilted so that octant boundaries cross each view.
LOOKS = [(1, 0.2, 0.3), (-1, -0.25, 0.2), (0.3, 1, -0.2), (-0.2, -1, 0.3), (0.25, -0.3, 1), (-0.3, 0.2, -1)]


def test_octants_agree_in_three_and_in_relights_viewer(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    data = exr_bytes(octant_map(64), tmp_path)
    page.set_input_files("#envmap-file", files=[{"name": "octants.exr", "mimeType": "image/x-exr", "buffer": data}])
    env_id = hashlib.sha256(data).hexdigest()
    page.wait_for_function("(id) => window.relight.environmentId === id", arg=env_id, timeout=120_000)
    export(viewer_server, env_id, target="three", format="ktx2", size=64)
    res = page.evaluate("""async ([id, size, looks]) => {""" + IMPORTS + """
        const v = window.relight.viewer;
        v.setFixedSize([size, size]);
        v.setFixedView({ view: [0, 0, 1], orthographic: true });
        v.setOptions({ shading: 'plain', exposure: 0, tonemap: 'none', background: false, rotation: 0 });
        v.render();
        const viewer = Array.from(v.readPixels().data);
        v.setFixedSize(null); v.setFixedView(null); v.setOptions({ background: true });
        const url = `/envmaps/${id}/ibl?target=three&format=ktx2&size=64`;
        const chain = R.cubeChainTexture(new Uint8Array(await (await fetch(url)).arrayBuffer()));
        const renderer = new THREE.WebGLRenderer({ canvas: document.createElement('canvas') });
        const target = new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType });
        const scene = new THREE.Scene();
        scene.background = chain;
        const views = looks.map((look) => {
          const cam = new THREE.PerspectiveCamera(90, 1, 0.1, 10);
          cam.up.set(0, 1, 0);
          cam.lookAt(...look);
          cam.updateMatrixWorld();
          renderer.setRenderTarget(target);
          renderer.render(scene, cam);
          const px = new Float32Array(size * size * 4);
          renderer.readRenderTargetPixels(target, 0, 0, size, size, px);
          return { px: Array.from(px), world: cam.matrixWorld.toArray(),
                   unproject: cam.projectionMatrixInverse.toArray() };
        });
        renderer.setRenderTarget(null);
        renderer.dispose();
        return { viewer, views };
    }""", [env_id, SIZE, LOOKS])
    # the viewer's mirror sphere: the octant of R = 2 (n.v) n - v (v = +Z, relight.shrm.sphere_geometry's camera)
    view = np.array([0.0, 0.0, 1.0])
    n, mask = sphere_geometry(view, SIZE)
    r = 2 * (n @ view)[..., None] * n - view
    # probe pixels ~ 10 degrees from every octant boundary and off the rim (the map's pixels are 2.8 degrees)
    probe = mask & (np.abs(r).min(axis=-1) > 0.18) & (n[..., 2] > 0.35)
    viewer = np.asarray(res["viewer"], dtype=np.float64).reshape(SIZE, SIZE, 4)[..., :3]
    # tone map none, then sRGB: 0.05 -> 0.25, 1 -> 1
    wrong = (octant_bits(viewer, 0.25 * 255, 255) != (r > 0)).any(axis=-1) & probe
    assert probe.sum() > 300 and wrong.sum() == 0, f"viewer: {wrong.sum()} of {probe.sum()} probe pixels"
    # three's background: the ray of every pixel centre from the camera's matrices (row 0 at the bottom)
    c = (np.arange(SIZE) + 0.5) / SIZE * 2 - 1
    x, y = np.meshgrid(c, c)
    ndc = np.stack([x, y, np.ones_like(x), np.ones_like(x)], axis=-1)
    total = 0
    for look, v3 in zip(LOOKS, res["views"], strict=True):
        unproject = np.asarray(v3["unproject"]).reshape(4, 4).T  # three's toArray is column-major
        world = np.asarray(v3["world"]).reshape(4, 4).T
        p = ndc @ unproject.T
        d = (p[..., :3] / p[..., 3:]) @ world[:3, :3].T
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        px = np.asarray(v3["px"], dtype=np.float64).reshape(SIZE, SIZE, 4)[..., :3]
        probe3 = np.abs(d).min(axis=-1) > 0.18
        wrong3 = (octant_bits(px, 0.05, 1.0) != (d > 0)).any(axis=-1) & probe3  # a linear float target
        assert wrong3.sum() == 0, (f"three, looking at {look}: {wrong3.sum()} of {probe3.sum()} probe pixels: "
                                   f"{d[wrong3][:5].round(3).tolist()} -> {px[wrong3][:5].round(3).tolist()}")
        total += int(probe3.sum())
    assert total > 6 * SIZE * SIZE // 4


def test_light_probe_lambert_equals_relights_order_2_map(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    pixels = make_envmap(64, seed=5)
    env_id = upload(viewer_server, exr_bytes(pixels, tmp_path))
    sh = export(viewer_server, env_id, format="sh")
    res = page.evaluate("""async ([doc, size]) => {""" + IMPORTS + """
        const renderer = new THREE.WebGLRenderer({ canvas: document.createElement('canvas') });
        const out = Array.from(E.renderProbeSphere(renderer, doc, { size }));
        renderer.dispose();
        return out;
    }""", [json.loads(sh), SIZE])
    got = cells(res, 1)[0]
    # the server holds the uploaded float32 EXR: the same numbers as `pixels`
    ref_map = prefilter_radial(np.asarray(pixels, dtype=np.float64), Lambert(1.0), order=2, size=256).map
    n, mask = sphere_geometry(np.array([0.0, 0.0, 1.0]), SIZE)
    inner = mask & (n[..., 2] > 0.2)  # the rim's pixels are partly off the tessellated silhouette
    want = sample_latlong(ref_map[None], n[inner])[:, 0, :]
    have = got[..., :3][inner]
    assert (got[..., 3][inner] > 0).all()
    rel = np.sqrt(((have - want) ** 2).sum() / (want**2).sum())
    assert rel <= 1e-3, f"relative RMS {rel:.2e}"


def test_shrm_material_teapot_equals_the_viewer(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    """The package's ShrmMaterial on the viewer's teapot, camera and SHRM (a view-dependent BRDF, P = 2: eq. 6
    per pixel and eq. 12 via the view map) against the viewer's own canvas: within 1/255 on >= 99.9 % of the
    pixels (the issue's bound). Same GLSL, same float16 layers, same uniforms: only the draw differs."""
    from tests.web.test_viewer_browser import compute, upload_map

    kinds = page.evaluate("window.relight.models.map(m => m.kind)")
    general = [k for k in ("microfacet", "ggx", "torrance-sparrow", "blinn-phong", "ward") if k in kinds]
    assert general, f"the server offers no view-dependent analytic BRDF (models: {kinds})"
    upload_map(page, tmp_path)
    page.select_option("#brdf-kind", general[0])
    page.check("input[name=accuracy][value=orders]")
    page.fill("#order-f", "8")
    page.fill("#order-p", "2")
    page.dispatch_event("#order-p", "input")
    page.wait_for_function("/P_B = 2/.test(document.getElementById('plan').innerText)", timeout=60_000)
    shrm_id = compute(page)
    res = page.evaluate("""async ([id, size]) => {""" + IMPORTS + """
        const O = await import('/src/objects.js');
        const v = window.relight.viewer;
        v.setObject(await O.loadSample('teapot'), 'teapot');
        v.setFixedSize([size, size]);
        v.setFixedView({ view: [0.3, 0.8, -0.5], orthographic: true });
        const manifest = await (await fetch(`/shrms/${id}`)).json();
        const coefficients = await (await fetch(`/shrms/${id}/coefficients.bin`)).arrayBuffer();
        const canvas = document.createElement('canvas');
        const renderer = new THREE.WebGLRenderer({ canvas, preserveDrawingBuffer: true, antialias: false });
        renderer.setPixelRatio(1);
        renderer.setSize(size, size, false);
        renderer.setClearColor(0x000000, 1);
        const out = {};
        for (const mode of ['near', 'distant']) {
          v.setOptions({ mode, exposure: 0, tonemap: 'aces', background: false, rotation: 0 });
          v.render();
          const viewer = v.readPixels();
          const camera = v._activeCamera();
          const material = new R.ShrmMaterial({ manifest, coefficients, mode, exposure: 0, tonemap: 'aces' });
          const obj = v.primary;
          const mesh = new THREE.Mesh(obj.mesh.geometry, material);
          mesh.position.copy(obj.center);
          mesh.scale.setScalar(obj.radius);
          const scene = new THREE.Scene();
          scene.add(mesh);
          renderer.render(scene, camera);
          const gl = renderer.getContext();
          const px = new Uint8Array(size * size * 4);
          gl.readPixels(0, 0, size, size, gl.RGBA, gl.UNSIGNED_BYTE, px);
          material.dispose();
          out[mode] = { viewer: Array.from(viewer.data), three: Array.from(px) };
        }
        renderer.dispose();
        v.setFixedSize(null); v.setFixedView(null); v.setObject('sphere'); v.setOptions({ background: true });
        return out;
    }""", [shrm_id, 128])
    for mode, imgs in res.items():
        a = np.asarray(imgs["viewer"], dtype=np.int64).reshape(128, 128, 4)[..., :3]
        b = np.asarray(imgs["three"], dtype=np.int64).reshape(128, 128, 4)[::-1, :, :3]  # GL rows: bottom first
        covered = (a.sum(axis=-1) > 0).mean()
        assert covered > 0.15, f"{mode}: the teapot covers only {covered:.1%} of the viewer's image"
        within = (np.abs(a - b).max(axis=-1) <= 1).mean()
        assert within >= 0.999, f"{mode}: {within:.4%} of the pixels within 1/255 (max {np.abs(a - b).max()})"
