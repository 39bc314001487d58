"""The viewer's accuracy–time chart and scene panel in a real browser (Chromium + SwiftShader) against a live server.

* *Accuracy vs time* posts ``/tradeoffs`` for the current map and material (16 rows), polls it to the end and draws
  the log-log chart: points of both methods (frequency, angular), their Pareto fronts, and the current choice (the
  last ``/plan``: predicted error and seconds) as a distinct marker.
* *Scene*: a two-object ``SceneCreate`` posted to ``/scenes``; the plan lists both objects with their simulated and
  skipped effects (with reasons), and each object's own SHRM rendered by the server (``{name}.sphere.png``).

Screenshots: ``test-artifacts/web/viewer-tradeoff-chart.png``, ``viewer-tradeoff-scene.png``.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(300)]


def test_tradeoff_chart_and_scene_plan(page: Any, tmp_path: Any) -> None:
    env = upload_map(page, tmp_path, name="tradeoff-sky.exr")

    # ---- accuracy vs time for the current material, with the current choice marked
    page.click("#tradeoff-run")
    page.wait_for_selector("#tradeoff-chart svg .current", timeout=120_000)
    counts = page.evaluate("""() => {
        const svg = document.querySelector('#tradeoff-chart svg');
        const n = (sel) => svg.querySelectorAll(sel).length;
        return {frequency: n('.point[data-method=frequency]'), angular: n('.point[data-method=angular]'),
                fronts: n('polyline.front'), current: n('.current'),
                points: window.relight.tradeoff.points.length, plan: window.relight.plan.predicted_seconds};
    }""")
    assert counts["frequency"] >= 2, counts
    assert counts["angular"] >= 2, counts
    assert counts["fronts"] == 2, counts
    assert counts["current"] == 1, counts
    assert "current choice" in page.inner_text("#tradeoff-status")
    title = page.text_content("#tradeoff-chart svg .current title") or ""
    assert "current choice" in title and "off the axes" not in title, title
    page.evaluate("document.getElementById('tradeoff-run').scrollIntoView()")
    screenshot(page, "viewer-tradeoff-chart")

    # ---- a two-object scene: the plan lists both objects, with skipped effects and their reasons
    scene = {
        "name": "browser-two", "environment": env, "epsilon": 0.05, "size": 16, "preview_size": 32,
        "objects": [
            {"name": "ball", "shape": "sphere", "size": 1, "distance": 3, "material": {"kind": "phong", "s": 32},
             "view": [0, 0, 1]},
            {"name": "bunny", "shape": "bunny", "size": 0.5, "distance": 20, "material": {"kind": "lambert"}},
        ],
    }
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function("window.relight.scene && ['succeeded', 'failed'].includes(window.relight.scene.state)"
                           " && document.querySelectorAll('.scene-object-plan').length === 2", timeout=120_000)
    assert page.evaluate("window.relight.scene.state") == "succeeded", page.inner_text("#scene-error")
    page.wait_for_function("document.querySelectorAll('.scene-plan img.scene-preview').length === 2",
                           timeout=30_000)
    text = page.inner_text("#scene-plan")
    assert "ball: sphere" in text and "bunny: bunny" in text, text
    assert "skipped:" in text and "simulated:" in text, text
    for name in ("ball", "bunny"):
        item = page.inner_text(f".scene-object-plan[data-name={name}]")
        assert "skipped:" in item, item
    assert page.evaluate("document.querySelectorAll('.scene-layout .scene-object').length") == 2
    assert page.evaluate("""() => [...document.querySelectorAll('.scene-plan img.scene-preview')]
                              .every((img) => img.complete && img.naturalWidth === 32)""")
    page.evaluate("document.getElementById('scene-plan').scrollIntoView()")
    screenshot(page, "viewer-tradeoff-scene")


# ------------------------------------------------------------------------------------------ a scene in the 3-D view
def scene_shrms(server: Any, pub: dict[str, Any]) -> dict[str, Any]:
    """Each object's SHRM as the page downloaded it: the float16 texture and its manifest (``relight.gl.layout``)."""
    import httpx

    from relight.gl import layout as gl_layout

    out = {}
    with httpx.Client(base_url=server.url, timeout=60) as http:
        for o in pub["result"]["objects"]:
            files = o["files"]
            manifest = http.get(f"/scenes/{pub['id']}/files/{files['texture']}").raise_for_status().json()
            data = http.get(f"/scenes/{pub['id']}/files/{files['coefficients_bin']}").raise_for_status().content
            lay = gl_layout.from_manifest(manifest)
            stack = np.frombuffer(data, dtype="<f2").astype(np.float64).reshape(lay.num_layers, lay.height,
                                                                               lay.width, 3)
            out[o["name"]] = gl_layout.to_shrm(lay, stack)
    return out


def cpu_scene(frame: dict[str, Any], shrms: dict[str, Any], size: int) -> tuple[np.ndarray, np.ndarray]:
    """The canvas on the CPU: through every pixel centre the camera's ray (the page's own matrices), the nearest
    sphere it hits, and there ``relight.shrm.shade`` with the object's SHRM and planned viewer: near, eq. 6 with
    the pixel's own V; distant, eq. 12 for the direction from the object's centre to the camera, looked up at the
    pixel's own R (what object.frag.glsl does). Returns linear RGB and the index of the object hit (-1: none)."""
    from relight.shrm import shade

    proj = np.asarray(frame["proj"]).reshape(4, 4).T  # three.js elements are column-major
    world = np.asarray(frame["world"]).reshape(4, 4).T
    inv = world @ np.linalg.inv(proj)
    c = (np.arange(size) + 0.5) * 2.0 / size - 1.0
    x, y = np.meshgrid(c, -c)
    far = np.stack([x, y, np.ones_like(x), np.ones_like(x)], axis=-1) @ inv.T
    eye = world[:3, 3]
    ray = far[..., :3] / far[..., 3:] - eye
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    hit_t = np.full((size, size), np.inf)
    hit = np.full((size, size), -1)
    objs = frame["objects"]
    for k, o in enumerate(objs):
        oc = eye - np.asarray(o["center"])
        b = ray @ oc
        disc = b * b - (oc @ oc - o["radius"] ** 2)
        t = np.where(disc >= 0, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        closer = (t > 0) & (t < hit_t)
        hit_t[closer], hit[closer] = t[closer], k
    out = np.zeros((size, size, 3))
    for k, o in enumerate(objs):
        m = hit == k
        centre = np.asarray(o["center"])
        p = eye + hit_t[m][:, None] * ray[m]
        n = (p - centre) / o["radius"]
        v = -ray[m]
        if o["mode"] == "near":
            out[m] = shade(shrms[o["name"]], n, v, local=True)
        else:
            out[m] = shade(shrms[o["name"]], n, v, map_view=(eye - centre) / np.linalg.norm(eye - centre))
    return out, hit


def test_scene_objects_in_the_3d_view(page: Any, tmp_path: Any, viewer_server: Any) -> None:
    """A two-object scene drawn together in the 3-D view, each object with its own SHRM and planned viewer, equals
    the CPU's render of the same scene pixel for pixel (8-bit display values; at most 2 levels, as the single-object
    comparison, for SwiftShader's float16 texture filtering and float32 shading, and a mean under 0.05; measured:
    at most 1 level, mean 0.001). Pixels next to
    a silhouette are left out (a ray grazing a sphere may hit or miss by rounding); everything else is compared,
    background included (black: no object may be drawn where none is, nor be missing)."""
    from relight.envmap import tonemap

    env = upload_map(page, tmp_path, name="scene-sky.exr")
    # epsilon 0.5: since the planner orders SHRMs by the view-band search (tolerance held down to N.V = 0.1), P
    # grows with tighter tolerances (microfacet sigma = 0.4: P = 10 at 0.1, 3 at 0.5), and a distant viewer needs
    # d > r / sin(sqrt(epsilon) / (2 P)) (relight.planning.effects): 63 r at 0.1, 8.5 r at 0.5. At 0.5 the satin
    # sphere at d = 10 is distant and still large on screen; the metal one at d = 2 is near (P delta > sqrt(eps)).
    scene = {
        "name": "browser-3d", "environment": env, "epsilon": 0.5, "size": 16,
        "objects": [
            {"name": "metal", "shape": "sphere", "size": 1, "distance": 2,
             "material": {"kind": "microfacet", "sigma": 0.3}, "view": [0, 0, 1]},
            {"name": "satin", "shape": "sphere", "size": 1, "distance": 10,
             "material": {"kind": "microfacet", "sigma": 0.4}, "view": [0.8, 0.25, 1]},
        ],
    }
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function("window.relight.sceneShown && window.relight.viewer.sceneObjects.length === 2"
                           " || document.getElementById('scene-error').textContent", timeout=120_000)
    assert page.inner_text("#scene-error") == ""
    pub = page.evaluate("window.relight.scene")
    planned = {o["name"]: o["viewer"] for o in pub["plan"]["objects"]}
    assert planned == {"metal": "near", "satin": "distant"}, planned
    assert not page.is_hidden("#scene-single")

    size = 256
    frame = page.evaluate("""(size) => {
        const v = window.relight.viewer;
        v.setFixedSize([size, size]);
        v.setOptions({exposure: 0, tonemap: 'aces', background: false, rotation: 0, shading: 'shrm'});
        v.render();
        const px = v.readPixels();
        return {data: Array.from(px.data), proj: Array.from(v.camera.projectionMatrix.elements),
                world: Array.from(v.camera.matrixWorld.elements),
                objects: v.sceneObjects.map((o) => ({name: o.name, center: o.center.toArray(), radius: o.radius,
                                                     mode: o.mode, shape: o.shape}))};
    }""", size)
    assert {o["name"]: o["mode"] for o in frame["objects"]} == planned
    got = np.asarray(frame["data"], dtype=np.uint8).reshape(size, size, 4)[..., :3].astype(int)
    linear, hit = cpu_scene(frame, scene_shrms(viewer_server, pub), size)
    want = tonemap(linear, exposure=0.0, operator="aces").astype(int)
    assert {int(k) for k in np.unique(hit)} == {-1, 0, 1}, "both objects must be in view"
    edge = np.zeros_like(hit, dtype=bool)
    for axis in (0, 1):
        d = np.diff(hit, axis=axis) != 0
        if axis == 0:
            edge[:-1] |= d
            edge[1:] |= d
        else:
            edge[:, :-1] |= d
            edge[:, 1:] |= d
    diff = np.abs(got - want)[~edge]
    print(f"scene canvas vs CPU: max {diff.max()} levels, mean {diff.mean():.3f} over {diff.size // 3} pixels")
    assert diff.max() <= 2 and diff.mean() < 0.05, f"max {diff.max()} levels, mean {diff.mean():.3f}"
    for k in (0, 1):  # each object covers what the CPU says, and is lit
        inside = (hit == k) & ~edge
        assert inside.sum() > 100 and got[inside].max() > 10, (frame["objects"][k]["name"], inside.sum())
    page.evaluate("() => { const v = window.relight.viewer; v.setFixedSize(null); v.setOptions({background: true});"
                  " v.render(); }")
    screenshot(page, "viewer-scene-3d")

    # the panel's example: a sphere and a mesh (the bunny, scaled to its bounding radius)
    page.click("#scene-example")
    page.click("#scene-run")
    page.wait_for_function("window.relight.scene?.scene?.name === 'two-objects' && window.relight.sceneShown"
                           " === window.relight.scene.id || document.getElementById('scene-error').textContent",
                           timeout=120_000)
    assert page.inner_text("#scene-error") == ""
    shown = page.evaluate("""() => {
        const v = window.relight.viewer;
        v.setFixedSize([128, 128]);
        v.setOptions({background: false});
        v.render();
        const px = v.readPixels().data;
        const litNear = (o) => {  // lit pixels within 3 pixels of the projected centre
            const c = o.center.clone().project(v.camera);
            const x = Math.floor((c.x + 1) * 64);
            const y = Math.floor((1 - c.y) * 64);
            let n = 0;
            for (let dy = -3; dy <= 3; dy += 1) {
                for (let dx = -3; dx <= 3; dx += 1) {
                    const i = 4 * ((y + dy) * 128 + (x + dx));
                    n += (px[i] + px[i + 1] + px[i + 2]) > 0 ? 1 : 0;
                }
            }
            return n;
        };
        return v.sceneObjects.map((o) => [o.name, o.shape, o.radius, o.mesh.visible, litNear(o)]);
    }""")
    assert [o[:4] for o in shown] == [["ball", "sphere", 1, True], ["bunny", "bunny", 0.5, True]], shown
    assert all(o[4] >= 25 for o in shown), f"objects must be drawn where they are: {shown}"

    # back to the current material on one object
    page.evaluate("() => { const v = window.relight.viewer; v.setFixedSize(null); v.setOptions({background: true}); }")
    page.click("#scene-single")
    assert page.evaluate("window.relight.viewer.sceneObjects.length") == 0
    assert page.evaluate("window.relight.viewer.objectName") == "sphere"
    assert page.is_hidden("#scene-single")
