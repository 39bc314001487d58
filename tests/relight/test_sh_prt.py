"""Shadowed SH-table shading with precomputed transfer (relight/sh_prt.py; seed 003 §5) and its GPU twin
(``transfer`` mode of relight/gl/sh_table.py).

References:

* an identity, independent of the matrix code path: with the shadow matrices' own ray directions, for lighting
  band-limited to the table's order, the folded-transfer result equals the direct ray sum
  ``(4 pi / R) sum_s V_p(w_s) L(w_s) f*_F(F_p w_s)`` (``f*_F`` the table's order-F product function evaluated with
  the local harmonics): both are the same finite sum, so they agree to rounding (1e-10 of the largest value).
  A parity or transposition slip in the folding breaks it (the light/view configuration is not mirror-symmetric,
  half the frames are mirrored);
* unshadowed (T_p = I) it is ``relight.sh_render.shade``;
* the GPU (float16 matrices and table, float32 arithmetic) vs the CPU on the same float16 data: lookups may differ
  by the sub-texel weight step (2^-9 of the footprint's change) times |L_local,i| and the sums by float32 rounding
  (1e-6 relative of sum |L_local| |c|), x 1.5.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import relight.gl.render as gl_render
from relight.brdf.spec import parse_frame_brdf
from relight.envmap.exr import to_half_safe
from relight.gl.sh_table import TableRenderer
from relight.mesh.load import sample_mesh
from relight.raycast import RayCaster, ray_offset
from relight.sh_prt import folded_transfer, shade_prt
from relight.sh_render import shade
from relight.sh_table import SHTable, build_table
from relight.shrm import real_harmonics
from relight.tangent_frames import projected_frames
from relight.view_maps import view_to_texel
from relight.visibility import TransferSettings, directions, free_rays, sh_basis, transfer_block

ORDER = 4
VIEW = np.array([0.3, 0.45, 0.84]) / np.linalg.norm([0.3, 0.45, 0.84])


@pytest.fixture(scope="module")
def scene() -> dict[str, Any]:
    mesh = sample_mesh("bunny")
    lo, hi = 700, 760
    settings = TransferSettings(order=ORDER, rays=512, kind="shadow_matrix", seed=3)
    caster = RayCaster(mesh.positions, mesh.faces)
    shadow = transfer_block(mesh, lo, hi, settings, caster=caster).arrays["shadow_matrix"]
    frames = projected_frames(mesh.normals[lo:hi], (1.0, 0.3, 0.2))
    frames[1::2, 1] *= -1.0  # mirrored frames (glTF w = -1)
    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0"), resolution=32)
    rng = np.random.default_rng(11)
    light = rng.normal(size=((ORDER + 1) ** 2, 3)) * 0.3
    light[0] += 3.0
    return {"mesh": mesh, "lo": lo, "hi": hi, "settings": settings, "caster": caster, "shadow": shadow,
            "frames": frames, "table": table, "light": light}


def test_folded_transfer_equals_the_direct_ray_sum(scene: dict[str, Any]) -> None:
    s, table, frames, light = scene["settings"], scene["table"], scene["frames"], scene["light"]
    mesh, lo, hi = scene["mesh"], scene["lo"], scene["hi"]
    prt = shade_prt(table, light, frames, VIEW, folded_transfer(frames, scene["shadow"], ORDER))

    dirs = directions(s.rays, s.sampling, s.seed)
    vis = free_rays(scene["caster"], mesh.positions[lo:hi], mesh.normals[lo:hi], dirs, ray_offset(mesh.positions))
    radiance = sh_basis(dirs, ORDER) @ light  # (R, 3): band-limited world lighting at the ray directions
    u = np.einsum("pij,sj->psi", frames, dirs)  # local coordinates, taken as SH-frame coordinates
    y_local = real_harmonics(ORDER, np.arccos(np.clip(u[..., 2], -1, 1)), np.arctan2(u[..., 1], u[..., 0]))
    vl = np.einsum("pij,j->pi", frames, VIEW)
    fstar = np.einsum("psi,pic->psc", y_local, table.lookup(vl))  # (P, R, C)
    direct = (4.0 * np.pi / s.rays) * np.einsum("ps,sc,psc->pc", vis.astype(float), radiance, fstar)
    direct = np.where((vl[:, 2] > 0)[:, None], direct, 0.0)

    assert np.abs(direct).max() > 0.05 and vis.mean() < 0.9  # lit, and shadowed for real
    assert np.abs(prt - direct).max() <= 1e-10 * np.abs(direct).max()
    unshadowed = shade(table, light, frames, VIEW)
    assert np.abs(unshadowed - prt).max() > 0.05 * np.abs(unshadowed).max()  # the shadows change the result


def test_identity_transfer_is_the_unshadowed_render(scene: dict[str, Any]) -> None:
    frames, table, light = scene["frames"], scene["table"], scene["light"]
    eye = np.broadcast_to(np.eye((ORDER + 1) ** 2), (frames.shape[0], 25, 25))
    got = shade_prt(table, light, frames, VIEW, folded_transfer(frames, eye, ORDER))
    assert np.abs(got - shade(table, light, frames, VIEW)).max() <= 1e-12 * np.abs(got).max()


def test_gpu_transfer_mode_matches_cpu(scene: dict[str, Any]) -> None:
    frames, table, light = scene["frames"], scene["table"], scene["light"]
    folded = folded_transfer(frames, scene["shadow"], ORDER)
    ctx = gl_render.create_context()
    try:
        r = TableRenderer(table.coefficients, "parabolic", ctx=ctx)
        r.set_transfer(folded)
        gpu = r.probe("transfer", frames[:, 2], frames, VIEW, light)
        same = SHTable(r.uploaded, table.views, table.valid, ORDER, "parabolic", {})
        half = np.asarray(to_half_safe(folded)[0], dtype=np.float64)
        cpu = shade_prt(same, light, frames, VIEW, half, exact_azimuth=False)
        vl = np.einsum("pij,j->pi", frames, VIEW)
        local = np.abs(np.einsum("vij,jc->vic", half, light))
        x, y = view_to_texel("parabolic", same.resolution, vl)
        x0 = np.clip(np.floor(x).astype(int), 0, same.resolution - 2)
        y0 = np.clip(np.floor(y).astype(int), 0, same.resolution - 2)
        quad = np.stack([same.coefficients[y0 + i, x0 + j] for i in (0, 1) for j in (0, 1)])
        coef = np.abs(same.lookup(vl, exact_azimuth=False))
        tol = 1.5 * (2.0**-9 * np.einsum("nic,nic->nc", local, quad.max(0) - quad.min(0))
                     + 1e-6 * np.einsum("nic,nic->nc", local, coef)) + 1e-7
        assert np.abs(cpu).max() > 0.05
        assert np.all(np.abs(gpu - cpu) <= tol), float(np.abs(gpu - cpu).max())
        r.release()
    finally:
        ctx.release()
