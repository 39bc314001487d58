"""The viewer's engine-export panel (issue 17, item 9) in Chromium against a live server: every download button
saves exactly the API's bytes (GET /envmaps/{id}/ibl, read here with httpx; a single SH convention's file holds
exactly that convention's numbers of the API's sh.json), and the side-by-side draws
relight's chain and three's PMREM (both rows lit) with their relative RMS per roughness, the numbers of
tests/web/test_three_package_browser.py (within 5 % for r >= 0.25)."""

from __future__ import annotations

import hashlib
import json
from typing import Any

import httpx
import numpy as np
import pytest

from tests.service.conftest import Server
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(900)]


def test_download_buttons_and_side_by_side(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    env_id = upload_map(page, tmp_path)
    # the buttons of this map (the page first showed another one's: clicking those saved that map's files)
    page.wait_for_function("(id) => document.getElementById('exports-buttons').dataset.envmap === id "
                           "&& document.querySelectorAll('#exports-buttons button').length === 10", arg=env_id,
                           timeout=30_000)
    queries = page.evaluate("Array.from(document.querySelectorAll('#exports-buttons button'))"
                            ".map(b => b.dataset.export)")
    conventions = ["three", "gltf", "filament", "babylon", "raw"]
    assert queries == ([f"target={t}&format=ktx2" for t in ("three", "filament", "gltf", "babylon")] + ["format=sh"]
                       + [f"format=sh&convention={c}" for c in conventions])
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        for q in queries:
            with page.expect_download(timeout=300_000) as dl:
                page.click(f"#exports-buttons button[data-export='{q}']")
            saved = dl.value.path().read_bytes()
            # the page's download ran this job: the API answers from its cache, 200 at once (a 202 here meant the
            # buttons still exported the previously selected map)
            api = http.get(f"/envmaps/{env_id}/ibl?{q.split('&convention=')[0]}")
            assert api.status_code == 200, api.text
            if "convention=" in q:  # one convention's entry of the API's sh.json, as `relight sh` names its fields
                conv = q.split("=")[-1]
                doc = json.loads(saved)
                assert doc["convention"] == conv
                assert doc["coefficients"] == api.json()["sh9"][conv]["coefficients"]
                assert doc["quantity"] == api.json()["sh9"][conv]["quantity"]
            else:  # digests: pytest's diff of two differing 1 MB byte strings runs for many minutes
                assert hashlib.sha256(saved).hexdigest() == hashlib.sha256(api.content).hexdigest(), \
                    f"{q}: the download ({len(saved)} bytes) differs from the API's ({len(api.content)} bytes)"
            assert dl.value.suggested_filename.endswith(".json" if "format=sh" in q else ".ktx2")
    page.click("#exports-compare")
    page.wait_for_function("window.relight.exportsPanel.rms !== null", timeout=300_000)
    rms = page.evaluate("window.relight.exportsPanel.rms")
    assert len(rms) == 5 and all(e <= 0.05 for e in rms[1:]), rms
    # both rows are drawn: every sphere's centre pixel is lit, the corners stay the clear colour
    px = np.asarray(page.evaluate("""() => { const c = document.getElementById('exports-canvas');
        const o = document.createElement('canvas'); o.width = c.width; o.height = c.height;
        const ctx = o.getContext('2d'); ctx.drawImage(c, 0, 0);
        return Array.from(ctx.getImageData(0, 0, c.width, c.height).data); }"""), dtype=np.uint8)
    img = px.reshape(128, 5 * 64, 4)[..., :3].astype(int)
    for row in (0, 1):
        for col in range(5):
            cy, cx = 64 * row + 32, 64 * col + 32
            assert img[cy, cx].sum() > 60, f"row {row}, sphere {col} is not drawn"
            assert img[64 * row + 1, 64 * col + 1].sum() == 0
    assert "relative RMS" in page.inner_text("#exports-rms")
    screenshot(page, "viewer_exports")
