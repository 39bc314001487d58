"""Headless OpenGL renderer of SHRMs (moderngl, EGL; Mesa llvmpipe works): float images of sphere/bunny/teapot.

The same GLSL as the browser viewer (``web/shaders``, assembled by :mod:`relight.gl.shaders` with
``#version 330``). Two paths, as in seed 000 §7.5:

* ``mode="distant"`` (eq. 12): the layers are turned into global ones once (eq. 8, ``layout.global_layers``);
  per frame ``view_map.frag.glsl`` sums them with the constant weights ``Yr_pq(V)`` into one S x 2S map per
  component (the per-frame reflection map), then ``object.frag.glsl`` (``SHADING_VIEW_MAP``) looks it up
  bilinearly at each pixel's lobe centre — ``relight.shrm.render_sphere(local=False)``.
* ``mode="near"`` (eq. 6): ``object.frag.glsl`` (``SHADING_LOCAL``) samples every layer at the centre and weights
  it with the harmonics of the pixel's own view direction — ``render_sphere(local=True)`` for an orthographic
  camera; with a perspective camera V varies over the image (a near viewer).

Cameras: ``orthographic`` is exactly ``relight.shrm.sphere_geometry``'s (looking along -V, +Y up, the unit ball
filling the frame); ``perspective`` sits at ``distance * V`` with the field of view that just fits the unit ball.
Images are (size, size, 3) float32, row 0 at the top; pixels off the object hold ``background``.
The coefficient texture is float16 (RGB16F, as ``coefficients.bin``) unless ``dtype="f4"`` is asked for.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError
from relight.gl import layout as layout_mod
from relight.gl import shaders
from relight.gl.mesh import Mesh, load_object
from relight.gl.targets import float_target, read_image, set_uniform

Mode = Literal["distant", "near"]
Camera = Literal["orthographic", "perspective"]
FloatImage = NDArray[np.float32]

#: Orthographic camera distance (docs/facts.md's Mitsuba set-up: look_at(3 V, 0, +Y)).
ORTHO_DISTANCE = 3.0
_FULLSCREEN = np.array([-1.0, -1.0, 3.0, -1.0, -1.0, 3.0], dtype="<f4")


def create_context() -> Any:
    """A standalone headless OpenGL 3.3+ context (EGL). Raises ``RuntimeError`` when none can be made."""
    import moderngl

    try:
        return moderngl.create_standalone_context(backend="egl")  # type: ignore[arg-type]  # stub says dict
    except Exception as exc:  # noqa: BLE001 - moderngl/glcontext raise bare Exceptions for a missing EGL
        raise RuntimeError(f"no headless OpenGL context (EGL): {exc}") from exc


def camera_basis(view: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Image right and up of a camera looking along -V with +Y up (+Z up when V = +-Y): shrm.sphere_geometry."""
    up = np.array([0.0, 1.0, 0.0]) if abs(view[1]) < 1.0 - 1e-9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(up, view)
    right /= np.linalg.norm(right)
    return right, np.cross(view, right)


def perspective_fov(distance: float) -> float:
    """Vertical field of view (radians) at which the unit ball just fills the frame from ``distance``."""
    if distance <= 1.0:
        raise InputError(f"a perspective camera must be outside the unit ball, got distance {distance}")
    return 2.0 * math.asin(1.0 / distance)


def view_projection(view: NDArray[np.float64], camera: Camera, distance: float) -> NDArray[np.float64]:
    """The 4 x 4 world -> clip matrix of the camera (OpenGL clip conventions)."""
    right, up = camera_basis(view)
    d = ORTHO_DISTANCE if camera == "orthographic" else distance
    eye = d * view
    look = np.eye(4)
    look[0, :3], look[1, :3], look[2, :3] = right, up, view
    look[:3, 3] = -look[:3, :3] @ eye
    near, far = max(d - 2.0, 0.05), d + 2.0  # the sphere proxy box reaches sqrt(3) from the origin
    proj = np.zeros((4, 4))
    if camera == "orthographic":
        proj[0, 0] = proj[1, 1] = 1.0
        proj[2, 2] = -2.0 / (far - near)
        proj[2, 3] = -(far + near) / (far - near)
        proj[3, 3] = 1.0
    else:
        f = 1.0 / math.tan(0.5 * perspective_fov(d))
        proj[0, 0] = proj[1, 1] = f
        proj[2, 2] = (far + near) / (near - far)
        proj[2, 3] = 2.0 * far * near / (near - far)
        proj[3, 2] = -1.0
    return np.asarray(proj @ look, dtype=np.float64)


@dataclass
class _Program:
    prog: Any
    vao: Any


class Renderer:
    """Renders one SHRM (layout + coefficient layers) with one GL context; reuse it for many views.

    ``coefficients`` is (layers, S, 2S, 3) in manifest layer order (``coefficients.bin`` reshaped). The layers are
    uploaded once, reordered to ``layout.texture_order``.
    """

    def __init__(self, layout: layout_mod.Layout, coefficients: NDArray[np.floating], *, ctx: Any = None,
                 dtype: Literal["f2", "f4"] = "f2") -> None:
        import moderngl

        self.layout = layout
        self.ctx = ctx if ctx is not None else create_context()
        coeffs = np.asarray(coefficients)
        expect = (layout.num_layers, layout.height, layout.width, 3)
        if coeffs.shape != expect:
            raise InputError(f"coefficients have shape {coeffs.shape}, expected {expect}")
        def array_texture(layers: NDArray[np.floating], lay: layout_mod.Layout) -> Any:
            if dtype == "f2":  # clamp to the half-float range (65504) instead of overflowing to inf
                from relight.envmap.exr import to_half_safe

                data = np.ascontiguousarray(to_half_safe(np.asarray(layers))[0], dtype="<f2")
            else:
                data = np.ascontiguousarray(layers, dtype="<f4")
            tex = self.ctx.texture_array((lay.width, lay.height, lay.num_layers), 3, data.tobytes(), dtype=dtype)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = True
            tex.repeat_y = False
            return tex

        # the layers as stored (local, eq. 6: the near viewer) and their global form (eq. 8, once: the distant
        # viewer's per-frame eq. 12 with constant weights), as in web/src/viewer.js
        self.coefficients = array_texture(coeffs[layout.texture_order], layout)
        self.global_layout, global_maps = layout_mod.global_layers(layout, coeffs.astype(np.float64))
        self.global_coefficients = array_texture(global_maps, self.global_layout)
        rows = layout.height
        self.view_map = self.ctx.texture((2 * rows, rows * len(layout.components)), 4, dtype="f4")
        self.view_map.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.view_map.repeat_x = True
        self.view_map.repeat_y = False
        self.view_map_fbo = self.ctx.framebuffer(color_attachments=[self.view_map])
        self._defines = layout_mod.defines(layout)
        quad = self.ctx.buffer(_FULLSCREEN.tobytes())
        vm = self.ctx.program(vertex_shader=shaders.build("fullscreen.vert.glsl"),
                              fragment_shader=shaders.build("view_map.frag.glsl",
                                                            defines=layout_mod.defines(self.global_layout)))
        self._view_map_prog = _Program(vm, self.ctx.vertex_array(vm, [(quad, "2f", "a_position")]))
        self._object_progs: dict[tuple[str, str], _Program] = {}
        self._meshes: dict[str, tuple[Mesh, Any]] = {}

    def release(self) -> None:
        for obj in (self.coefficients, self.global_coefficients, self.view_map, self.view_map_fbo):
            obj.release()

    # ------------------------------------------------------------------------------------------------ passes
    def _object_program(self, obj: str, mode: Mode) -> _Program:
        key = (obj, mode)
        if key not in self._object_progs:
            mesh, buf = self._mesh(obj)
            defines = dict(self._defines)
            defines["SHADING_VIEW_MAP" if mode == "distant" else "SHADING_LOCAL"] = None
            defines["OUTPUT_LINEAR"] = None
            if mesh.analytic_sphere:
                defines["OBJECT_SPHERE"] = None
            prog = self.ctx.program(vertex_shader=shaders.build("object.vert.glsl"),
                                    fragment_shader=shaders.build("object.frag.glsl", defines=defines))
            if prog.get("a_normal", None) is None:  # the analytic sphere ignores the proxy's normals
                vao = self.ctx.vertex_array(prog, [(buf, "3f 12x", "a_position")])
            else:
                vao = self.ctx.vertex_array(prog, [(buf, "3f 3f", "a_position", "a_normal")])
            self._object_progs[key] = _Program(prog, vao)
        return self._object_progs[key]

    def _mesh(self, obj: str) -> tuple[Mesh, Any]:
        if obj not in self._meshes:
            mesh = load_object(obj)
            self._meshes[obj] = (mesh, self.ctx.buffer(mesh.interleaved()))
        return self._meshes[obj]

    def render_view_map(self, view_env: NDArray[np.float64]) -> None:
        """Eq. 12 for the view V (environment frame) into the per-frame map (all component bands)."""
        p = self._view_map_prog.prog
        set_uniform(p, "u_coefficients", 0)
        set_uniform(p, "u_view_env", tuple(float(x) for x in view_env))
        set_uniform(p, "u_view_map_rows", float(self.layout.height))
        set_uniform(p, "u_layer_weight", [float(w) for w in layout_mod.uniform_weights(self.global_layout, view_env)])
        self.global_coefficients.use(location=0)
        self.view_map_fbo.use()
        self.view_map_fbo.viewport = (0, 0, 2 * self.layout.height, self.layout.height * len(self.layout.components))
        self.ctx.disable(self.ctx.DEPTH_TEST | self.ctx.CULL_FACE)
        self._view_map_prog.vao.render(vertices=3)

    def read_view_map(self) -> FloatImage:
        """The per-frame map as (components, S, 2S, 3), row 0 = +Y (for tests)."""
        s, n = self.layout.height, len(self.layout.components)
        raw = np.frombuffer(self.view_map.read(), dtype="<f4").reshape(n * s, 2 * s, 4)
        return np.ascontiguousarray(raw[..., :3].reshape(n, s, 2 * s, 3))

    def render(
        self,
        view: Sequence[float] | NDArray[np.floating],
        size: int,
        *,
        obj: str = "sphere",
        mode: Mode = "distant",
        camera: Camera = "orthographic",
        distance: float = 3.0,
        env_rotation: float = 0.0,
        background: float = 0.0,
    ) -> FloatImage:
        """A (size, size, 3) float32 image of ``obj`` seen from the unit direction ``view`` (module docstring).

        ``env_rotation`` (radians) rotates the environment about +Y (right-handed); the lookups are rotated
        instead of the data (no recomputation).
        """
        import moderngl

        v = np.asarray(view, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0.0:
            raise InputError(f"view must be a non-zero 3-vector, got {np.asarray(view).tolist()}")
        v = v / np.linalg.norm(v)
        validate.int_in_range("size", size, 1, 4096)
        if mode not in ("distant", "near"):
            raise InputError(f"mode must be 'distant' or 'near', got {mode!r}")
        if camera not in ("orthographic", "perspective"):
            raise InputError(f"camera must be 'orthographic' or 'perspective', got {camera!r}")
        cs = (math.cos(-env_rotation), math.sin(-env_rotation))
        view_env = _rotate_y(v, cs)
        if mode == "distant":
            self.render_view_map(view_env)
        prog = self._object_program(obj, mode)
        p = prog.prog
        vp = view_projection(v, camera, distance)
        d = ORTHO_DISTANCE if camera == "orthographic" else distance
        set_uniform(p, "u_model", tuple(np.eye(4).T.ravel()))
        set_uniform(p, "u_view_projection", tuple(vp.T.ravel()))
        set_uniform(p, "u_normal_matrix", tuple(np.eye(3).T.ravel()))
        set_uniform(p, "u_camera_position", tuple(float(x) for x in d * v))
        set_uniform(p, "u_view_direction", tuple(float(x) for x in v))
        set_uniform(p, "u_orthographic", camera == "orthographic")
        set_uniform(p, "u_env_rotation", cs)
        set_uniform(p, "u_sphere", (0.0, 0.0, 0.0, 1.0))
        set_uniform(p, "u_inverse_view_projection", tuple(np.linalg.inv(vp).T.ravel()))
        set_uniform(p, "u_viewport", (float(size), float(size)))
        set_uniform(p, "u_coefficients", 0)
        set_uniform(p, "u_view_map", 1)
        set_uniform(p, "u_view_map_rows", float(self.layout.height))
        set_uniform(p, "u_layer_weight", [float(w) for w in layout_mod.uniform_weights(self.layout, view_env)])
        self.coefficients.use(location=0)
        self.view_map.use(location=1)
        with float_target(self.ctx, size, size, depth=True) as fbo:
            fbo.clear(background, background, background, 1.0, depth=1.0)
            self.ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            prog.vao.render(moderngl.TRIANGLES)
            return read_image(fbo)


def _rotate_y(d: NDArray[np.float64], cs: tuple[float, float]) -> NDArray[np.float64]:
    """``common.glsl``'s rotate_y."""
    c, s = cs
    return np.array([c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]])



def render_result(
    manifest: dict[str, Any],
    coefficients_bin: bytes,
    view: Sequence[float],
    size: int,
    *,
    obj: str = "sphere",
    mode: Mode = "distant",
    camera: Camera = "orthographic",
    env_rotation: float = 0.0,
    ctx: Any = None,
) -> FloatImage:
    """Render a stored result (its manifest and the bytes of ``coefficients.bin``): the server's render route."""
    lay = layout_mod.from_manifest(manifest)
    info = manifest["files"]["coefficients.bin"]
    if info.get("dtype", "float16") != "float16" or info.get("byte_order", "little") != "little":
        raise InputError(f"coefficients.bin must be little-endian float16, got {info.get('dtype')}")
    data = np.frombuffer(coefficients_bin, dtype="<f2")
    expect = lay.num_layers * lay.height * lay.width * 3
    if data.size != expect:
        raise InputError(f"coefficients.bin holds {data.size} values, expected {expect}")
    renderer = Renderer(lay, data.reshape(lay.num_layers, lay.height, lay.width, 3), ctx=ctx)
    try:
        return renderer.render(view, size, obj=obj, mode=mode, camera=camera, env_rotation=env_rotation)
    finally:
        renderer.release()
