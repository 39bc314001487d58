"""Mitsuba 3 as the independent renderer of a Lambertian mesh under an environment map (issue 13, item 4).

Extends ``relight.mitsuba_twin`` (the analytic sphere) to meshes with its conventions: the ``envmap`` bitmap of
:func:`relight.mitsuba_twin.mitsuba_bitmap` (relight's lat-long map shown exactly), the orthographic camera at
``look_at(3 V, 0, up)`` framing the unit ball (``relight.mesh_render``'s camera), the ``hdrfilm`` box filter, the
``moment`` integrator for each pixel's Monte Carlo variance. The mesh (scaled into the unit ball) is written as an
``obj`` with relight's own vertex normals as ``vn`` (``f v//vn``), so both renderers shade with the same
interpolated normals; the BSDF is ``diffuse`` with ``reflectance = albedo`` (``f_r = albedo / pi``).

``path`` with ``max_depth = 2`` is direct light with exact self-shadowing (one bounce from the surface to the
environment); ``max_depth = 2 + B`` adds B interreflection bounces.

``env_rotation`` turns the environment about +Y the way the viewer and ``relight.gl.prt.rotate_lighting_y`` do (the
map looked up at ``rotate_y(d, -angle)``): the emitter's ``to_world`` is Mitsuba's right-handed rotation by the
same angle about +Y, applied to the un-rotated bitmap, so no texel is resampled.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import luminance
from relight.errors import InputError, RelightError
from relight.mesh.model import TriangleMesh
from relight.mitsuba_compare import block_mean
from relight.mitsuba_twin import camera_up, check_bitmap_shape, mitsuba_bitmap, mitsuba_module, texels_per_pixel

FloatArray = NDArray[np.float64]


def write_obj(mesh: TriangleMesh, path: str | Path, uvs: NDArray[np.floating] | None = None) -> None:
    """``v``, ``vn`` (relight's normals) and ``f a//a b//b c//c`` lines, 1-based, in canonical order; with ``uvs``
    (V, 2) also ``vt`` lines and ``f a/a/a ...`` (Mitsuba then takes its shading tangent from them:
    :func:`uv_frames`)."""
    with open(path, "w") as fh:
        fh.write("".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in mesh.positions))
        if uvs is not None:
            fh.write("".join(f"vt {u:.9g} {v:.9g}\n" for u, v in np.asarray(uvs, dtype=np.float64)))
        fh.write("".join(f"vn {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in mesh.normals))
        if uvs is None:
            fh.write("".join(f"f {a}//{a} {b}//{b} {c}//{c}\n" for a, b, c in mesh.faces + 1))
        else:
            fh.write("".join(f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}\n" for a, b, c in mesh.faces + 1))


def uv_frames(mesh: TriangleMesh, uvs: NDArray[np.floating], prim: NDArray[np.integer],
              normals: NDArray[np.floating]) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Mitsuba's shading frame at surface points of triangles ``prim`` (P,) with interpolated unit ``normals``
    (P, 3) when the mesh carries ``uvs`` (V, 2): per triangle ``dp/du = (dv2 dp1 - dv1 dp2) / det`` (``dp_k``,
    ``(du_k, dv_k)`` the edges from corner 0, ``det = du1 dv2 - dv1 du2``), then ``s = normalize(dp/du - (n.dp/du)
    n)``, ``t = n x s`` (``SurfaceInteraction.initialize_sh_frame``; matched to Mitsuba's ``si.sh_frame`` to
    1e-5, float32, tests/relight/test_sh_prt_mitsuba.py). Returns relight frames (P, 3, 3), rows (s, t, n) — the
    anisotropic twin's ``alpha_u`` acts along s — and whether each triangle's UVs are non-degenerate (det != 0;
    where they are, Mitsuba falls back to an arbitrary frame)."""
    uv = np.asarray(uvs, dtype=np.float64)
    f = mesh.faces[np.asarray(prim)]
    p0, p1, p2 = (mesh.positions[f[:, k]] for k in range(3))
    u0, u1, u2 = (uv[f[:, k]] for k in range(3))
    d1, d2 = u1 - u0, u2 - u0
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    ok = np.abs(det) > 0.0
    dpdu = (d2[:, 1:2] * (p1 - p0) - d1[:, 1:2] * (p2 - p0)) / np.where(ok, det, 1.0)[:, None]
    n = np.asarray(normals, dtype=np.float64)
    s = dpdu - np.sum(dpdu * n, axis=1, keepdims=True) * n
    length = np.linalg.norm(s, axis=1, keepdims=True)
    ok &= length[:, 0] > 0.0
    s = s / np.where(length > 0.0, length, 1.0)
    return np.stack([s, np.cross(n, s), n], axis=1), np.asarray(ok)


@dataclass(frozen=True)
class MeshRender:
    """Mitsuba's image: RGB, luminance and the Monte Carlo variance of each pixel's luminance."""

    rgb: FloatArray
    luminance: FloatArray
    variance: FloatArray
    spp: int
    seconds: float
    max_depth: int

    def blocks(self, block: int) -> tuple[FloatArray, FloatArray]:
        """Block means of luminance and their standard deviations (independent pixels: variance / block^4)."""
        return block_mean(self.luminance, block), np.sqrt(block_mean(self.variance, block) / block**2)


def render_mesh_mitsuba(mesh: TriangleMesh, pixels: NDArray[np.floating], *, view: NDArray[np.floating],
                        size: int, spp: int, albedo: float = 1.0, max_depth: int = 2, seed: int = 0,
                        texels: int = 8, bsdf: dict[str, Any] | None = None,
                        env_rotation: float = 0.0, uvs: NDArray[np.floating] | None = None) -> MeshRender:
    """Render the (unit-ball) mesh under the lat-long map (negatives clamped) seen along V (module docstring);
    ``bsdf`` (a ``relight.mitsuba_twin.twin`` dictionary) replaces the Lambertian of ``albedo``; ``env_rotation``
    (radians about +Y) turns the environment; ``uvs`` (V, 2) give Mitsuba's shading tangents (:func:`uv_frames`:
    the frame of an anisotropic twin)."""
    mi = mitsuba_module()
    p = np.maximum(np.asarray(pixels, dtype=np.float64), 0.0)
    reason = check_bitmap_shape(p.shape)
    if reason is not None:
        raise InputError(reason)
    validate.at_least("max_depth (2 = direct light)", max_depth, 2)
    v = np.asarray(view, dtype=np.float64) / np.linalg.norm(view)
    bitmap = mitsuba_bitmap(p, texels_per_pixel(p.shape[1], texels))
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "mesh.obj"
        write_obj(mesh, obj, uvs)
        scene: dict[str, Any] = {
            "type": "scene",
            "integrator": {"type": "moment",
                           "nested": {"type": "path", "max_depth": max_depth, "hide_emitters": True}},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=(3.0 * v).tolist(), target=[0, 0, 0],
                                                           up=camera_up(v).tolist()),
                "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                         "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "emitter": {"type": "envmap", "bitmap": mi.Bitmap(bitmap),
                        "to_world": mi.ScalarTransform4f().rotate(axis=[0, 1, 0],
                                                                  angle=float(np.degrees(env_rotation)))},
            "mesh": {"type": "obj", "filename": str(obj), "face_normals": False,
                     "bsdf": bsdf or {"type": "diffuse", "reflectance": {"type": "rgb", "value": [albedo] * 3}}},
        }
        t0 = time.perf_counter()
        img = np.array(mi.render(mi.load_dict(scene), spp=spp, seed=mi.UInt32(seed)), dtype=np.float64)
        seconds = time.perf_counter() - t0
    if img.shape != (size, size, 9):
        raise RelightError(f"unexpected Mitsuba film layout {img.shape}")
    y, m2 = img[..., 4], img[..., 7]
    var = np.maximum(m2 - y * y, 0.0) / spp
    return MeshRender(rgb=img[..., :3], luminance=luminance(img[..., :3]), variance=var, spp=spp,
                      seconds=seconds, max_depth=max_depth)
