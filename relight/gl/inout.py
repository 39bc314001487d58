"""In-out factorized PRT on the GPU (moderngl, EGL; Mesa llvmpipe works): eq. 4 of Mahajan, Tseng & Ramamoorthi
2008 per vertex, the same GLSL as the viewer (``web/shaders/inout.vert.glsl``, fragment ``sh_table.frag.glsl``).

Uploads: the per-vertex transport ``T`` (V, K, (F+1)^2) of ``relight.inout_prt`` as a float16 data texture
(``relight.vertex_texture.pack_float16``, as the service would serve it) and the factors' ``sigma_k h_k`` profiles
with their (m, parity) as an R32F texture of K rows. The mesh is drawn indexed from its canonical arrays, so
``gl_VertexID`` indexes the transport; the camera is ``relight.gl.render``'s orthographic one with the mesh moved
into the unit ball (``relight.gl.prt.model_matrix``). Lighting and view are uniforms: a new frame, not new data.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.gl import shaders
from relight.gl.prt import model_matrix
from relight.gl.render import ORTHO_DISTANCE, create_context, view_projection
from relight.gl.targets import (
    MESH_LAYOUT,
    POINT_WIDTH,
    float_target,
    mesh_buffers,
    point_rows,
    read_image,
    read_points,
    set_uniform,
    vertex_array,
)
from relight.inout_factors import InOutFactors
from relight.mesh.model import TriangleMesh
from relight.vertex_texture import pack_float16


def factor_texture(factors: InOutFactors) -> NDArray[np.float32]:
    """(K, N + 2) float32 rows: m, parity, then sigma_k times h_k's radial profile (the shader's ``u_factors``)."""
    out = np.empty((factors.terms, factors.theta.size + 2), dtype=np.float32)
    out[:, 0], out[:, 1] = factors.m, factors.parity
    out[:, 2:] = factors.sigma[:, None] * factors.h
    return out


class InOutRenderer:
    """One mesh, its factors and its per-vertex transport on the GPU (module docstring)."""

    def __init__(self, mesh: TriangleMesh, factors: InOutFactors, transport: ArrayLike, *, ctx: Any = None) -> None:
        t = np.asarray(transport, dtype=np.float64)
        if t.ndim != 3 or t.shape[:2] != (mesh.n_vertices, factors.terms):
            raise InputError(f"transport must be ({mesh.n_vertices}, {factors.terms}, n), got shape {t.shape}")
        order = int(round(np.sqrt(t.shape[2]))) - 1
        if (order + 1) ** 2 != t.shape[2]:
            raise InputError(f"the transport's last axis must be (F+1)^2 long, got {t.shape[2]}")
        self.mesh, self.factors, self.order = mesh, factors, order
        self.ctx = ctx if ctx is not None else create_context()
        self.vbo, self.ibo = mesh_buffers(self.ctx, mesh)
        tex, lay = pack_float16(t)
        #: the transport as uploaded (float16-rounded), for CPU references
        self.uploaded = np.asarray(tex, dtype=np.float64).reshape(-1, 4)[: mesh.n_vertices * lay["texels_per_vertex"]]
        self.uploaded = self.uploaded.reshape(mesh.n_vertices, -1)[:, : t[0].size].reshape(t.shape)
        self.transport = self.ctx.texture((lay["width"], lay["height"]), 4, np.ascontiguousarray(tex, "<f2").tobytes(),
                                          dtype="f2")
        ft = factor_texture(factors)
        self.factor_tex = self.ctx.texture((ft.shape[1], ft.shape[0]), 1, ft.tobytes(), dtype="f4")
        for tx in (self.transport, self.factor_tex):
            tx.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        self._progs: dict[tuple[bool, int], Any] = {}

    def release(self) -> None:
        for obj in (self.vbo, self.ibo, self.transport, self.factor_tex, *self._progs.values()):
            obj.release()

    def program(self, probe: bool = False, terms: int | None = None) -> Any:
        """The program summing the first ``terms`` stored terms (all by default; whole pairs are the caller's)."""
        k = self.factors.terms if terms is None else int(terms)
        validate.int_in_range("terms", k, 1, self.factors.terms)
        key = (probe, k)
        if key not in self._progs:
            defs: dict[str, object] = {"INOUT_ORDER": self.order, "INOUT_TERMS": k,
                                       "INOUT_STORED": self.factors.terms, "OUTPUT_LINEAR": None}
            if probe:
                defs["PROBE"] = None
            self._progs[key] = self.ctx.program(
                vertex_shader=shaders.build("inout.vert.glsl", defines=defs),
                fragment_shader=shaders.build("sh_table.frag.glsl", defines={"OUTPUT_LINEAR": None}))
        return self._progs[key]

    def _uniforms(self, prog: Any, lighting: ArrayLike, view: ArrayLike) -> None:
        light = np.asarray(lighting, dtype=np.float64)
        n = (self.order + 1) ** 2
        if light.ndim != 2 or light.shape[0] < n or light.shape[1] != 3:
            raise InputError(f"lighting must be (>= {n}, 3) real coefficients, got shape {light.shape}")
        v = np.asarray(view, dtype=np.float64)
        set_uniform(prog, "u_light", [tuple(float(x) for x in row) for row in light[:n]])
        set_uniform(prog, "u_view", tuple(float(x) for x in v / np.linalg.norm(v)))
        set_uniform(prog, "u_eye", (0.0, 0.0, 0.0, 0.0))
        set_uniform(prog, "u_transport", 0)
        set_uniform(prog, "u_factors", 1)
        self.transport.use(location=0)
        self.factor_tex.use(location=1)

    def _vao(self, prog: Any, indexed: bool) -> Any:
        return vertex_array(self.ctx, prog, self.vbo, MESH_LAYOUT, self.ibo if indexed else None)

    def probe(self, lighting: ArrayLike, view: ArrayLike, terms: int | None = None) -> NDArray[np.float32]:
        """Every vertex's radiance (V, 3) through the vertex shader, summing the first ``terms`` terms (one point
        per vertex; tests)."""
        prog = self.program(probe=True, terms=terms)
        self._uniforms(prog, lighting, view)
        n = self.mesh.n_vertices
        set_uniform(prog, "u_output_size", (POINT_WIDTH, point_rows(n)))
        vao = self._vao(prog, indexed=False)
        try:
            return read_points(self.ctx, vao, n, vertices=n)
        finally:
            vao.release()

    def draw(self, lighting: ArrayLike, view: ArrayLike, size: int) -> NDArray[np.float32]:
        """A (size, size, 3) float32 image (row 0 at the top) from the orthographic camera looking along -view."""
        import moderngl

        validate.int_in_range("size", size, 1, 4096)
        v = np.asarray(view, dtype=np.float64)
        v = v / np.linalg.norm(v)
        prog = self.program()
        self._uniforms(prog, lighting, v)
        set_uniform(prog, "u_view_projection", tuple(view_projection(v, "orthographic", ORTHO_DISTANCE).T.ravel()))
        set_uniform(prog, "u_model", tuple(model_matrix(self.mesh).T.ravel()))
        vao = self._vao(prog, indexed=True)
        try:
            with float_target(self.ctx, size, size, depth=True) as fbo:
                self.ctx.enable(moderngl.DEPTH_TEST)
                self.ctx.disable(moderngl.CULL_FACE)
                fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
                vao.render(moderngl.TRIANGLES)
                return read_image(fbo)
        finally:
            vao.release()
