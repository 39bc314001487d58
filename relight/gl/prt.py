"""Diffuse PRT on the GPU (moderngl, EGL; Mesa llvmpipe works): a Lambertian mesh lit by an environment's SH
coefficients, unshadowed, with ambient occlusion, or shadowed by per-vertex transfer vectors (Sloan, Kautz & Snyder
2002; ``docs/conventions.md``, "Meshes").

The same GLSL as the viewer (``web/shaders/prt.vert.glsl``, fragment ``sh_table.frag.glsl``): the mesh is drawn
indexed from its canonical arrays (``relight.mesh.geometry``), so ``gl_VertexID`` is the canonical vertex id that
the float16 data textures of a visibility result (``relight.vertex_texture``) are indexed by. Shading is per vertex
(Gouraud), as ``relight.mesh_render.interpolate``; the camera is ``relight.gl.render``'s orthographic one, the mesh
moved into the unit ball (``TriangleMesh.normalised``), so images are pixel for pixel those of
``relight.mesh_render.surface_samples(..., supersample=1)``.

Environment rotation about +Y by an angle a (the viewer's ``rotation``: the map looked up at ``rotate_y(d, -a)``)
rotates the lighting coefficients (:func:`rotate_lighting_y`, closed form per band) and nothing else: a new frame,
not a new job. :func:`cosine_zonal` gives the clamped cosine's ``2 I_l`` of the unshadowed modes.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from typing import Any, Final, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.gl import shaders
from relight.gl.render import ORTHO_DISTANCE, create_context, view_projection
from relight.gl.targets import (
    MESH_LAYOUT,
    POINT_WIDTH,
    float_target,
    mesh_buffers,
    point_rows,
    read_points,
    read_rgba,
    set_uniform,
    vertex_array,
)
from relight.mesh.model import TriangleMesh
from relight.vertex_texture import pack_float16

Mode = Literal["unshadowed", "ao", "transfer"]
MODES: Final[tuple[Mode, ...]] = ("unshadowed", "ao", "transfer")
_DEFINE: Final = {"unshadowed": "MODE_UNSHADOWED", "ao": "MODE_AO", "transfer": "MODE_TRANSFER"}


def cosine_zonal(order: int) -> NDArray[np.float64]:
    """``2 I_l`` for l <= order, ``I_l = int_0^1 mu P_l(mu) dmu`` (Ramamoorthi & Hanrahan 2001: A_l = 2 pi I_l):
    ``I_0 = 1/2``, ``I_1 = 1/3``, 0 for odd l > 1, ``(-1)^(l/2 - 1) l! / (2^l ((l/2)!)^2 (l + 2) (l - 1))`` for
    even l >= 2. ``c_lm(n) = 2 I_l Yr_lm(n)`` is the unshadowed transfer (the factor ``sqrt(4 pi / (2l+1))`` of
    the addition theorem times the zonal ``2 sqrt((2l+1) / 4 pi) I_l``)."""
    out = np.zeros(order + 1)
    for l in range(order + 1):
        if l == 0:
            i_l = 0.5
        elif l == 1:
            i_l = 1.0 / 3.0
        elif l % 2:
            i_l = 0.0
        else:
            h = l // 2
            i_l = (-1.0) ** (h - 1) * math.factorial(l) / (2.0**l * math.factorial(h) ** 2 * (l + 2) * (l - 1))
        out[l] = 2.0 * i_l
    return out


def rotate_lighting_y(lighting: ArrayLike, angle: float) -> NDArray[np.float64]:
    """Real SH coefficients ((F+1)^2, C) of the environment rotated by ``angle`` about +Y (looked up at
    ``rotate_y(d, -angle)``). +Y is the SH pole and the SH azimuth is ``atan2(Z, X)``, which the lookup shifts by
    ``+angle``: ``(c_m, c_-m) -> (c_m cos(m a) + c_-m sin(m a), c_-m cos(m a) - c_m sin(m a))``."""
    c = np.array(lighting, dtype=np.float64)
    order = int(round(math.sqrt(c.shape[0]))) - 1
    out = c.copy()
    for l in range(1, order + 1):
        for m in range(1, l + 1):
            cm, sm = math.cos(m * angle), math.sin(m * angle)
            pos, neg = c[l * l + l + m], c[l * l + l - m]
            out[l * l + l + m] = pos * cm + neg * sm
            out[l * l + l - m] = neg * cm - pos * sm
    return out


def model_matrix(mesh: TriangleMesh) -> NDArray[np.float64]:
    """The 4 x 4 matrix of ``TriangleMesh.normalised``: centre to the origin, bounding radius to 1."""
    r = mesh.radius if mesh.radius > 0 else 1.0
    m = np.eye(4) / r
    m[3, 3] = 1.0
    m[:3, 3] = -mesh.centre / r
    return m


class PrtRenderer:
    """One mesh and its per-vertex data on the GPU (module docstring). ``transfer`` (V, (F+1)^2) and ``ao`` (V,)
    are rounded to float16 on upload exactly as ``relight.vertex_texture.pack_float16`` (what the service serves);
    either may be None when the modes that need it are not drawn."""

    def __init__(self, mesh: TriangleMesh, *, transfer: ArrayLike | None = None, ao: ArrayLike | None = None,
                 order: int = 3, ctx: Any = None) -> None:
        self.mesh, self.order, self.n = mesh, int(order), (int(order) + 1) ** 2
        self.ctx = ctx if ctx is not None else create_context()
        self.vbo, self.ibo = mesh_buffers(self.ctx, mesh)
        self.textures: dict[str, Any] = {}
        for name, values in (("transfer", transfer), ("ao", ao)):
            if values is None:
                continue
            v = np.asarray(values, dtype=np.float64)
            if v.shape[0] != mesh.n_vertices or (name == "transfer" and v.shape[1:] != (self.n,)):
                raise InputError(f"{name} must have one row of {self.n if name == 'transfer' else 1} values per "
                                 f"vertex ({mesh.n_vertices}), got shape {v.shape}")
            tex, lay = pack_float16(v)
            t = self.ctx.texture((lay["width"], lay["height"]), 4, np.ascontiguousarray(tex, "<f2").tobytes(),
                                 dtype="f2")
            t.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self.textures[name] = t
        self._progs: dict[tuple[Mode, bool], Any] = {}

    def release(self) -> None:
        for obj in (self.vbo, self.ibo, *self.textures.values(), *self._progs.values()):
            obj.release()

    def program(self, mode: Mode, probe: bool = False) -> Any:
        if mode not in MODES:
            raise InputError(f"unknown PRT mode {mode!r}; valid modes are {list(MODES)}")
        need = {"transfer": "transfer", "ao": "ao"}.get(mode)
        if need is not None and need not in self.textures:
            raise InputError(f"mode {mode!r} needs the per-vertex {need} data")
        key = (mode, probe)
        if key not in self._progs:
            defs: dict[str, object] = {"PRT_ORDER": self.order, _DEFINE[mode]: None, "OUTPUT_LINEAR": None}
            if probe:
                defs["PROBE"] = None
            self._progs[key] = self.ctx.program(
                vertex_shader=shaders.build("prt.vert.glsl", defines=defs),
                fragment_shader=shaders.build("sh_table.frag.glsl", defines={"OUTPUT_LINEAR": None}))
        return self._progs[key]

    def _uniforms(self, prog: Any, lighting: ArrayLike, albedo: float) -> None:
        light = np.asarray(lighting, dtype=np.float64)
        if light.ndim != 2 or light.shape[0] < self.n or light.shape[1] != 3:
            raise InputError(f"lighting must be (>= {self.n}, 3) real coefficients, got shape {light.shape}")
        set_uniform(prog, "u_light", [tuple(float(x) for x in row) for row in light[: self.n]])
        set_uniform(prog, "u_cosine", [float(x) for x in cosine_zonal(self.order)])
        set_uniform(prog, "u_albedo", float(albedo))
        for unit, name in enumerate(("transfer", "ao")):
            set_uniform(prog, f"u_{name}", unit)
            if name in self.textures:
                self.textures[name].use(location=unit)

    def _vao(self, prog: Any, indexed: bool) -> Any:
        return vertex_array(self.ctx, prog, self.vbo, MESH_LAYOUT, self.ibo if indexed else None)

    def probe(self, mode: Mode, lighting: ArrayLike, albedo: float = 1.0) -> NDArray[np.float32]:
        """Every vertex's radiance (V, 3) through ``mode``'s vertex shader (one point per vertex, tests)."""
        prog = self.program(mode, probe=True)
        self._uniforms(prog, lighting, albedo)
        n = self.mesh.n_vertices
        set_uniform(prog, "u_output_size", (POINT_WIDTH, point_rows(n)))
        vao = self._vao(prog, indexed=False)
        try:
            return read_points(self.ctx, vao, n, vertices=n)
        finally:
            vao.release()

    def draw(self, mode: Mode, view: ArrayLike, lighting: ArrayLike, size: int, *,
             albedo: float = 1.0) -> NDArray[np.float32]:
        """A (size, size, 3) float32 image (row 0 at the top) from the orthographic camera looking along -view,
        background 0."""
        with self._target(mode, view, lighting, size, albedo) as frame:
            raw = frame()
        return np.ascontiguousarray(raw[::-1, :, :3])

    def frame_seconds(self, modes: list[Mode], view: ArrayLike, lighting: ArrayLike, size: int,
                      frames: int) -> dict[str, list[float]]:
        """Wall seconds of ``frames`` frames per mode, the modes interleaved frame by frame (so a change of machine
        load affects them alike), each frame finished (``glFinish``) before the clock stops; nothing read back."""
        out: dict[str, list[float]] = {m: [] for m in modes}
        import time
        from contextlib import ExitStack

        with ExitStack() as stack:
            draws = {m: stack.enter_context(self._target(m, view, lighting, size, 1.0)) for m in modes}
            for m in modes:  # warm-up: shader compilation and first uploads
                draws[m](read=False)
            for _ in range(frames):
                for m in modes:
                    t0 = time.perf_counter()
                    draws[m](read=False)
                    out[m].append(time.perf_counter() - t0)
        return out

    @contextlib.contextmanager
    def _target(self, mode: Mode, view: ArrayLike, lighting: ArrayLike, size: int,
                albedo: float) -> Iterator[Callable[..., NDArray[np.float32]]]:
        """A float target with depth and ``frame(read=True)``: clear, draw, finish, and read the pixels back."""
        import moderngl

        validate.int_in_range("size", size, 1, 4096)
        v = np.asarray(view, dtype=np.float64)
        v = v / np.linalg.norm(v)
        prog = self.program(mode)
        vp = tuple(view_projection(v, "orthographic", ORTHO_DISTANCE).T.ravel())
        model = tuple(model_matrix(self.mesh).T.ravel())
        vao = self._vao(prog, indexed=True)
        try:
            with float_target(self.ctx, size, size, depth=True) as fbo:

                def frame(read: bool = True) -> NDArray[np.float32]:
                    self._uniforms(prog, lighting, albedo)
                    set_uniform(prog, "u_view_projection", vp)
                    set_uniform(prog, "u_model", model)
                    fbo.use()
                    self.ctx.enable(moderngl.DEPTH_TEST)
                    self.ctx.disable(moderngl.CULL_FACE)
                    fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
                    vao.render(moderngl.TRIANGLES)
                    if not read:
                        self.ctx.finish()
                        return np.zeros((0, 0, 4), dtype=np.float32)
                    return read_rgba(fbo)

                yield frame
        finally:
            vao.release()

