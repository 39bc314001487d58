"""Measured errors of a plan's mesh representations against a per-vertex brute force (issue 16 item 4: "every
object's measured error (vs Mitsuba or the brute force) within its predicted error"; the sphere's representations
are :mod:`relight.planning.measure`'s).

For an object on a mesh whose lobe the plan drew with ``diffuse_transfer`` (SKS02), ``inout_prt`` (seed 004) or
``prt_matrix`` (seed 003 §5), the data a run computed (:func:`relight.planning.run_plan` with ``write=False``:
``SceneRun.transfers`` and ``SceneRun.jobs``) is shaded at every vertex toward the object's view with the plan's
lighting order, exactly as the renderers do (``relight.mesh_render.shade_transfer``, ``relight.inout_prt.shade``,
``relight.sh_prt.shade_prt``), and compared with the untruncated direct integral over every pixel of the plan's map
with ray-cast visibility (:func:`brute_force_vertices`: ``sum_p L_p V(x, w_p) f(w_p, v) max(0, n.w_p) dOmega_p``;
no SH, no factorization, no Monte Carlo) by relative RMS over the vertices that face the view
(``sqrt(sum |a - ref|^2 / sum |ref|^2)``, RGB).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.planning.scene_plan import Plan

FloatArray = NDArray[np.float64]
#: Map pixels per batch of the brute force (bounds the (V, S, 3) intermediate).
PIXEL_BATCH = 256


def brute_force_vertices(mesh: Any, frames: FloatArray, brdf: Any, pixels: NDArray[np.floating],
                         view: FloatArray, shadows: bool = True) -> FloatArray:
    """Direct radiance (V, 3) toward ``view`` at a mesh's vertices with local frames (V, 3, 3) (rows t, b, n) for a
    ``relight.brdf.frame.FrameBRDF`` (``fcos_local``: f times the local cosine), every map pixel a light."""
    from relight.conventions import latlong_dirs, pixel_solid_angles
    from relight.raycast import RayCaster, ray_offset

    px = np.asarray(pixels, dtype=np.float64)
    h, w = px.shape[:2]
    dirs = latlong_dirs(h, w).reshape(-1, 3)
    weight = (px * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    normals = np.asarray(mesh.normals, dtype=np.float64)
    caster = RayCaster(mesh.positions, mesh.faces)
    origins = (mesh.positions + ray_offset(mesh.positions) * normals).astype(np.float32)
    vl = np.einsum("pij,j->pi", frames, view)
    out = np.zeros((normals.shape[0], 3))
    for s0 in range(0, dirs.shape[0], PIXEL_BATCH):
        d = dirs[s0 : s0 + PIXEL_BATCH]
        above = normals @ d.T > 0.0
        vis = np.zeros(above.shape)
        rows, cols = np.nonzero(above)
        vis[rows, cols] = ~caster.occluded(origins[rows], d[cols].astype(np.float32)) if shadows else 1.0
        local = np.einsum("pij,sj->psi", frames, d)
        f = np.asarray(brdf.fcos_local(local, vl[:, None, :]), dtype=np.float64)
        out += np.einsum("ps,psc,sc->pc", vis, np.broadcast_to(f, f.shape[:2] + (3,)), weight[s0 : s0 + PIXEL_BATCH])
    return out


def _frames(obj: Any, normals: FloatArray) -> FloatArray:
    from relight.tangent_frames import azimuthal_frames, projected_frames

    t = obj.tangent or {}
    if t.get("kind") == "project":
        return np.asarray(projected_frames(normals, np.asarray(t["direction"], dtype=np.float64)), dtype=np.float64)
    return np.asarray(azimuthal_frames(normals), dtype=np.float64)


def shade_vertices(plan: Plan, run: Any, name: str, index: int) -> tuple[FloatArray, FloatArray, str] | None:
    """The object's ``index``-th lobe at its mesh's vertices as drawn with its planned representation, the vertex
    frames used and the mesh's reference (``Plan.meshes``); None for a representation not drawn from per-vertex
    data."""
    from relight.mesh_render import lighting_coefficients, shade_transfer

    o = next(x for x in plan.report.objects if x.name == name)
    r = o.representations[index]
    view = np.asarray(o.view, dtype=np.float64) / np.linalg.norm(o.view)
    if r.representation == "diffuse_transfer":
        tr = run.transfers[name]
        order = int(tr.manifest["order"])
        albedo = np.broadcast_to(np.asarray(r.lobe.get("albedo", 1.0), dtype=np.float64), (3,))
        val = shade_transfer(np.asarray(tr.arrays["transfer"], np.float64), lighting_coefficients(plan.pixels, order))
        assert o.shadows is not None
        normals = np.asarray(plan.meshes[o.shadows.mesh].normals, np.float64)
        return val * albedo[None, :], _frames(o, normals), o.shadows.mesh
    jobs = {j.id: j for j in plan.report.jobs}
    if r.representation == "inout_prt":
        from relight.inout_prt import shade

        job = next(jobs[j] for j in r.jobs if jobs[j].kind == "inout_transport")
        data = run.jobs[job.id]
        order = int(job.params["order"])
        return shade(data["factors"], data["transport"], lighting_coefficients(plan.pixels, order), data["frames"],
                     view), np.asarray(data["frames"], np.float64), str(job.params["mesh"])
    if r.representation == "prt_matrix":
        from relight.sh_prt import folded_transfer, shade_prt

        table = run.jobs[next(j for j in r.jobs if jobs[j].kind == "sh_table")]
        tr = run.jobs[next(j for j in r.jobs if jobs[j].kind == "shadow_matrix")]
        ref = str(next(jobs[j] for j in r.jobs if jobs[j].kind == "shadow_matrix").params["mesh"])
        frames = _frames(o, np.asarray(plan.meshes[ref].normals, np.float64))
        folded = folded_transfer(frames, tr.arrays["shadow_matrix"], table.order)
        return shade_prt(table, lighting_coefficients(plan.pixels, table.order), frames, view, folded), frames, ref
    return None


def measure_mesh_lobes(plan: Plan, run: Any, name: str) -> list[dict[str, Any]]:
    """Per lobe of object ``name`` drawn from per-vertex data: representation, predicted and measured relative RMS
    over the vertices facing the view (module docstring); other lobes have ``measured = None``."""
    from relight.brdf.spec import parse_frame_brdf

    o = next(x for x in plan.report.objects if x.name == name)
    view = np.asarray(o.view, dtype=np.float64) / np.linalg.norm(o.view)
    out = []
    for i, r in enumerate(o.representations):
        entry: dict[str, Any] = {"lobe": r.kind, "representation": r.representation, "predicted": r.predicted_error,
                                 "error_kind": r.error_kind, "measured": None}
        shaded = shade_vertices(plan, run, name, i)
        if shaded is not None:
            img, frames, mesh_ref = shaded
            mesh = plan.meshes[mesh_ref]
            ref = brute_force_vertices(mesh, frames, parse_frame_brdf(r.lobe), plan.pixels, view)
            facing = np.asarray(mesh.normals, np.float64) @ view > 0.0
            d = img[facing] - ref[facing]
            entry["measured"] = float(np.sqrt(np.sum(d * d) / np.sum(ref[facing] ** 2)))
            entry["vertices"] = int(np.count_nonzero(facing))
        out.append(entry)
    return out
