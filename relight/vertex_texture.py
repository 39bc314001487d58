"""Per-vertex data as float16 RGBA data textures, indexed by vertex id (``docs/conventions.md``, "Meshes").

Layout: a vertex's ``n`` values occupy ``t = ceil(n / 4)`` consecutive RGBA texels (value k in texel ``k // 4``,
channel ``k % 4``, unused channels 0); vertex v's first texel has the linear index ``v t``, at row
``(v t) // width`` and column ``(v t) % width`` of a ``width``-texel-wide texture (rows padded with 0). A shader
fetches value k of vertex ``gl_VertexID`` with ``texelFetch`` at that row and column. Values beyond the float16
range (+-65504) are clamped, never turned into infinity, and counted (as EXR outputs, ``docs/conventions.md``).
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

#: Largest finite float16.
HALF_MAX: Final = 65504.0
#: Default texture width: within every WebGL2 implementation's MAX_TEXTURE_SIZE (at least 2048, spec §6.2).
DEFAULT_WIDTH: Final = 2048


def pack_float16(values: NDArray[np.floating], width: int = DEFAULT_WIDTH) -> tuple[NDArray[np.float16],
                                                                                      dict[str, Any]]:
    """Pack (V, ...) per-vertex values (flattened per vertex) into a (rows, width, 4) float16 texture and its
    manifest (module docstring)."""
    a = np.asarray(values, dtype=np.float64)
    if a.ndim < 1 or a.shape[0] == 0:
        raise InputError(f"need per-vertex values of shape (V, ...), got {a.shape}")
    validate.finite_array("per-vertex values", a)
    validate.positive_int("texture width", width)
    v = a.shape[0]
    flat = a.reshape(v, -1)
    n = flat.shape[1]
    t = -(-n // 4)
    padded = np.zeros((v, 4 * t))
    padded[:, :n] = flat
    clamped = int(np.count_nonzero(np.abs(padded) > HALF_MAX))
    texels = np.clip(padded, -HALF_MAX, HALF_MAX).reshape(v * t, 4)
    rows = -(-(v * t) // width)
    out = np.zeros((rows * width, 4), dtype=np.float16)
    out[: v * t] = texels.astype(np.float16)
    manifest = {"vertices": v, "values_per_vertex": n, "value_shape": list(a.shape[1:]), "texels_per_vertex": t,
                "width": width, "height": rows, "format": "RGBA16F", "clamped": clamped}
    return out.reshape(rows, width, 4), manifest


def unpack_float16(texture: NDArray[np.float16], manifest: dict[str, Any]) -> NDArray[np.float32]:
    """Inverse of :func:`pack_float16` (values as float32 in their original per-vertex shape)."""
    v, n, t = int(manifest["vertices"]), int(manifest["values_per_vertex"]), int(manifest["texels_per_vertex"])
    flat = np.asarray(texture, dtype=np.float32).reshape(-1, 4)[: v * t].reshape(v, 4 * t)[:, :n]
    return flat.reshape((v, *manifest["value_shape"]))
