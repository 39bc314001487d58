"""SH-table shading on the GPU (moderngl, EGL; Mesa llvmpipe works): seed 003's three rendering modes.

Kautz, Sloan & Snyder 2002, §4: at each vertex p with frame rows ``(t, b, n)``, (1) rotate the world lighting into
the local frame, (2) rotate the view, (3) look the table up at the local view, (4) ``Q_p = sum_i L_{p,i} c_i(v_p)``
(eq. 1). The paper rotated the lighting on the host ("too complicated for current graphics hardware"); here it is
``web/shaders/sh_rotation.glsl`` (Ivanic–Ruedenberg from the 3 x 3 frame, the parity rule of
docs/conventions.md), run per vertex in ``web/shaders/sh_table.vert.glsl``, the same GLSL as the viewer
(``web/src/sh_table.js``). Modes (:data:`MODES`):

* ``general``: view and lighting both change; steps 1-4 per vertex every frame.
* ``fixed-light``: ``L_p`` computed once per lighting on the GPU (a PRECOMPUTE pass into a float32 vertex data
  texture, texel ``p * n + i``), per frame steps 2-4.
* ``fixed-view``: the table at ``v_p`` turned to the world frame, ``(S M)^T c(v_p)``, computed once per view (zero
  where the vertex faces away); per frame one n-term dot product with the world lighting.
* ``transfer`` (PRT, §5): per vertex the folded transfer matrix ``T'_p = S M(R_p) T_p`` (``relight.sh_prt``) as
  RGBA16F rows (:meth:`TableRenderer.set_transfer`); per frame ``L_p = T'_p L'`` then steps 3-4. View and lighting
  both free; shadows from ``T_p``.

The table is a texture array of n RGB16F layers (the ``.exr`` / viewer data: float16, grey tables repeated in R, G,
B), bilinear and clamped to the edge, exactly ``SHTable.lookup(exact_azimuth=False)`` on the CPU. Shading is per
vertex (Gouraud); :meth:`TableRenderer.probe` evaluates the same vertex shader at arbitrary frames (one point per
frame into a float target) for tests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError
from relight.gl import shaders
from relight.gl.render import ORTHO_DISTANCE, create_context, view_projection
from relight.gl.targets import POINT_WIDTH, float_target, point_rows, read_image, read_points, set_uniform, vertex_array
from relight.view_maps import check_layout

Mode = Literal["general", "fixed-light", "fixed-view", "transfer"]
#: The paper's three rendering modes (§4); ``transfer`` is PRT (§5, :meth:`TableRenderer.set_transfer`).
MODES: Final[tuple[Mode, ...]] = ("general", "fixed-light", "fixed-view")
_MODE_DEFINE: Final = {"general": "MODE_GENERAL", "fixed-light": "MODE_FIXED_LIGHT", "fixed-view": "MODE_FIXED_VIEW",
                       "transfer": "MODE_TRANSFER"}
#: Width of the float targets of probes and per-vertex data (texels); rows as needed.
DATA_WIDTH: Final = 2048


def shader_defines(order: int, layout: str, mode: Mode, target: str | None = None) -> dict[str, object]:
    """The defines of ``sh_table.vert.glsl`` (also what ``web/src/sh_table.js`` passes)."""
    if mode not in _MODE_DEFINE:
        raise InputError(f"unknown SH-table mode {mode!r}; valid modes are {list(_MODE_DEFINE)}")
    lay = check_layout(layout)
    out: dict[str, object] = {"SH_ORDER": int(order),
                              "TABLE_PARABOLIC" if lay == "parabolic" else "TABLE_HEMI_OCTAHEDRAL": None,
                              _MODE_DEFINE[mode]: None, "OUTPUT_LINEAR": None}
    if target is not None:
        out[target] = None
    return out


def vertex_tangents(frames: ArrayLike) -> NDArray[np.float32]:
    """glTF-style tangents (N, 4) of frames (N, 3, 3) with rows (t, b, n): xyz = t, w = sign(det)."""
    f = np.asarray(frames, dtype=np.float64)
    w = np.where(np.linalg.det(f) < 0.0, -1.0, 1.0)
    return np.ascontiguousarray(np.concatenate([f[:, 0], w[:, None]], axis=1), dtype="<f4")


#: The interleaved vertex layout of :meth:`TableRenderer.geometry`.
_LAYOUT: Final = (("a_position", 3), ("a_normal", 3), ("a_tangent", 4))


def _rows(count: int) -> int:
    return max(1, -(-count // DATA_WIDTH))


@dataclass
class _Geometry:
    count: int
    vbo: Any
    ibo: Any | None


class TableRenderer:
    """One SH table on the GPU (module docstring). ``coefficients`` (R, R, n, C) with C = 1 or 3 are rounded to
    float16 on upload; :attr:`uploaded` holds the float16 values as float64 (the CPU reference's input)."""

    def __init__(self, coefficients: ArrayLike, layout: str, *, ctx: Any = None) -> None:
        import moderngl

        from relight.envmap.exr import to_half_safe

        c = np.asarray(coefficients, dtype=np.float64)
        if c.ndim != 4 or c.shape[0] != c.shape[1] or c.shape[3] not in (1, 3):
            raise InputError(f"table coefficients must be (R, R, n, 1 or 3), got shape {c.shape}")
        order = int(round(np.sqrt(c.shape[2]))) - 1
        if (order + 1) ** 2 != c.shape[2]:
            raise InputError(f"a table holds (F+1)^2 coefficients per texel, got {c.shape[2]}")
        self.order, self.layout, self.n = order, check_layout(layout), c.shape[2]
        self.ctx = ctx if ctx is not None else create_context()
        half = np.broadcast_to(to_half_safe(c)[0], c.shape[:3] + (3,))
        self.uploaded = np.asarray(half, dtype=np.float64)
        res = c.shape[0]
        layers = np.ascontiguousarray(np.transpose(half, (2, 0, 1, 3)), dtype="<f2")  # (n, R rows, R, 3)
        self.table = self.ctx.texture_array((res, res, self.n), 3, layers.tobytes(), dtype="f2")
        self.table.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.table.repeat_x = self.table.repeat_y = False
        self._progs: dict[tuple[Mode, str | None], Any] = {}
        self._data: Any = None

    def release(self) -> None:
        self.table.release()
        if self._data is not None:
            self._data.release()
        for prog in self._progs.values():
            prog.release()

    def program(self, mode: Mode, target: str | None = None) -> Any:
        key = (mode, target)
        if key not in self._progs:
            defs = shader_defines(self.order, self.layout, mode, target)
            self._progs[key] = self.ctx.program(
                vertex_shader=shaders.build("sh_table.vert.glsl", defines=defs),
                fragment_shader=shaders.build("sh_table.frag.glsl", defines={"OUTPUT_LINEAR": None}))
        return self._progs[key]

    # ------------------------------------------------------------------------------------------- geometry
    def geometry(self, positions: ArrayLike, normals: ArrayLike, frames: ArrayLike,
                 faces: ArrayLike | None = None) -> _Geometry:
        """Vertex buffers (position, normal, tangent) and an optional index buffer for :meth:`draw`."""
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        tan = vertex_tangents(frames)
        if not pos.shape[0] == nrm.shape[0] == tan.shape[0]:
            raise InputError("positions, normals and frames must have one row per vertex")
        inter = np.concatenate([pos, nrm, tan], axis=1).astype("<f4")
        ibo = None
        if faces is not None:
            ibo = self.ctx.buffer(np.ascontiguousarray(np.asarray(faces).reshape(-1), dtype="<u4").tobytes())
        return _Geometry(pos.shape[0], self.ctx.buffer(inter.tobytes()), ibo)

    def _vao(self, prog: Any, geo: _Geometry, indexed: bool) -> Any:
        # fixed-view uses no attribute: everything comes from the data texture
        return vertex_array(self.ctx, prog, geo.vbo, _LAYOUT, geo.ibo if indexed else None)

    def _uniforms(self, prog: Any, view: ArrayLike, lighting: ArrayLike | None) -> None:
        v = np.asarray(view, dtype=np.float64)
        v = v / np.linalg.norm(v)
        set_uniform(prog, "u_view", tuple(float(x) for x in v))
        if lighting is not None:
            light = np.asarray(lighting, dtype=np.float64)
            if light.ndim != 2 or light.shape[0] < self.n or light.shape[1] != 3:
                raise InputError(f"lighting must be (>= {self.n}, 3) real coefficients, got shape {light.shape}")
            set_uniform(prog, "u_light", [tuple(float(x) for x in row) for row in light[: self.n]])
        set_uniform(prog, "u_table", 0)
        set_uniform(prog, "u_vertex_data", 1)
        self.table.use(location=0)
        if self._data is not None:
            self._data.use(location=1)

    def _points(self, prog: Any, geo: _Geometry, count: int, instances: int) -> NDArray[np.float32]:
        set_uniform(prog, "u_output_size", (POINT_WIDTH, point_rows(count)))
        vao = self._vao(prog, geo, indexed=False)
        try:
            return read_points(self.ctx, vao, count, vertices=geo.count, instances=instances)
        finally:
            vao.release()

    # ------------------------------------------------------------------------------------------ passes
    def set_transfer(self, folded: ArrayLike) -> None:
        """Upload folded transfer matrices (V, n, n) for ``transfer`` (float16: rows padded to a multiple of 4
        values, one RGBA16F texel per 4, vertex p from texel ``p n ceil(n / 4)``, DATA_WIDTH texels a row)."""
        from relight.envmap.exr import to_half_safe

        t = np.asarray(folded, dtype=np.float64)
        if t.ndim != 3 or t.shape[1:] != (self.n, self.n):
            raise InputError(f"folded transfer must be (V, {self.n}, {self.n}), got shape {t.shape}")
        row = -(-self.n // 4) * 4
        padded = np.zeros((t.shape[0], self.n, row))
        padded[:, :, : self.n] = t
        texels = padded.reshape(-1, 4)
        rows = _rows(texels.shape[0])
        data = np.zeros((rows * DATA_WIDTH, 4), dtype="<f2")
        data[: texels.shape[0]] = to_half_safe(texels)[0]
        if self._data is not None:
            self._data.release()
        self._data = self.ctx.texture((DATA_WIDTH, rows), 4, data.tobytes(), dtype="f2")
        self._data.filter = (self.ctx.NEAREST, self.ctx.NEAREST)

    def prepare(self, mode: Mode, geo: _Geometry, *, view: ArrayLike, lighting: ArrayLike) -> None:
        """The fixed modes' per-vertex data (module docstring) into the vertex data texture; ``general`` and
        ``transfer`` (whose data :meth:`set_transfer` uploads): none."""
        if mode in ("general", "transfer"):
            return
        prog = self.program(mode, "PRECOMPUTE")
        self._uniforms(prog, view, lighting)
        data = self._points(prog, geo, geo.count * self.n, self.n)
        if self._data is not None:
            self._data.release()
        padded = np.zeros((_rows(data.shape[0]) * DATA_WIDTH, 4), dtype="<f4")
        padded[: data.shape[0], :3] = data
        self._data = self.ctx.texture((DATA_WIDTH, _rows(data.shape[0])), 4, padded.tobytes(), dtype="f4")
        self._data.filter = (self.ctx.NEAREST, self.ctx.NEAREST)

    def vertex_data(self) -> NDArray[np.float32]:
        """The current per-vertex data texture as (texels, 3) (tests)."""
        if self._data is None:
            raise InputError("no per-vertex data: call prepare() with a fixed mode first")
        return np.frombuffer(self._data.read(), dtype="<f4").reshape(-1, 4)[:, :3].copy()

    def probe(self, mode: Mode, normals: ArrayLike, frames: ArrayLike, view: ArrayLike,
              lighting: ArrayLike) -> NDArray[np.float32]:
        """``Q`` (N, 3) at N points with world frames (N, 3, 3) and normals (N, 3), through ``mode``'s vertex shader
        (the fixed modes prepare their per-vertex data from the same lighting and view first)."""
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        geo = self.geometry(np.zeros_like(nrm), nrm, frames)
        try:
            self.prepare(mode, geo, view=view, lighting=lighting)
            prog = self.program(mode, "PROBE")
            self._uniforms(prog, view, lighting)
            return self._points(prog, geo, geo.count, 1)
        finally:
            geo.vbo.release()

    def draw(self, mode: Mode, geo: _Geometry, view: ArrayLike, lighting: ArrayLike | None, size: int,
             *, background: float = 0.0, frames: int = 1) -> NDArray[np.float32]:
        """A (size, size, 3) float32 image (row 0 at the top) of the geometry from the orthographic camera of
        ``relight.gl.render`` looking along -view; the fixed modes use the data of the last :meth:`prepare`.
        ``frames`` > 1 draws that many frames (the view turning by 1 degree about +Y per frame, the lighting kept)
        before the read-back, for timing (bench/shtable_modes.py)."""
        import moderngl

        validate.int_in_range("size", size, 1, 4096)
        validate.at_least("frames", frames, 1)
        v = np.asarray(view, dtype=np.float64)
        v = v / np.linalg.norm(v)
        prog = self.program(mode)
        self._uniforms(prog, v, lighting)
        vao = self._vao(prog, geo, indexed=True)
        try:
            with float_target(self.ctx, size, size, depth=True) as fbo:
                self.ctx.enable(moderngl.DEPTH_TEST)
                self.ctx.disable(moderngl.CULL_FACE)
                for k in range(frames - 1, -1, -1):  # the last frame is the asked-for view
                    c, s = np.cos(np.radians(k)), np.sin(np.radians(k))
                    vk = np.array([c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]])
                    if mode != "fixed-view":  # fixed-view: the view the data was prepared for (the camera moves)
                        set_uniform(prog, "u_view", tuple(float(x) for x in vk))
                    set_uniform(prog, "u_view_projection",
                         tuple(view_projection(vk, "orthographic", ORTHO_DISTANCE).T.ravel()))
                    fbo.clear(background, background, background, 1.0, depth=1.0)
                    vao.render(moderngl.TRIANGLES)
                return read_image(fbo)
        finally:
            vao.release()

