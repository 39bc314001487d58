"""The Scene panel tells the user what went wrong (issue 16 item 4, the viewer's Scene panel), in a real browser
(Chromium + SwiftShader) against a live server and real workers:

* a scene the server cannot plan (``POST /scenes`` answers 4xx with an RFC 9457 problem: the request's validation,
  422 with per-field ``errors``, or the service's refusal, 404 for a mesh never uploaded): the panel's error line
  shows the problem's title, status and the server's own detail text, exactly as the API gives them (the same body
  posted by the test), once (the field messages the detail already holds are not repeated: they were, followed by
  "— : undefined", before web/src/api.js ApiError.display read relight's ``field`` / ``message`` entries), and
  nothing is drawn;
* a part's data that the API refuses (``GET /scenes/{id}/files/{name}`` answers 404 with a problem): the object is
  left out of the 3-D view and, under that object in the panel, the problem's title, status and detail are shown;
  the other object is drawn. The refusal is the real server's: the test only renames, in the scene record the page
  receives (``page.route`` on ``/scenes`` and ``/scenes/{id}``), one file of one object to a name the scene does
  not hold, as a stale listing would, and the page asks the server for it.
"""

from __future__ import annotations

import json
import re
from typing import Any

import httpx
import pytest

from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(600)]

WAIT = ("window.relight.sceneShown === window.relight.scene?.id"
        " || document.getElementById('scene-error').textContent")


def shown(problem: dict[str, Any], status: int) -> str:
    """web/src/api.js ApiError.display(): "Title (status) — detail" (and field messages, none here)."""
    return f"{problem['title']} ({status}) — {problem['detail']}"


BRUSHED = "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0"
UNPLANNABLE = {
    # the request's validation: a tangent field from the mesh's own tangents on the analytic sphere (it has none)
    "validation": ({"name": "brushed", "shape": "sphere", "size": 1, "distance": 4, "material": BRUSHED,
                    "view": [0, 0, 1], "tangent": {"kind": "mesh"}}, "tangent"),
    # the service's: a mesh that was never uploaded
    "unknown-mesh": ({"name": "ghost", "mesh": "0" * 64, "size": 1, "distance": 4, "material": BRUSHED,
                      "view": [0, 0, 1]}, "0" * 64),
}


@pytest.mark.parametrize("case", sorted(UNPLANNABLE))
def test_a_scene_the_server_cannot_plan_shows_the_problem(page: Any, tmp_path: Any, viewer_server: Any,
                                                          case: str) -> None:
    env = upload_map(page, tmp_path, name="scene-errors-sky.exr")
    obj, named = UNPLANNABLE[case]
    scene = {"name": "unplannable", "environment": env, "epsilon": 0.1, "size": 16, "preview_size": 64,
             "objects": [obj]}
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        answer = http.post("/scenes", json=scene)
    assert 400 <= answer.status_code < 500, answer.text
    problem = answer.json()
    assert named in problem["detail"] and answer.headers["content-type"].startswith("application/problem+json")
    before = page.evaluate("window.relight.sceneShown")
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function("document.getElementById('scene-error').textContent", timeout=120_000)
    assert page.inner_text("#scene-error") == shown(problem, answer.status_code)
    assert page.evaluate("window.relight.sceneShown") == before  # nothing drawn
    assert page.evaluate("document.getElementById('scene-run').disabled") is False  # the user can try again


def test_a_part_whose_data_the_api_refuses_shows_the_problem_under_its_object(page: Any, tmp_path: Any,
                                                                                viewer_server: Any) -> None:
    env = upload_map(page, tmp_path, name="scene-errors-sky.exr")
    scene = {"name": "stale-listing", "environment": env, "epsilon": 0.1, "size": 16, "preview_size": 0, "objects": [
        {"name": "chalk", "shape": "sphere", "size": 1, "distance": 4, "material": {"kind": "lambert"},
         "view": [0.6, 0, 1]},
        {"name": "shiny", "shape": "sphere", "size": 1, "distance": 4, "material": {"kind": "phong", "s": 16},
         "view": [-0.6, 0, 1]}]}
    renamed: dict[str, str] = {}

    def stale(route: Any) -> None:
        response = route.fetch()
        pub = response.json()
        for o in (pub.get("result") or {}).get("objects", []):
            if o["name"] == "shiny":
                renamed[o["files"]["texture"]] = o["files"]["texture"] = "shiny.stale.texture.json"
        route.fulfill(response=response, json=pub)

    page.route(re.compile(r".*/scenes(/[0-9a-f]+)?$"), stale)
    page.fill("#scene-json", json.dumps(scene))
    page.click("#scene-run")
    page.wait_for_function(WAIT, timeout=300_000)
    assert page.inner_text("#scene-error") == ""
    pub = page.evaluate("window.relight.scene")
    assert pub["state"] == "succeeded" and renamed, renamed
    # the real server's answer to the request the page made
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        answer = http.get(f"/scenes/{pub['id']}/files/shiny.stale.texture.json")
    assert answer.status_code == 404
    problem = answer.json()
    assert "shiny.stale.texture.json" in problem["detail"]
    assert page.evaluate("window.relight.sceneErrors") == [{"name": "shiny", "message": shown(problem, 404)}]
    under = page.inner_text(".scene-object-plan[data-name=shiny] .scene-draw-error")
    assert under == f"not drawn in the 3-D view: {shown(problem, 404)}"
    assert page.locator(".scene-object-plan[data-name=chalk] .scene-draw-error").count() == 0
    drawn = page.evaluate("() => window.relight.viewer.sceneObjects.map((o) => o.name)")
    assert drawn == ["chalk"]
    assert "1 not drawn" in page.inner_text("#overlay")
