"""Cube maps: face geometry (OpenGL 4.6 core specification, section 8.13, table 8.19), cutting single-image
layouts into faces, and solid-angle-aware resampling to the project's lat-long layout.

Face order is OpenGL's (``GL_TEXTURE_CUBE_MAP_POSITIVE_X`` + i): +X, -X, +Y, -Y, +Z, -Z. Directions are
project directions (:mod:`relight.conventions`, +Y up), taken literally as the ``r`` of table 8.19.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

F32 = NDArray[np.float32]

#: Cube-map face order (OpenGL: GL_TEXTURE_CUBE_MAP_POSITIVE_X + i).
FACE_NAMES: Final = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
#: Cube-map layouts :func:`relight.envmap.read_envmap` and :func:`cube_faces_from_image` know, with their aspect
#: (W, H) in faces.
CUBE_LAYOUTS: Final = {"strip-h": (6, 1), "strip-v": (1, 6), "cross-h": (4, 3), "cross-v": (3, 4)}


def layout_for_size(width: int, height: int) -> str | None:
    """The cube-map layout whose aspect ratio a ``width x height`` image has (whole faces), or None."""
    return next((n for n, (a, b) in CUBE_LAYOUTS.items() if width * b == height * a and width % a == 0), None)


def cube_face_dirs(size: int) -> NDArray[np.float64]:
    """Unit directions of every texel centre of a cube map, shape (6, size, size, 3), faces in FACE_NAMES order.

    Texel (row r, column c) has ``s = (c + 0.5) / size``, ``t = (r + 0.5) / size`` and, with ``a = 2 s - 1``,
    ``b = 2 t - 1``, the direction given by inverting OpenGL 4.6 table 8.19 (see :func:`cube_to_latlong`).
    """
    validate.positive_int("cube face size", size)
    g = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    return _face_uv_to_dirs(g[None, :, None], g[None, None, :], np.arange(6)[:, None, None])


def _face_uv_to_dirs(b: NDArray[np.float64], a: NDArray[np.float64], face: NDArray[np.int_]) -> NDArray[np.float64]:
    """Inverse of table 8.19: face, ``a = 2s - 1`` (columns), ``b = 2t - 1`` (rows) -> unit direction."""
    a, b, face = np.broadcast_arrays(a, b, face)
    m = _FACE_AXES[face]  # (..., 3 [a, b, 1], 3 [x, y, z]): each component is +-a, +-b or +-1
    d = a[..., None] * m[..., 0, :] + b[..., None] * m[..., 1, :] + m[..., 2, :]
    return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True), dtype=np.float64)


#: Per face of table 8.19, the (unnormalised) direction as rows of coefficients of ``a``, ``b`` and 1:
#: +X (1, -b, -a), -X (-1, -b, a), +Y (a, 1, b), -Y (a, -1, -b), +Z (a, -b, 1), -Z (-a, -b, -1).
_FACE_AXES = np.array([
    [[0, 0, -1], [0, -1, 0], [1, 0, 0]],
    [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],
    [[1, 0, 0], [0, 0, 1], [0, 1, 0]],
    [[1, 0, 0], [0, 0, -1], [0, -1, 0]],
    [[1, 0, 0], [0, -1, 0], [0, 0, 1]],
    [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],
], dtype=np.float64)


def _dirs_to_face_uv(x: NDArray[Any], y: NDArray[Any], z: NDArray[Any]) -> tuple[NDArray[np.intp], NDArray[Any],
                                                                             NDArray[Any]]:
    """OpenGL 4.6 table 8.19: direction components -> (face, s, t), ``s, t`` in [0, 1]. Ties go to x, then y.

    Written per axis: ``+-X``: ``sc = -sign(rx) rz``, ``tc = -ry``; ``+-Y``: ``sc = rx``, ``tc = sign(ry) rz``;
    ``+-Z``: ``sc = sign(rz) rx``, ``tc = -ry``; ``ma`` is the major component.
    """
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    is_x = (ax >= ay) & (ax >= az)
    is_y = ~is_x & (ay >= az)
    is_z = ~is_x & ~is_y
    neg = np.where(is_x, x < 0, np.where(is_y, y < 0, z < 0))
    face = (np.where(is_x, 0, np.where(is_y, 2, 4)) + neg).astype(np.intp)
    sign = np.where(neg, -1.0, 1.0).astype(x.dtype)
    ma = np.maximum(np.where(is_x, ax, np.where(is_y, ay, az)), np.finfo(x.dtype).tiny)
    sc = np.where(is_x, -sign * z, np.where(is_z, sign * x, x))
    tc = np.where(is_y, sign * z, -y)
    half = x.dtype.type(0.5)
    return face, (sc / ma + 1) * half, (tc / ma + 1) * half


def faces_array(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating]) -> NDArray[np.float32]:
    """Cube faces as one (6, S, S, C) float32 array, from a dict keyed by FACE_NAMES or an array (6, S, S[, C])."""
    if isinstance(faces, Mapping):
        missing = [n for n in FACE_NAMES if n not in faces]
        extra = [n for n in faces if n not in FACE_NAMES]
        if missing or extra:
            raise InputError(f"cube faces must be named {', '.join(FACE_NAMES)}; missing {missing}, unknown {extra}")
        arrs = [np.asarray(faces[n], dtype=np.float32) for n in FACE_NAMES]
        if len({a.shape for a in arrs}) != 1:
            raise InputError(f"cube faces differ in shape: {[a.shape for a in arrs]}")
        cube = np.stack(arrs)
    else:
        cube = np.asarray(faces, dtype=np.float32)
    if cube.ndim == 3:
        cube = cube[..., None]
    if cube.ndim != 4 or cube.shape[0] != 6 or cube.shape[1] != cube.shape[2] or cube.shape[1] == 0:
        raise InputError(f"cube faces must have shape (6, S, S[, C]) with S > 0, got {cube.shape}")
    return cube


def cube_faces_from_image(image: NDArray[np.floating], layout: str = "auto") -> NDArray[np.float32]:
    """Cut one image holding a cube map into faces, shape (6, S, S, C) in FACE_NAMES order.

    Layouts (each cell is one S x S face, stored exactly as an OpenGL face image, row 0 = ``t = 0``):

    * ``"strip-h"`` (6S x S): +X, -X, +Y, -Y, +Z, -Z from left to right;
    * ``"strip-v"`` (S x 6S): the same order from top to bottom;
    * ``"cross-h"`` (4S x 3S): middle row -X, +Z, +X, -Z; +Y above +Z, -Y below +Z (the faces fold edge to edge
      without rotation under the table-8.19 convention);
    * ``"cross-v"`` (3S x 4S): the horizontal cross with -Z moved below -Y and turned 180 degrees so that its
      edges still meet their neighbours: rows ``+Y`` / ``-X +Z +X`` / ``-Y`` / ``-Z`` (rotated), in column 1.

    ``"auto"`` picks the layout from the aspect ratio.
    """
    img = np.asarray(image, dtype=np.float32)
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3:
        raise InputError(f"a cube-map image must have shape (H, W[, C]), got {img.shape}")
    h, w = img.shape[:2]
    if layout == "auto":
        layout = layout_for_size(w, h) or ""
    if layout not in CUBE_LAYOUTS:
        raise InputError(f"image is {w} x {h}: not a cube-map layout ({', '.join(CUBE_LAYOUTS)}), or unknown "
                         f"layout {layout!r}")
    a, b = CUBE_LAYOUTS[layout]
    s = w // a
    if s == 0 or w != a * s or h != b * s:
        raise InputError(f"image is {w} x {h}: a {layout} cube map must be {a}S x {b}S pixels")
    cells = {
        "strip-h": [(0, i) for i in range(6)],
        "strip-v": [(i, 0) for i in range(6)],
        "cross-h": [(1, 2), (1, 0), (0, 1), (2, 1), (1, 1), (1, 3)],
        "cross-v": [(1, 2), (1, 0), (0, 1), (2, 1), (1, 1), (3, 1)],
    }[layout]
    faces = np.stack([img[r * s:(r + 1) * s, c * s:(c + 1) * s] for r, c in cells])
    if layout == "cross-v":
        faces[5] = faces[5, ::-1, ::-1]
    return faces


def cube_to_latlong(faces: Mapping[str, NDArray[np.floating]] | NDArray[np.floating], height: int, *,
                    samples: int | None = None) -> F32:
    """Resample a cube map to a lat-long map of shape (height, 2 height, C), solid-angle aware.

    Faces: a dict keyed ``"+X", "-X", "+Y", "-Y", "+Z", "-Z"`` or an array (6, S, S[, C]) in that order
    (``GL_TEXTURE_CUBE_MAP_POSITIVE_X`` + i). Each face is an image whose row 0 is ``t = 0`` and column 0 is
    ``s = 0``; texel centres sit at ``(i + 0.5) / S``.

    Face selection and coordinates follow the OpenGL 4.6 core specification, section 8.13, table 8.19: for a
    direction ``r = (rx, ry, rz)`` the major axis picks the face and ``(sc, tc, ma)``

    ======  =====  =====  =====
    face     sc     tc     ma
    ======  =====  =====  =====
    +X      -rz    -ry    rx
    -X      +rz    -ry    rx
    +Y      +rx    +rz    ry
    -Y      +rx    -rz    ry
    +Z      +rx    -ry    rz
    -Z      -rx    -ry    rz
    ======  =====  =====  =====

    then ``s = (sc / |ma| + 1) / 2``, ``t = (tc / |ma| + 1) / 2``. The direction ``r`` is taken literally as a
    project direction (:mod:`relight.conventions`, +Y up), so the lat-long pixel for ``d`` holds what an OpenGL
    ``texture(samplerCube, d)`` lookup returns. (Table 8.19 is a left-handed, RenderMan-style frame: a face image
    looks mirrored from the cube's centre. That is the standard for cube-map files; no flip is applied.)

    Notes
    -----
    Each output pixel is the average of the cube map over the pixel's footprint on the sphere, weighted by solid
    angle. The footprint is split into ``n x n`` cells of equal solid angle (uniform in ``cos theta`` and in
    ``phi``); the cube map is sampled bilinearly at each cell centre (across face edges, from the neighbouring
    face, as OpenGL seamless cube maps do) and the ``n^2`` samples are averaged::

        L(i, j) = (1 / n^2) sum_{k,l} L_cube(d(z_k, phi_l)),   z_k uniform in [cos theta_i+, cos theta_i-]

    ``n`` (``samples``) defaults to about twice the ratio of output pixel size to cube texel size, so every
    texel is seen by several samples and the radiance integral is preserved to well under 1 %.
    """
    cube = faces_array(faces)
    if not np.isfinite(cube).all():
        raise InputError(f"cube faces contain {int(np.sum(~np.isfinite(cube)))} non-finite values (NaN/Inf)")
    height = validate.positive_int("output height", height)
    size, channels = cube.shape[1], cube.shape[3]
    width = 2 * height
    n = int(samples) if samples is not None else max(2, math.ceil(8.0 * size / height))
    validate.positive_int("samples", n)
    planes = np.ascontiguousarray(_pad_cube(cube).reshape(-1, channels).T, dtype=np.float32)
    # Equal-area sub-sample grid: z = cos(theta) uniform in each row band, phi uniform in each column.
    z_edges = np.cos(np.arange(height + 1) * np.pi / height)
    frac = (np.arange(n) + 0.5) / n
    z = (z_edges[:-1, None] + (z_edges[1:] - z_edges[:-1])[:, None] * frac[None, :]).reshape(-1)
    phi = ((np.arange(width)[:, None] + frac[None, :]).reshape(-1) / width - 0.5) * 2.0 * np.pi
    cos_phi, sin_phi = np.cos(phi).astype(np.float32), np.sin(phi).astype(np.float32)
    out = np.empty((height, width, channels), dtype=np.float32)
    rows_per_chunk = max(1, (1 << 19) // (width * n * n))
    for r0 in range(0, height, rows_per_chunk):  # chunks of output rows, to bound memory
        r1 = min(height, r0 + rows_per_chunk)
        zc = z[r0 * n:r1 * n, None]
        rho = np.sqrt(np.maximum(0.0, 1.0 - zc * zc)).astype(np.float32)
        dy = np.broadcast_to(zc.astype(np.float32), (zc.shape[0], cos_phi.size))
        vals = _sample_padded(planes, size, rho * cos_phi, dy, rho * sin_phi)
        out[r0:r1] = vals.reshape(r1 - r0, n, width, n, channels).mean(axis=(1, 3))
    return out


def _pad_cube(cube: NDArray[np.float32]) -> NDArray[np.float32]:
    """Faces with a one-texel border copied from the neighbouring faces: shape (6, S + 2, S + 2, C).

    Border texel centres lie just past the face edge (``a`` or ``b`` = +-(1 + 1/S)); their direction falls on the
    neighbouring face, where the nearest texel is taken. This makes bilinear lookups seamless across edges.
    """
    size = cube.shape[1]
    g = (np.arange(-1, size + 1) + 0.5) / size * 2.0 - 1.0
    d = _face_uv_to_dirs(g[None, :, None], g[None, None, :], np.arange(6)[:, None, None])
    face, s, t = _dirs_to_face_uv(d[..., 0], d[..., 1], d[..., 2])
    col = np.clip(np.floor(s * size), 0, size - 1).astype(np.intp)
    row = np.clip(np.floor(t * size), 0, size - 1).astype(np.intp)
    padded = cube[face, row, col]
    padded[:, 1:-1, 1:-1] = cube  # interior texels are the faces themselves
    # Corners: three faces meet, so there is no fourth texel; seamless cube-map filtering (ARB_seamless_cube_map,
    # core since OpenGL 3.2) recommends the average of the three available ones.
    for r, c, dr, dc in ((0, 0, 1, 1), (0, -1, 1, -1), (-1, 0, -1, 1), (-1, -1, -1, -1)):
        padded[:, r, c] = (padded[:, r + dr, c] + padded[:, r, c + dc] + padded[:, r + dr, c + dc]) / 3.0
    return np.asarray(padded, dtype=np.float32)


def _sample_padded(planes: NDArray[np.float32], size: int, x: NDArray[np.float32], y: NDArray[np.float32],
                   z: NDArray[np.float32]) -> NDArray[np.float32]:
    """Bilinear lookup of directions in a padded cube stored as channel planes (C, 6 (S+2)^2); returns (..., C)."""
    face, s, t = _dirs_to_face_uv(x, y, z)
    p = size + 2
    fsize = np.float32(size)
    u = np.clip(s * fsize + np.float32(0.5), 0.0, fsize + 1)  # texel-centre coordinates in the padded face
    v = np.clip(t * fsize + np.float32(0.5), 0.0, fsize + 1)
    u0 = np.minimum(u.astype(np.intp), size)  # u >= 0, so truncation is floor
    v0 = np.minimum(v.astype(np.intp), size)
    fu = u - u0
    fv = v - v0
    base = face * (p * p) + v0 * p + u0
    w00, w01 = (1 - fu) * (1 - fv), fu * (1 - fv)
    w10, w11 = (1 - fu) * fv, fu * fv
    out = np.empty(x.shape + (planes.shape[0],), dtype=np.float32)
    for c, plane in enumerate(planes):  # a handful of channels
        out[..., c] = (w00 * plane.take(base) + w01 * plane.take(base + 1) + w10 * plane.take(base + p)
                       + w11 * plane.take(base + p + 1))
    return out

