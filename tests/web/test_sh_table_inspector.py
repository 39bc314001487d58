"""The SH-table panel's inspector (web/src/sh_table_panel.js, seed 003 Fig. 2 bottom row) in a real browser: the
albedo and per-band energies it computes from a table.bin (float16 [(F+1)^2, R, R, C]) equal
``relight.sh_table.SHTable.albedo`` / ``band_energy`` on the same float16 data (channel means; float32 sums of
squares: 1e-6 relative); and the panel end to end: the button submits an ``sh_table`` job to the viewer's server,
follows it, and shows one false-colour map per band plus the albedo, the inspection being that of the job's own
table.bin."""

from __future__ import annotations

import base64
from typing import Any

import httpx
import numpy as np

from relight.brdf.spec import parse_frame_brdf
from relight.envmap.exr import to_half_safe
from relight.sh_table import SHTable, build_table

from .conftest import Server

INSPECT_JS = """async (a) => {
  const { inspectTable } = await import('/src/sh_table_panel.js');
  const bytes = Uint8Array.from(atob(a.half), (c) => c.charCodeAt(0));
  const r = inspectTable(new Uint16Array(bytes.buffer), a.order, a.resolution, a.channels);
  return { albedo: Array.from(r.albedo), bands: r.bands.map((b) => Array.from(b)), share: r.share };
}"""


def test_inspector_matches_the_core(page: Any) -> None:
    order, res = 4, 16
    table = build_table(parse_frame_brdf({"kind": "ashikhmin-shirley", "nu": 48, "nv": 16,
                                                    "rs": [0.9, 0.6, 0.3], "rd": 0}), order=order,
                        resolution=res)
    assert table.coefficients.shape[-1] == 3
    half = np.asarray(to_half_safe(table.coefficients)[0], dtype="<f2")
    got = page.evaluate(INSPECT_JS, {"order": order, "resolution": res, "channels": 3, "half": base64.b64encode(
        np.ascontiguousarray(np.transpose(half, (2, 0, 1, 3))).tobytes()).decode()})
    same = SHTable(half.astype(np.float64), table.views, table.valid, order, "parabolic", {})
    albedo = same.albedo().mean(axis=-1).ravel()
    bands = same.band_energy().mean(axis=-1)  # (R, R, F + 1)
    assert np.allclose(got["albedo"], albedo, rtol=1e-6, atol=1e-7)
    for l in range(order + 1):
        assert np.allclose(got["bands"][l], bands[..., l].ravel(), rtol=1e-5, atol=1e-9), l
    share = bands.sum(axis=(0, 1)) / bands.sum()
    assert np.allclose(got["share"], share, rtol=1e-5) and share[1:].sum() > 0.3  # a glossy lobe: high bands


def test_panel_computes_and_shows_a_table(page: Any, viewer_server: Server) -> None:
    page.fill("#shtable-brdf", "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0")
    page.select_option("#shtable-order", "2")
    page.fill("#shtable-resolution", "12")
    page.click("#shtable-compute")
    page.wait_for_function("window.relight.shTable !== undefined", timeout=120_000)
    got = page.evaluate("""() => ({ jobId: window.relight.shTable.jobId,
      bands: window.relight.shTable.inspection.bands.map((b) => Array.from(b)),
      maps: document.querySelectorAll('#shtable-maps canvas').length,
      status: document.getElementById('shtable-status').textContent,
      error: document.getElementById('shtable-error').textContent })""")
    assert got["error"] == "" and got["maps"] == 1 + 3 and "9 coefficients" in got["status"]
    with httpx.Client(base_url=viewer_server.url, timeout=60) as http:
        raw = np.frombuffer(http.get(f"/jobs/{got['jobId']}/files/table.bin").content, dtype="<f2")
    c = raw.reshape(9, 12, 12, 1).astype(np.float64)
    for l in range(3):
        want = (c[l * l : (l + 1) ** 2] ** 2).sum(axis=0)[..., 0].ravel()
        assert np.allclose(got["bands"][l], want, rtol=1e-5, atol=1e-9), l
