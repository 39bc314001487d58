"""Gaussian-lobe shading on the GPU (moderngl, EGL; Mesa llvmpipe works): seed 002's §5 renderer.

The GLSL is ``web/shaders/gaussian.glsl`` (with ``gaussian.vert.glsl`` / ``gaussian.frag.glsl``), the same text the
viewer uses; it evaluates eq. 5, or eq. 7 with per-vertex SH visibility, exactly as the CPU does
(``relight.sg_render``, ``relight.sg_shadow``). The data are float16 as stored: :func:`half_material` and
:func:`half_chain` round a material and a chain the way the textures hold them, so the CPU evaluation of the
rounded data is the GPU's reference (``tests/relight/test_gl_gaussian.py``).

Textures (the paper's Fig. 3): ``u_lobes`` RGBA32UI, the float16 lobe table (:class:`LobeTable`: a row per
elevation, or per row of an even grid through them, so that the shader finds its rows with one multiply; read with
texelFetch, interpolated in the shader); ``u_chain`` an RGBA16F 3-D texture whose slices are the chain's
levels, which must share one size (``build_chain(..., uniform_size=True)``): one trilinear lookup per lobe blends
two levels. Objects: the unit sphere (orthographic, ``relight.shrm.sphere_geometry``'s frame) or a
``TriangleMesh`` in the unit ball (indexed, canonical vertex order, with its per-vertex visibility), with
``relight.mesh_render``'s orthographic camera. ``plain=True`` draws the baseline instead: the chain's sharpest
level as an ordinary RGBA16F 2-D texture (``u_env``) looked up at R, one bilinear lookup per pixel (the per-frame
cost reference of ``bench/gaussian_frame.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.gaussian_lobes import GaussianLobes
from relight.errors import InputError
from relight.gaussian_chain import ChainLevel, GaussianChain
from relight.gl import shaders
from relight.gl.render import camera_basis, create_context, view_projection
from relight.gl.targets import MESH_LAYOUT, float_target, read_image, set_uniform, vertex_array
from relight.mesh.model import TriangleMesh

#: Visibility modes as the shader's VIS_MODE (relight.sg_shadow.MODES; "none" compiles no visibility).
VIS_MODES: Final = {"ao": 1, "sh": 2, "sh-lobe": 3}
#: Coefficients per vertex in the attributes (order 3, the paper's 16).
VIS_COEFFICIENTS: Final = 16
#: :meth:`GaussianRenderer.mesh_buffers`' interleaved vertex: position, normal, 16 visibility floats.
_MESH_LAYOUT: Final = (*MESH_LAYOUT, *((f"a_visibility{i}", 4) for i in range(4)))
_FULLSCREEN: Final = np.array([-1.0, -1.0, 0.0, 3.0, -1.0, 0.0, -1.0, 3.0, 0.0], dtype="<f4")


def _half(a: NDArray[np.floating]) -> NDArray[np.float64]:
    return np.asarray(np.asarray(a, dtype=np.float64).astype(np.float16), dtype=np.float64)


#: The most rows of an even grid the lobe table is resampled onto; with more, or with elevations on no grid, the
#: table keeps the material's own elevations and the shader bisects them.
MAX_GRID_ROWS: Final = 1024
#: Grid steps tried: the smallest gap between elevations divided by 1, 2, ..., this.
GRID_SUBDIVISIONS: Final = 16
#: How far, in rows, an elevation may sit from its grid row (float32 elevations of a float64 grid: ~1e-5).
GRID_TOLERANCE: Final = 1e-3


def lobe_grid(elevations: NDArray[np.floating]) -> tuple[float, float, int] | None:
    """(theta_0, step, rows) of the coarsest even grid that has a row at every elevation (within
    :data:`GRID_TOLERANCE` rows; step = gap / q for the smallest gap and q = 1 ... :data:`GRID_SUBDIVISIONS`, the
    last row at the last elevation), or None (fewer than two elevations, none found within :data:`MAX_GRID_ROWS`).
    ``relight fit``'s elevations always have one: N even ones, then bisections (docs/conventions.md)."""
    e = np.asarray(elevations, dtype=np.float64)
    if e.size < 2:
        return None
    gap, span = float(np.min(np.diff(e))), float(e[-1] - e[0])
    for q in range(1, GRID_SUBDIVISIONS + 1):
        rows = int(round(span / (gap / q))) + 1
        if rows > MAX_GRID_ROWS:
            return None
        step = span / (rows - 1)
        m = (e - e[0]) / step
        if float(np.max(np.abs(m - np.round(m)))) <= GRID_TOLERANCE:
            return float(e[0]), step, rows
    return None


class LobeTable:
    """The material as the shader's lobe table holds it (``web/shaders/gaussian.glsl``): rows at the material's
    elevations (float32), or at every row of :func:`lobe_grid`'s grid through them, the inserted rows linearly
    interpolated (so the piecewise-linear parameters in theta_o are the material's); every value float16.
    ``web/src/gaussian.js``'s lobeTable computes the same rows with the same arithmetic."""

    def __init__(self, material: GaussianLobes) -> None:
        e = np.asarray(material.elevations.astype(np.float32), dtype=np.float64)
        rounded = GaussianLobes(e, _half(material.mu), _half(material.sigma), _half(material.weight))
        grid = lobe_grid(e)
        #: (theta_0, rows per radian), the shader's ``u_lobe_grid``, or None (the rows are the elevations)
        self.grid: tuple[float, float] | None = None
        self.material = rounded
        if grid is not None:
            theta0, step, rows = grid
            at = theta0 + step * np.arange(rows)
            mu, sigma, weight = rounded.params_at(at)
            self.material = GaussianLobes(at, _half(mu), _half(sigma), _half(weight))
            self.grid = (theta0, 1.0 / step)

    @property
    def rows(self) -> int:
        return int(self.material.elevations.size)

    def words(self) -> NDArray[np.uint32]:
        """The RGBA32UI texels, (rows, :func:`lobe_texels` (K), 4) uint32: per row the float16 halves mu_0, sigma_0,
        w_0.r, w_0.g, mu_1, ..., then w_0.b, ..., w_{K-1}.b, zero-padded, two to a word (low half first)."""
        m = self.material
        k = m.n_lobes
        halves = np.zeros((self.rows, 8 * lobe_texels(k)), dtype=np.float16)
        w = np.asarray(m.weight)
        per_lobe = np.stack([m.mu, m.sigma, w[..., 0], w[..., 1]], axis=-1)  # (rows, K, 4)
        halves[:, : 4 * k] = per_lobe.reshape(self.rows, 4 * k)
        halves[:, 4 * k : 5 * k] = w[..., 2]
        return np.ascontiguousarray(halves).view("<u4").reshape(self.rows, lobe_texels(k), 4)

    def defines(self) -> dict[str, object]:
        out: dict[str, object] = {"GAUSSIAN_K": self.material.n_lobes, "GAUSSIAN_ROWS": self.rows}
        if self.grid is not None:
            out["GAUSSIAN_GRID"] = None
        else:
            out["GAUSSIAN_SEARCH_STEP"] = 1 << ((self.rows - 2).bit_length() - 1) if self.rows > 2 else 0
        return out

    def uniforms(self) -> dict[str, object]:
        if self.grid is not None:
            return {"u_lobe_grid": self.grid}
        return {"u_elevations": [float(x) for x in self.material.elevations]}


def half_material(material: GaussianLobes) -> GaussianLobes:
    """The material as the GPU holds it (:class:`LobeTable`): float16 values at float32 elevations, on the even grid
    through them where there is one (the same parameters at every theta_o, up to the float16 rounding of the
    inserted rows). Idempotent."""
    return LobeTable(material).material


def half_chain(chain: GaussianChain) -> GaussianChain:
    """The chain as its texture holds it: every level rounded to float16 (sigmas as float32 uniforms)."""
    levels = [ChainLevel(sigma=float(np.float32(lv.sigma)), map=_half(lv.map).astype(np.float32), orders=lv.orders)
              for lv in chain.levels]
    return GaussianChain(sigma0=levels[0].sigma, ratio=chain.ratio, levels=levels, report=chain.report)


def lobe_texels(n_lobes: int) -> int:
    """RGBA32UI texels per row of the lobe table: 2 words per lobe and the blue weights two to a word."""
    return (2 * n_lobes + (n_lobes + 1) // 2 + 3) // 4


class GaussianRenderer:
    """One material and one chain on one GL context; :meth:`render` draws the sphere or a mesh from any view."""

    def __init__(self, material: GaussianLobes, chain: GaussianChain, *, ctx: Any = None) -> None:
        import moderngl

        sizes = {lv.map.shape for lv in chain.levels}
        if len(sizes) != 1:
            raise InputError(f"the GL chain needs levels of one size (build_chain(..., uniform_size=True)), got "
                             f"{sorted(sizes)}")
        self.material, self.chain = material, chain
        self.table = LobeTable(material)
        self.ctx = ctx if ctx is not None else create_context()
        words = self.table.words()
        self.lobes = self.ctx.texture((words.shape[1], words.shape[0]), 4, words.tobytes(), dtype="u4")
        self.lobes.filter = (moderngl.NEAREST, moderngl.NEAREST)  # read with texelFetch; the shader interpolates
        self.lobes.repeat_x = self.lobes.repeat_y = False
        h, w = next(iter(sizes))[:2]
        from relight.envmap.exr import to_half_safe

        levels = np.zeros((len(chain.levels), h, w, 4), dtype=np.float16)
        for j, lv in enumerate(chain.levels):
            levels[j, ..., :3] = to_half_safe(np.asarray(lv.map))[0]
        # the levels as the slices of one 3-D texture: one trilinear lookup blends two levels (gaussian.glsl)
        self.chain_tex = self.ctx.texture3d((w, h, len(chain.levels)), 4, levels.tobytes(), dtype="f2")
        self.chain_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.chain_tex.repeat_x = True
        self.chain_tex.repeat_y = self.chain_tex.repeat_z = False
        # the plain baseline's environment: the sharpest level as an ordinary 2-D texture (one bilinear lookup)
        self.env_tex = self.ctx.texture((w, h), 4, np.ascontiguousarray(levels[0]).tobytes(), dtype="f2")
        self.env_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.env_tex.repeat_x = True
        self.env_tex.repeat_y = False
        self._programs: dict[tuple[str, str, int, bool], Any] = {}
        self._quad = self.ctx.buffer(_FULLSCREEN.tobytes())

    def release(self) -> None:
        for obj in (self.lobes, self.chain_tex, self.env_tex, self._quad):
            obj.release()

    def defines(self, obj: str, mode: str = "none", order: int = 3, plain: bool = False) -> dict[str, object]:
        """The shader's defines (also what the viewer passes)."""
        out: dict[str, object] = {**self.table.defines(), "GAUSSIAN_LEVELS": len(self.chain.levels),
                                  "OUTPUT_LINEAR": None}
        if obj == "sphere":
            out["GAUSSIAN_SPHERE"] = None
        if plain:
            out["GAUSSIAN_PLAIN"] = None
        if mode != "none":
            if mode not in VIS_MODES:
                raise InputError(f"unknown visibility mode {mode!r}; expected none or one of {', '.join(VIS_MODES)}")
            validate.int_in_range("GL visibility order (16 coefficients)", order, 0, 3)
            out.update(GAUSSIAN_VISIBILITY=None, VIS_MODE=VIS_MODES[mode], SH_ORDER=int(order))
        return out

    def _program(self, obj: str, mode: str, order: int, plain: bool) -> Any:
        key = (obj, mode, order, plain)
        if key not in self._programs:
            d = self.defines(obj, mode, order, plain)
            self._programs[key] = self.ctx.program(vertex_shader=shaders.build("gaussian.vert.glsl", defines=d),
                                                   fragment_shader=shaders.build("gaussian.frag.glsl", defines=d))
        return self._programs[key]

    def mesh_buffers(self, mesh: TriangleMesh, visibility: NDArray[np.floating] | None = None) -> tuple[Any, Any]:
        """Vertex buffer (position, normal, 16 visibility floats; zeros where missing) and index buffer."""
        nv = mesh.n_vertices
        data = np.zeros((nv, 6 + VIS_COEFFICIENTS), dtype="<f4")
        data[:, :3], data[:, 3:6] = mesh.positions, mesh.normals
        if visibility is not None:
            vis = np.asarray(visibility, dtype=np.float64)
            if vis.ndim != 2 or vis.shape[0] != nv:
                raise InputError(f"visibility must be ({nv}, (F+1)^2), got {vis.shape}")
            m = min(vis.shape[1], VIS_COEFFICIENTS)
            data[:, 6 : 6 + m] = vis[:, :m]
        return (self.ctx.buffer(np.ascontiguousarray(data).tobytes()),
                self.ctx.buffer(np.ascontiguousarray(mesh.faces, dtype="<u4").tobytes()))

    def render(self, view: Sequence[float] | NDArray[np.floating], size: int, *,
               mesh: tuple[Any, Any] | None = None, mode: str = "none", order: int = 3, plain: bool = False,
               frames: int = 1) -> NDArray[np.float32]:
        """A (size, size, 3) float32 image (row 0 at the top; 0 off the object) of the sphere, or of the mesh whose
        :meth:`mesh_buffers` are given, seen along -view; ``frames`` > 1 draws it that many times (timing)."""
        import moderngl

        v = np.asarray(view, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0.0:
            raise InputError(f"view must be a non-zero 3-vector, got {np.asarray(view).tolist()}")
        v = v / np.linalg.norm(v)
        validate.int_in_range("size", size, 1, 4096)
        obj = "sphere" if mesh is None else "mesh"
        if obj == "sphere" and mode != "none":
            raise InputError("visibility needs a mesh (the sphere does not shadow itself)")
        prog = self._program(obj, mode, order, plain)
        right, up = camera_basis(v)
        values: dict[str, Any] = {
            "u_lobes": 0, "u_chain": 1, "u_env": 2,
            **self.table.uniforms(),
            "u_chain_sigma0": float(self.chain.levels[0].sigma),
            "u_chain_log_ratio": math.log(self.chain.levels[1].sigma / self.chain.levels[0].sigma)
            if len(self.chain.levels) > 1 else 1.0,
            "u_view_direction": tuple(float(x) for x in v), "u_viewport": (float(size), float(size)),
            "u_right": tuple(float(x) for x in right), "u_up": tuple(float(x) for x in up),
            "u_view_projection": tuple(view_projection(v, "orthographic", 3.0).T.ravel()),
        }
        for name, value in values.items():
            set_uniform(prog, name, value)
        if mesh is None:
            vao = self.ctx.vertex_array(prog, [(self._quad, "3f", "a_position")])
        else:
            vbo, ibo = mesh
            # visibility attributes not compiled in, or optimised away (AO reads only the DC term), are padding
            vao = vertex_array(self.ctx, prog, vbo, _MESH_LAYOUT, ibo)
        self.lobes.use(location=0)
        self.chain_tex.use(location=1)
        self.env_tex.use(location=2)
        try:
            with float_target(self.ctx, size, size, depth=True) as fbo:
                for _ in range(max(1, frames)):
                    fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
                    self.ctx.enable(moderngl.DEPTH_TEST)
                    self.ctx.disable(moderngl.CULL_FACE)
                    vao.render(moderngl.TRIANGLES, vertices=3 if mesh is None else -1)
                return read_image(fbo)
        finally:
            vao.release()

