"""PNG and JPEG: header reading, decoding to linear RGB, and the sRGB transfer functions.

* Headers are read by Pillow's own PNG and JPEG plugins, which open lazily: only the header chunks / marker
  segments are read, no pixel is decoded (Pillow, "Image.open": "This is a lazy operation").
* 8-bit PNG and JPEG are decoded by Pillow; 16-bit PNG by ``imagecodecs`` (libpng), which returns every sample
  at full precision (Pillow has no 16-bit colour mode and keeps only the high byte of each sample).
* Values are decoded from sRGB to linear with the exact piecewise sRGB EOTF (IEC 61966-2-1:1999, section 5.2);
  ICC profiles and PNG ``gAMA`` are ignored (sRGB is assumed).
"""

from __future__ import annotations

import io
from typing import IO, Any, Final

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageFile, JpegImagePlugin, PngImagePlugin

from relight.envmap.formats import ImageHeader
from relight.errors import InputError

F32 = NDArray[np.float32]

_PLUGINS: Final[dict[str, type[ImageFile.ImageFile]]] = {
    "png": PngImagePlugin.PngImageFile, "jpeg": JpegImagePlugin.JpegImageFile,
}
_PILLOW_FORMATS: Final = {"png": "PNG", "jpeg": "JPEG"}
#: PNG colour type -> samples per pixel (ISO/IEC 15948, table 11.1).
_PNG_CHANNELS: Final = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}


def srgb_to_linear(c: NDArray[np.floating]) -> NDArray[np.float64]:
    """sRGB EOTF, IEC 61966-2-1:1999 eq. (5.2): ``c / 12.92`` for ``c <= 0.04045``, else ``((c+0.055)/1.055)^2.4``."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: NDArray[np.floating]) -> NDArray[np.float64]:
    """sRGB OETF, IEC 61966-2-1:1999 eq. (5.1) inverted: ``12.92 x`` for ``x <= 0.0031308``, else
    ``1.055 x^(1/2.4) - 0.055``."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)


def read_header(fp: IO[bytes], fmt: str) -> ImageHeader:
    """The header of the PNG or JPEG file ``fp`` (positioned at its start), read lazily by Pillow's plugin.

    The plugin class is used directly, not ``Image.open``: ``Image.open`` would apply Pillow's own
    decompression-bomb limit, while the project applies its own (``max_pixels``) to the header returned here.
    A file that ends inside its header raises "truncated ...", a zero size "empty or unsupported ...", anything
    else Pillow rejects "corrupt ...".
    PNG bit depth and colour type are IHDR bytes 24 and 25 (ISO/IEC 15948, 11.2.2; IHDR is always first and
    Pillow has validated it), which Pillow does not expose.
    """
    kind = _PILLOW_FORMATS[fmt]
    start = fp.tell()
    try:
        # Third-party parser boundary: any failure to read the header is bad input.
        with _PLUGINS[fmt](fp) as im:
            width, height = im.size
            if fmt == "jpeg":
                return ImageHeader("jpeg", width, height, int(getattr(im, "layers", len(im.getbands()))),
                                   int(getattr(im, "bits", 8)))
    except Exception as exc:
        stopped = fp.tell()
        end = fp.seek(0, io.SEEK_END)
        if stopped >= end:  # Pillow read to the end of the data and wanted more
            raise InputError(f"truncated {kind} file: the header ends after {end - start} bytes") from None
        if str(exc) == "not identified by this driver":  # Pillow's words for a zero size or no pixel mode
            raise InputError(f"empty or unsupported {kind} image: Pillow finds no size or pixel mode in its header"
                             ) from None
        raise InputError(f"corrupt {kind} file: {type(exc).__name__}: {exc}".splitlines()[0]) from None
    fp.seek(start + 24)
    depth, colour = fp.read(2)
    return ImageHeader("png", width, height, _PNG_CHANNELS[colour], depth)


def decode(buf: bytes, hdr: ImageHeader) -> F32:
    """8/16-bit PNG and JPEG to (H, W, 3) linear float32: Pillow (8 bits) or imagecodecs (16-bit PNG), then sRGB."""
    kind = hdr.format.upper()
    try:
        # Third-party decoder boundary: any failure (truncation, corrupt data, bomb check) is bad input.
        if hdr.format == "png" and hdr.bit_depth == 16:
            value = _png16(buf)
        else:
            with Image.open(io.BytesIO(buf), formats=[_PILLOW_FORMATS[hdr.format]]) as im:
                if im.mode.startswith("I"):  # Pillow's 16-bit grey modes; 16-bit PNGs never come here
                    raise InputError(f"unexpected Pillow mode {im.mode!r} for a {hdr.bit_depth}-bit {kind} file")
                value = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"cannot decode {kind} file: {type(exc).__name__}: {exc}".splitlines()[0]) from exc
    return srgb_to_linear(value).astype(np.float32)


def _png16(buf: bytes) -> NDArray[np.float64]:
    """A 16-bit PNG at full precision through imagecodecs' libpng decoder: grey, grey + alpha, RGB or RGBA samples
    as stored (alpha dropped, grey replicated), scaled by 1/65535."""
    import imagecodecs  # a large extension module, needed only for 16-bit PNG

    from relight.envmap.png_check import check_png_stream

    check_png_stream(buf, what="16-bit PNG")  # libpng's error path leaks a reference to None (png_check)
    samples: NDArray[Any] = np.asarray(imagecodecs.png_decode(buf))
    if samples.dtype != np.uint16:
        raise InputError(f"16-bit PNG decoded to {samples.dtype}, expected uint16")
    if samples.ndim == 2:
        samples = samples[..., None]
    colour = samples[..., :3] if samples.shape[-1] >= 3 else np.repeat(samples[..., :1], 3, axis=-1)
    return colour.astype(np.float64) / 65535.0
