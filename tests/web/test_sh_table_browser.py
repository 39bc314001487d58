"""The SH-table shader in a real browser (Debian Chromium, WebGL2 on SwiftShader; tests/web/conftest.py): all three
modes of ``web/src/sh_table.js`` (the same GLSL as relight/gl/sh_table.py) against the CPU evaluation
``relight.sh_render.shade`` on the same float16 table; and the ``transfer`` mode (PRT with shadows and one
interreflection bounce, ``relight.sh_prt_bounce``, on the teapot) against ``relight.sh_prt.shade_prt`` on the same
float16 table and matrices; and spatially varying tables (three AS exponents, a per-vertex position among them)
against ``relight.sh_table_varying.VaryingTable.lookup`` on the same float16 tables.

Tolerance per point (as tests/relight/test_gl_sh_table.py): a bilinear lookup may differ by a fixed-point
sub-texel weight (2^-9 of the change over its 2 x 2 footprint) times |L_local,i|, plus the float32 rotation error
(1e-5 per band, the issue's GPU target) times the band norms, plus float32 sums; x 1.5.
"""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

from relight.brdf.spec import parse_frame_brdf
from relight.envmap.exr import to_half_safe
from relight.indexing import full_block
from relight.mesh import sample_mesh
from relight.sh_prt import folded_transfer, shade_prt
from relight.sh_prt_bounce import BounceSettings, vertex_transfer
from relight.sh_render import shade
from relight.sh_rotation import local_rotations, rotate_coefficients
from relight.sh_table import SHTable, build_table
from relight.sh_table_varying import VaryingTable, build_varying_table
from relight.tangent_frames import projected_frames
from relight.view_maps import view_to_texel

MODES = ("general", "fixed-light", "fixed-view")
ROT_TOL, FILTER_STEP, SLACK = 1e-5, 2.0**-9, 1.5

PROBE_JS = """async (a) => {
  const { loadSources } = await import('/src/shaders.js');
  const { SHTableGL, SHADER_FILES } = await import('/src/sh_table.js');
  const read = await loadSources(SHADER_FILES, '/shaders/');
  const bytes = Uint8Array.from(atob(a.half), (c) => c.charCodeAt(0));
  const gl = document.createElement('canvas').getContext('webgl2');
  const t = new SHTableGL(gl, read, { order: a.order, layout: a.layout, resolution: a.resolution,
                                       half: new Uint16Array(bytes.buffer), tables: a.tables || 1 });
  if (a.positions) {
    t.setTablePositions(new Float32Array(a.positions));
  }
  const out = {};
  if (a.transfer) {
    const tb = Uint8Array.from(atob(a.transfer), (c) => c.charCodeAt(0));
    t.setTransfer(new Uint16Array(tb.buffer), a.normals.length / 3);
  }
  for (const mode of a.modes) {
    out[mode] = Array.from(t.probe(mode, new Float32Array(a.normals), new Float32Array(a.tangents), a.view,
                                   new Float32Array(a.light)));
  }
  return out;
}"""


def test_sh_table_shader_three_modes_match_cpu(page: Any) -> None:
    order, layout = 4, "parabolic"
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0"), resolution=32, order=order)
    half = np.broadcast_to(to_half_safe(table.coefficients)[0], table.coefficients.shape[:3] + (3,))
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(400, 3))
    normals[:2] = [[0, 0, 1], [1e-8, 0, -1]]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    frames = projected_frames(normals, (0.3, 0.2, 0.9))
    frames[1::2, 1] *= -1.0  # mirrored frames (glTF w = -1)
    tangents = np.concatenate([frames[:, 0], np.where(np.linalg.det(frames) < 0, -1.0, 1.0)[:, None]], axis=1)
    view = np.array([0.25, 0.55, 0.8]) / np.linalg.norm([0.25, 0.55, 0.8])
    light = rng.normal(size=(25, 3)) * 0.3
    light[0] += 3.0
    got = page.evaluate(PROBE_JS, {
        "order": order, "layout": layout, "resolution": table.resolution, "modes": list(MODES),
        "half": base64.b64encode(np.ascontiguousarray(np.transpose(half, (2, 0, 1, 3)), "<f2").tobytes()).decode(),
        "normals": normals.ravel().tolist(), "tangents": tangents.ravel().tolist(), "view": view.tolist(),
        "light": light.ravel().tolist()})

    same = SHTable(np.asarray(half, np.float64), table.views, table.valid, order, layout, {})
    cpu = shade(same, light, frames, view, exact_azimuth=False)
    vl = np.einsum("nij,j->ni", frames, view)
    local = rotate_coefficients(local_rotations(frames, order), light[None])
    coef = same.lookup(vl, exact_azimuth=False)
    x, y = view_to_texel(layout, table.resolution, vl)
    x0 = np.clip(np.floor(x).astype(int), 0, table.resolution - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, table.resolution - 2)
    quad = np.stack([same.coefficients[y0 + i, x0 + j] for i in (0, 1) for j in (0, 1)])
    band = sum(np.linalg.norm(local[:, full_block(l)], axis=1) * np.linalg.norm(coef[:, full_block(l)], axis=1)
               for l in range(order + 1))
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", np.abs(local), quad.max(0) - quad.min(0))
                   + ROT_TOL * band + 1e-6 * np.einsum("nic,nic->nc", np.abs(local), np.abs(coef)))
    tol = np.where((vl[:, 2] > 0)[:, None], tol, 0.0) + 1e-6
    assert np.abs(cpu).max() > 0.1 and (vl[:, 2] > 0).sum() > 100
    for mode in MODES:
        gpu = np.asarray(got[mode]).reshape(-1, 3)
        assert np.all(np.abs(gpu - cpu) <= tol), (mode, float(np.abs(gpu - cpu).max()))


def test_transfer_mode_with_interreflections_matches_cpu(page: Any) -> None:
    """Tolerance as tests/relight/test_sh_prt.py's GPU test: the sub-texel weight step times |L_local| over the
    lookup's footprint plus float32 sums (1e-6 of sum |L_local| |c|), x 1.5; no rotation on the GPU here (it is
    folded into the matrices on the CPU)."""
    order, layout = 4, "parabolic"
    mesh = sample_mesh("teapot")
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.6,rd=0.1"), resolution=32, order=order)
    frames = projected_frames(mesh.normals, (1.0, 0.3, 0.2))
    frames[1::2, 1] *= -1.0  # mirrored frames
    vt = vertex_transfer(table, mesh, frames, BounceSettings(rays=128, bounces=1))
    total = vt.total()
    assert total.shape[-1] == 1  # a grey table: one matrix per vertex
    folded = folded_transfer(frames, total[..., 0], order)
    n, row = 25, 28
    padded = np.zeros((mesh.n_vertices, n, row))
    padded[:, :, :n] = folded
    half_t = np.asarray(to_half_safe(padded)[0], dtype="<f2")
    half = np.broadcast_to(to_half_safe(table.coefficients)[0], table.coefficients.shape[:3] + (3,))
    tangents = np.concatenate([frames[:, 0], np.where(np.linalg.det(frames) < 0, -1.0, 1.0)[:, None]], axis=1)
    view = np.array([0.3, 0.45, 0.84]) / np.linalg.norm([0.3, 0.45, 0.84])
    rng = np.random.default_rng(2)
    light = rng.normal(size=(25, 3)) * 0.3
    light[0] += 3.0
    got = page.evaluate(PROBE_JS, {
        "order": order, "layout": layout, "resolution": table.resolution, "modes": ["transfer"],
        "half": base64.b64encode(np.ascontiguousarray(np.transpose(half, (2, 0, 1, 3)), "<f2").tobytes()).decode(),
        "transfer": base64.b64encode(half_t.tobytes()).decode(),
        "normals": mesh.normals.ravel().tolist(), "tangents": tangents.ravel().tolist(), "view": view.tolist(),
        "light": light.ravel().tolist()})
    gpu = np.asarray(got["transfer"]).reshape(-1, 3)

    same = SHTable(np.asarray(half, np.float64), table.views, table.valid, order, layout, {})
    fold16 = np.asarray(half_t, np.float64)[:, :, :n]
    cpu = shade_prt(same, light, frames, view, fold16, exact_azimuth=False)
    vl = np.einsum("nij,j->ni", frames, view)
    local = np.abs(np.einsum("vij,jc->vic", fold16, light))
    x, y = view_to_texel(layout, same.resolution, vl)
    x0 = np.clip(np.floor(x).astype(int), 0, same.resolution - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, same.resolution - 2)
    quad = np.stack([same.coefficients[y0 + i, x0 + j] for i in (0, 1) for j in (0, 1)])
    coef = np.abs(same.lookup(vl, exact_azimuth=False))
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", local, quad.max(0) - quad.min(0))
                   + 1e-6 * np.einsum("nic,nic->nc", local, coef)) + 1e-6
    assert np.abs(cpu).max() > 0.05 and (vl[:, 2] > 0).sum() > 100
    assert np.all(np.abs(gpu - cpu) <= tol), float(np.abs(gpu - cpu).max())
    # the bounce is in what the browser drew: without it the CPU result differs by more than the tolerance
    shadow_only = shade_prt(same, light, frames, view, folded_transfer(frames, vt.direct, order))
    assert np.abs(shadow_only - cpu).max() > 10 * tol.max()


def test_spatially_varying_tables_match_cpu(page: Any) -> None:
    """Three modes with Q = 3 tables of AS at nu = 8, 24, 72 (log spacing) and per-vertex nu from 5 to 100 (clamped
    at both ends): the GPU blends the two neighbouring tables' bilinear lookups. Tolerance as the three-mode test,
    the footprint taken over both tables, plus the float32 position (2^-22 of the neighbours' difference)."""
    order, layout = 4, "parabolic"
    var = build_varying_table({"kind": "ashikhmin-shirley", "nu": 24, "nv": 8, "rs": 0.05, "rd": 0.0}, "nu",
                              [8.0, 24.0, 72.0], order=order, resolution=16)
    halves = [np.broadcast_to(to_half_safe(t.coefficients)[0], t.coefficients.shape[:3] + (3,))
              for t in var.tables]
    rng = np.random.default_rng(9)
    normals = rng.normal(size=(300, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    frames = projected_frames(normals, (0.3, 0.2, 0.9))
    frames[1::2, 1] *= -1.0
    tangents = np.concatenate([frames[:, 0], np.where(np.linalg.det(frames) < 0, -1.0, 1.0)[:, None]], axis=1)
    nu = np.exp(rng.uniform(np.log(5.0), np.log(100.0), 300))
    pos = var.positions(nu).astype(np.float32)
    view = np.array([0.25, 0.55, 0.8]) / np.linalg.norm([0.25, 0.55, 0.8])
    light = rng.normal(size=(25, 3)) * 0.3
    light[0] += 3.0
    stacked = np.concatenate([np.transpose(h, (2, 0, 1, 3)) for h in halves])  # (Q n, R, R, 3)
    got = page.evaluate(PROBE_JS, {
        "order": order, "layout": layout, "resolution": 16, "modes": list(MODES), "tables": 3,
        "half": base64.b64encode(np.ascontiguousarray(stacked, "<f2").tobytes()).decode(),
        "positions": pos.tolist(), "normals": normals.ravel().tolist(), "tangents": tangents.ravel().tolist(),
        "view": view.tolist(), "light": light.ravel().tolist()})

    same = VaryingTable("nu", var.values, "log", [SHTable(np.asarray(h, np.float64), t.views, t.valid, order, layout,
                                                          {}) for h, t in zip(halves, var.tables, strict=True)])
    vl = np.einsum("nij,j->ni", frames, view)
    coef = same.lookup(vl, nu, exact_azimuth=False)
    local = rotate_coefficients(local_rotations(frames, order), light[None])
    cpu = np.where((vl[:, 2] > 0)[:, None], np.einsum("nic,nic->nc", local, coef), 0.0)
    x, y = view_to_texel(layout, 16, vl)
    x0, y0 = (np.clip(np.floor(c).astype(int), 0, 14) for c in (x, y))
    quad = np.stack([t.coefficients[y0 + i, x0 + j] for t in same.tables for i in (0, 1) for j in (0, 1)])
    per = np.stack([t.lookup(vl, exact_azimuth=False) for t in same.tables])
    band = sum(np.linalg.norm(local[:, full_block(l)], axis=1) * np.linalg.norm(coef[:, full_block(l)], axis=1)
               for l in range(order + 1))
    tol = SLACK * (FILTER_STEP * np.einsum("nic,nic->nc", np.abs(local), quad.max(0) - quad.min(0))
                   + ROT_TOL * band + 1e-6 * np.einsum("nic,nic->nc", np.abs(local), np.abs(coef))
                   + 2.0**-22 * np.einsum("nic,nic->nc", np.abs(local), per.max(0) - per.min(0)))
    tol = np.where((vl[:, 2] > 0)[:, None], tol, 0.0) + 1e-6
    assert np.abs(cpu).max() > 0.1 and (vl[:, 2] > 0).sum() > 100
    assert (pos == 0).any() and (pos == 2).any() and ((pos > 0) & (pos < 2)).sum() > 100  # clamped and blended
    single = np.where((vl[:, 2] > 0)[:, None], np.einsum("nic,nic->nc", local, per[1]), 0.0)
    assert np.abs(single - cpu).max() > 20 * tol.max()  # the parameter really varies the result
    for mode in MODES:
        gpu = np.asarray(got[mode]).reshape(-1, 3)
        assert np.all(np.abs(gpu - cpu) <= tol), (mode, float(np.abs(gpu - cpu).max()))
