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
