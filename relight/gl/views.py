"""Plain functions behind the viewer's image endpoints, runnable in a worker process (no web framework here).

* :func:`reference_sphere_image` — the angular-domain brute force (seed 000 eqs. 1-2,
  ``relight.reference_view.reference_sphere``) of the unit sphere for one distant view, with the camera of
  ``relight.shrm.render_sphere`` (and of the viewer's comparison panel and ``relight.gl.render``).
* :func:`mesh_reference_image` — Mitsuba 3's path-traced image (``relight.mitsuba_mesh``: Lambertian, exact
  self-shadowing, optional interreflections) of a mesh under a map, with the orthographic camera of
  ``relight.mesh_render`` and of the viewer's fixed views (the mesh normalised into the unit ball).
* :func:`envmap_texture` — an environment map as float16 RGB lat-long texels for the viewer's background.
* :func:`encode_png` / :func:`encode_exr` — the display PNG (``relight.envmap.tonemap``) and the float EXR.

Both readers take a file path of an *uploaded* map: call them in a worker process (untrusted bytes, docs/facts.md).
"""

from __future__ import annotations

import os
import tempfile
from io import BytesIO
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

#: Largest reference image edge (the brute force costs O(size^2 x environment pixels in the lobe)).
MAX_REFERENCE_SIZE = 256
#: Largest Mitsuba sample budget of one mesh reference (size^2 x spp): 256^2 x 256, about 20 s on 2 cores.
MAX_MESH_REFERENCE_SAMPLES = 256 * 256 * 256
#: Path depths of the mesh reference: 2 = direct light with exact shadows, each step above adds one bounce.
MESH_REFERENCE_DEPTHS = (2, 5)


def _read_map(envmap_path: str, max_pixels: int | None, rows: int | None) -> NDArray[np.float32]:
    from relight.envmap.environment import read_envmap
    from relight.envmap.resample import resample_latlong

    env = read_envmap(envmap_path, max_pixels=max_pixels)
    px = env.pixels
    if rows is not None and rows < env.height:
        px = resample_latlong(px, rows)
    return np.asarray(px, dtype=np.float32)


def reference_sphere_image(
    envmap_path: str,
    brdf_spec: Any,
    view: list[float],
    size: int,
    *,
    env_rows: int | None = None,
    max_pixels: int | None = None,
) -> NDArray[np.float32]:
    """Brute-force image (size, size, 3) of the unit sphere lit by the map, for the distant view V.

    ``env_rows`` (optional) first resamples the map to that many rows by area (``relight.envmap
    .resample_latlong``: integrals over pixels are kept, so smooth lobes are unchanged and sharp ones blur by
    at most one coarse pixel).
    """
    from relight.brdf.spec import parse_brdf
    from relight.reference_view import reference_sphere

    validate.int_in_range("reference size", size, 1, MAX_REFERENCE_SIZE)
    px = _read_map(envmap_path, max_pixels, env_rows)
    brdf = parse_brdf(brdf_spec)
    return np.asarray(reference_sphere(px, brdf, np.asarray(view, dtype=np.float64), size), dtype=np.float32)


def mesh_reference_image(
    envmap_path: str,
    geometry: bytes,
    vertices: int,
    faces: int,
    view: list[float],
    size: int,
    *,
    spp: int,
    albedo: float,
    max_depth: int = 2,
    env_rotation: float = 0.0,
    env_rows: int | None = None,
    max_pixels: int | None = None,
    seed: int = 0,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Mitsuba's image (size, size, 3) of the mesh (``geometry.bin`` bytes, canonical order) lit by the map, and
    the per-pixel Monte Carlo variance of its luminance (size, size).

    The map is area-resampled to ``env_rows`` first (the viewer lights from the SH of its own float16 texture, so
    the reference only needs the frequencies a comparison can resolve); ``env_rotation`` (radians about +Y) turns
    it like the viewer's rotation slider. Deterministic for a given ``seed``.
    """
    from relight.mesh import geometry as geometry_mod
    from relight.mitsuba_mesh import render_mesh_mitsuba

    validate.int_in_range("reference size", size, 1, MAX_REFERENCE_SIZE)
    if spp < 1 or size * size * spp > MAX_MESH_REFERENCE_SAMPLES:
        raise InputError(f"size^2 x spp must be in 1..{MAX_MESH_REFERENCE_SAMPLES}, got {size}^2 x {spp}")
    lo, hi = MESH_REFERENCE_DEPTHS
    validate.int_in_range("max_depth (2 = direct light)", max_depth, lo, hi)
    validate.in_range("albedo", albedo, 0.0, 1.0)
    mesh = geometry_mod.from_bytes(geometry, vertices, faces).normalised()
    px = _read_map(envmap_path, max_pixels, env_rows)
    out = render_mesh_mitsuba(mesh, px, view=np.asarray(view, dtype=np.float64), size=size, spp=spp,
                              albedo=albedo, max_depth=max_depth, seed=seed, env_rotation=env_rotation)
    return np.asarray(out.rgb, dtype=np.float32), np.asarray(out.variance, dtype=np.float32)


def envmap_texture(envmap_path: str, rows: int, *, max_pixels: int | None = None) -> tuple[bytes, int, int]:
    """The map as little-endian float16 RGB (rows, 2 rows, 3) (its own size if smaller), row 0 = +Y; returns the
    bytes, the height and the width. Values beyond the half range are clamped (``relight.envmap.to_half_safe``).
    """
    from relight.envmap.exr import to_half_safe

    validate.int_in_range("rows", rows, 1, 4096)
    px = _read_map(envmap_path, max_pixels, rows)
    half, _ = to_half_safe(px)
    return np.ascontiguousarray(half).astype("<f2").tobytes(), int(px.shape[0]), int(px.shape[1])


def encode_png(image: NDArray[np.floating], *, exposure: float = 0.0, operator: str = "aces") -> bytes:
    """8-bit sRGB PNG through the project's display transform (``relight.envmap.tonemap``)."""
    from PIL import Image

    from relight.envmap.display import tonemap

    buf = BytesIO()
    Image.fromarray(tonemap(np.asarray(image), exposure=exposure, operator=operator), "RGB").save(buf, format="PNG")
    return buf.getvalue()


def encode_exr(image: NDArray[np.floating], attributes: dict[str, str] | None = None) -> bytes:
    """Float32 RGB EXR bytes (``relight.envmap.write_exr``, ZIP compression)."""
    from relight.envmap.exr import write_exr

    fd, name = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    try:
        write_exr(name, np.asarray(image, dtype=np.float32), attributes=attributes)
        with open(name, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(name)
