"""Environment-map input and output: probe, decode, validate, convert to the project's lat-long layout, write.

One module per object:

=====================================  =======================================================================
:mod:`relight.envmap.formats`          the format-sniff table (magic bytes -> format), :class:`ImageHeader`,
                                       size limits
:mod:`relight.envmap.headers`          header probing without decoding (:func:`probe`)
:mod:`relight.envmap.exr`              OpenEXR read / write (OpenEXR 3.x bindings; hand-written header bound)
:mod:`relight.envmap.rgbe`             Radiance RGBE ``.hdr`` read / write
:mod:`relight.envmap.ldr`              PNG / JPEG (Pillow; 16-bit PNG through imagecodecs), sRGB transfer
:mod:`relight.envmap.cubemap`          cube-map geometry (OpenGL 4.6 table 8.19), layouts, cube -> lat-long
:mod:`relight.envmap.resample`         lat-long resampling (solid-angle area average / bilinear)
:mod:`relight.envmap.display`          tone mapping and PNG previews
:mod:`relight.envmap.environment`      :class:`EnvMap`, :func:`read_envmap`, :func:`read_image`
=====================================  =======================================================================

Every decoder returns linear float32 RGB, shape (H, W, 3), row 0 at the top of the image.

Upload safety (docs/facts.md, "Upload safety"): call :func:`probe` (header only) and pass ``max_pixels`` before decoding
anything untrusted; EXR channels are read separately (``separate_channels=True``), never combined by the
bindings. Run untrusted decodes in a worker process under memory and time limits.

This package re-exports the public names of its modules (``from relight.envmap import read_envmap`` works), and
imports each module only when one of its names is first used (PEP 562 ``__getattr__``), so importing
:mod:`relight.envmap.formats` alone does not load OpenEXR or Pillow.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from relight import lazy

if TYPE_CHECKING:
    from relight.envmap.cubemap import CUBE_LAYOUTS, FACE_NAMES, cube_face_dirs, cube_faces_from_image, cube_to_latlong
    from relight.envmap.display import TONEMAP_OPERATORS, tonemap, write_png_preview
    from relight.envmap.environment import LAYOUTS, EnvMap, envmap_from_array, envmap_from_cube, read_envmap, read_image
    from relight.envmap.exr import HALF_MAX, read_exr_layers, to_half_safe, write_exr, write_exr_layers
    from relight.envmap.formats import FORMATS, HARD_MAX_PIXELS, ImageHeader, Source, sniff
    from relight.envmap.headers import probe
    from relight.envmap.ldr import linear_to_srgb, srgb_to_linear
    from relight.envmap.resample import resample_latlong
    from relight.envmap.rgbe import write_hdr

#: Public name -> the module defining it.
_EXPORTS: dict[str, str] = {
    "CUBE_LAYOUTS": "cubemap",
    "FACE_NAMES": "cubemap",
    "cube_face_dirs": "cubemap",
    "cube_faces_from_image": "cubemap",
    "cube_to_latlong": "cubemap",
    "TONEMAP_OPERATORS": "display",
    "tonemap": "display",
    "write_png_preview": "display",
    "LAYOUTS": "environment",
    "EnvMap": "environment",
    "envmap_from_array": "environment",
    "envmap_from_cube": "environment",
    "read_envmap": "environment",
    "read_image": "environment",
    "HALF_MAX": "exr",
    "read_exr_layers": "exr",
    "to_half_safe": "exr",
    "write_exr": "exr",
    "write_exr_layers": "exr",
    "FORMATS": "formats",
    "HARD_MAX_PIXELS": "formats",
    "ImageHeader": "formats",
    "Source": "formats",
    "sniff": "formats",
    "linear_to_srgb": "ldr",
    "srgb_to_linear": "ldr",
    "probe": "headers",
    "resample_latlong": "resample",
    "write_hdr": "rgbe",
}

__all__ = [
    "CUBE_LAYOUTS", "EnvMap", "FACE_NAMES", "FORMATS", "HALF_MAX", "HARD_MAX_PIXELS", "ImageHeader", "LAYOUTS",
    "Source", "TONEMAP_OPERATORS", "cube_face_dirs", "cube_faces_from_image", "cube_to_latlong",
    "envmap_from_array", "envmap_from_cube", "linear_to_srgb", "probe", "read_envmap", "read_exr_layers",
    "read_image", "resample_latlong", "sniff", "srgb_to_linear", "to_half_safe", "tonemap", "write_exr",
    "write_exr_layers", "write_hdr", "write_png_preview",
]


__getattr__, __dir__ = lazy.exports(__name__, _EXPORTS)
