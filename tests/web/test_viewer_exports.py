"""The viewer's engine-export panel (issue 17, item 9) in Chromium against a live server: every download button
saves exactly the API's bytes (GET /envmaps/{id}/ibl and GET /dfg, read here with httpx; a single SH convention's
file holds exactly that convention's numbers of the API's sh.json): the KTX2 chain per target, the glTF lighting
GLB, the same with the current material's lobe per level (brdf=, relight export --brdf), SH9, the DFG tables.
The side-by-side draws relight's chain and three's PMREM (both rows lit) with their relative RMS per roughness,
the numbers of tests/web/test_three_package_browser.py (within 5 % for r >= 0.25)."""

from __future__ import annotations

import hashlib
import json
from typing import Any
from urllib.parse import quote

import httpx
import numpy as np
import pytest

from relight.brdf.spec import parse_brdf
from tests.service.conftest import Server
from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

#: 900 s before the glTF, material and DFG buttons; they add ~4 jobs of ~30-45 s each on a loaded 2-core machine.
pytestmark = [pytest.mark.timeout(1500)]

TARGETS = ("three", "filament", "gltf", "babylon")
CONVENTIONS = ("three", "gltf", "filament", "babylon", "raw")
DFG = ("size=128&format=exr", "size=128&format=png", "size=128&format=ktx2", "size=128&multiscatter=true&format=ktx2")


def test_download_buttons_and_side_by_side(page: Any, viewer_server: Server, tmp_path: Any) -> None:
    env_id = upload_map(page, tmp_path)
    # the buttons of this map (the page first showed another one's: clicking those saved that map's files) and of
    # the page's current material (its chain buttons: 4 targets + glTF)
    page.wait_for_function("(id) => document.getElementById('exports-buttons').dataset.envmap === id "
                           "&& document.getElementById('exports-buttons').dataset.brdf "
                           "&& document.querySelectorAll('#exports-buttons button').length === 20", arg=env_id,
                           timeout=30_000)
    material = page.evaluate("document.getElementById('exports-buttons').dataset.brdf")
    parse_brdf(material)  # the panel's spec string is one relight parses
    buttons = page.evaluate("Array.from(document.querySelectorAll('#exports-buttons button'))"
                            ".map(b => [b.dataset.url, b.dataset.export ?? null])")
    brdf = f"&brdf={quote(material, safe='')}"
    queries = ([f"target={t}&format=ktx2" for t in TARGETS] + ["target=gltf&format=gltf"]
               + [f"target={t}&format=ktx2{brdf}" for t in TARGETS] + [f"target=gltf&format=gltf{brdf}"]
               + ["format=sh"] + [f"format=sh&convention={c}" for c in CONVENTIONS])
    assert [q for _, q in buttons] == queries + [None] * len(DFG)
    urls = [f"/envmaps/{env_id}/ibl?{q.split('&convention=')[0]}" for q in queries] + [f"/dfg?{q}" for q in DFG]
    assert [u for u, _ in buttons] == urls
    # every button but the material's chains for three's peers (the same code path with another target: ~45 s
    # each at 256^2 faces) is clicked
    skip = {f"target={t}&format=ktx2{brdf}" for t in ("filament", "gltf", "babylon")}
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        for url, q in buttons:
            if q in skip:
                continue
            with page.expect_download(timeout=300_000) as dl:
                page.click(f"#exports-buttons button[data-url='{url}']" if q is None
                           else f"#exports-buttons button[data-export='{q}']")
            saved = dl.value.path().read_bytes()
            # the page's download ran this job: the API answers from its cache, 200 at once (a 202 here meant the
            # buttons still exported the previously selected map)
            api = http.get(url)
            assert api.status_code == 200, api.text
            if q is not None and "convention=" in q:  # one convention's entry of the API's sh.json, as `relight sh`
                conv = q.split("=")[-1]               # names its fields
                doc = json.loads(saved)
                assert doc["convention"] == conv
                assert doc["coefficients"] == api.json()["sh9"][conv]["coefficients"]
                assert doc["quantity"] == api.json()["sh9"][conv]["quantity"]
            else:  # digests: pytest's diff of two differing 1 MB byte strings runs for many minutes
                assert hashlib.sha256(saved).hexdigest() == hashlib.sha256(api.content).hexdigest(), \
                    f"{url}: the download ({len(saved)} bytes) differs from the API's ({len(api.content)} bytes)"
            ext = (".json" if "format=sh" in url else ".glb" if "format=gltf" in url
                   else "." + url.rsplit("format=", 1)[1].split("&")[0])
            assert dl.value.suggested_filename.endswith(ext), (url, dl.value.suggested_filename)
            if "brdf=" in url:  # the material's chain: its lobe family is recorded in the file's sidecar
                job = api.headers["x-relight-job"]
                assert http.get(f"/jobs/{job}/result").json()["manifest"]["brdf"] == material
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
