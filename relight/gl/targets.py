"""Render targets, read-back and vertex set-up shared by the moderngl renderers (``relight.gl.render``, ``prt``,
``inout``, ``sh_table``, ``gaussian``): an RGBA float32 framebuffer made, bound and released in one place, the image
read-back (row 0 at the top), the per-vertex point pass that the tests probe through, a mesh's vertex and index
buffers, the vertex array over an interleaved buffer, and the uniform setter; the last two skip what the linker
dropped.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

#: Texels per row of a point pass's output (vertex p writes texel ``(p mod POINT_WIDTH, p div POINT_WIDTH)``).
POINT_WIDTH: Final = 2048
#: The interleaved layout of :func:`mesh_buffers`: (attribute, float32 values) per vertex, in order.
MESH_LAYOUT: Final = (("a_position", 3), ("a_normal", 3))


def set_uniform(prog: Any, name: str, value: Any) -> None:
    """Set a uniform if the linker kept it (unused uniforms are optimised away); a one-element list goes to a
    one-element array uniform as its element (moderngl reads such an array as a scalar)."""
    try:
        member = prog[name]
    except KeyError:
        return
    if isinstance(value, list) and getattr(member, "array_length", 0) == 1:
        value = value[0]
    member.value = value


@contextlib.contextmanager
def float_target(ctx: Any, width: int, height: int, *, depth: bool) -> Iterator[Any]:
    """An RGBA float32 framebuffer of ``width x height`` (with a depth buffer when ``depth``), bound with its whole
    area as the viewport; released on exit."""
    color = ctx.texture((width, height), 4, dtype="f4")
    depth_rb = ctx.depth_renderbuffer((width, height)) if depth else None
    fbo = ctx.framebuffer(color_attachments=[color], depth_attachment=depth_rb)
    try:
        fbo.use()
        fbo.viewport = (0, 0, width, height)
        yield fbo
    finally:
        fbo.release()
        color.release()
        if depth_rb is not None:
            depth_rb.release()


def read_rgba(fbo: Any) -> NDArray[np.float32]:
    """The framebuffer's pixels as float32 (height, width, 4), row 0 at the bottom (OpenGL's order)."""
    width, height = fbo.size
    return np.frombuffer(fbo.read(components=4, dtype="f4"), dtype="<f4").reshape(height, width, 4)


def read_image(fbo: Any) -> NDArray[np.float32]:
    """The framebuffer's RGB as a (height, width, 3) float32 image with row 0 at the top."""
    return np.ascontiguousarray(read_rgba(fbo)[::-1, :, :3])


def point_rows(count: int) -> int:
    """Rows of a point pass's output holding ``count`` values (:data:`POINT_WIDTH` a row)."""
    return max(1, -(-count // POINT_WIDTH))


def read_points(ctx: Any, vao: Any, count: int, *, vertices: int,
                instances: int | None = None) -> NDArray[np.float32]:
    """Draw ``vao`` as points (no depth test, culling or blending) into a :func:`point_rows` ``(count)`` x
    :data:`POINT_WIDTH` float target cleared to 0 and return the first ``count`` texels' RGB (count, 3). The vertex
    shader places each point on its texel (its ``u_output_size`` uniform is ``(POINT_WIDTH, point_rows(count))``)."""
    import moderngl

    with float_target(ctx, POINT_WIDTH, point_rows(count), depth=False) as fbo:
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        if instances is None:
            vao.render(moderngl.POINTS, vertices=vertices)
        else:
            vao.render(moderngl.POINTS, vertices=vertices, instances=instances)
        raw = read_rgba(fbo).reshape(-1, 4)
    return np.asarray(raw[:count, :3])


def mesh_buffers(ctx: Any, mesh: Any) -> tuple[Any, Any]:
    """A triangle mesh's vertex buffer (:data:`MESH_LAYOUT`: positions and normals, float32) and index buffer
    (uint32 faces)."""
    inter = np.concatenate([mesh.positions, mesh.normals], axis=1).astype("<f4")
    return ctx.buffer(inter.tobytes()), ctx.buffer(np.ascontiguousarray(mesh.faces, dtype="<u4").tobytes())


def vertex_array(ctx: Any, prog: Any, vbo: Any, layout: Sequence[tuple[str, int]], ibo: Any = None) -> Any:
    """The vertex array of ``prog`` over one interleaved float32 buffer whose vertices hold ``layout``'s attributes
    in order (name, float count). Attributes the program does not use (not compiled in, or dropped by the linker)
    are skipped as padding; indexed by ``ibo`` (uint32) when given."""
    used = [name for name, _ in layout if prog.get(name, None) is not None]
    fmt = " ".join(f"{k}f" if name in used else f"{4 * k}x" for name, k in layout)
    content = [(vbo, fmt, *used)] if used else []
    if ibo is not None:
        return ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4)
    return ctx.vertex_array(prog, content)
