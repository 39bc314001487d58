"""Display: tone mapping linear HDR RGB to 8-bit sRGB, and PNG previews.

Operators: Narkowicz's ACES fit (K. Narkowicz, "ACES Filmic Tone Mapping Curve", blog post, 6 Jan 2016) and
Reinhard et al. 2002, eq. 3; encoding with the sRGB OETF (IEC 61966-2-1). The viewer's shader
(``web/shaders/tonemap.glsl``) uses the same constants, generated from this module by :mod:`relight.gl.shaders`.
"""

from __future__ import annotations

import os
from typing import Final

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from relight import validate
from relight.envmap.formats import check_rgb_image
from relight.envmap.ldr import linear_to_srgb
from relight.errors import InputError

#: Narkowicz's ACES fit coefficients (K. Narkowicz, "ACES Filmic Tone Mapping Curve", blog post, 6 Jan 2016).
ACES_A, ACES_B, ACES_C, ACES_D, ACES_E = 2.51, 0.03, 2.43, 0.59, 0.14
TONEMAP_OPERATORS: Final = ("aces", "reinhard")


def tonemap(rgb: NDArray[np.floating], *, exposure: float = 0.0, operator: str = "aces") -> NDArray[np.uint8]:
    """Linear HDR RGB to 8-bit sRGB for display.

    ``x = rgb 2^exposure`` (exposure in stops; negatives and NaN count as 0), then per channel

    * ``"aces"``: Narkowicz's fit of the ACES RRT + sRGB ODT, ``x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)``,
      as published (pre-exposed: 1 maps to about 0.8);
    * ``"reinhard"``: ``x / (1 + x)`` (Reinhard et al. 2002, eq. 3),

    clamped to [0, 1], encoded with the sRGB OETF (IEC 61966-2-1) and rounded to 8 bits.
    """
    if operator not in TONEMAP_OPERATORS:
        raise InputError(f"unknown tone-mapping operator {operator!r}: expected one of {', '.join(TONEMAP_OPERATORS)}")
    exposure = validate.finite("exposure", exposure)
    x = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=np.inf, neginf=0.0)
    x = np.maximum(x, 0.0) * 2.0 ** exposure
    if operator == "aces":
        with np.errstate(invalid="ignore"):
            y = np.where(np.isinf(x), 1.0, x * (ACES_A * x + ACES_B) / (x * (ACES_C * x + ACES_D) + ACES_E))
    else:
        with np.errstate(invalid="ignore"):
            y = np.where(np.isinf(x), 1.0, x / (1.0 + x))
    return np.round(linear_to_srgb(np.clip(y, 0.0, 1.0)) * 255.0).astype(np.uint8)


def write_png_preview(path: str | os.PathLike[str], rgb: NDArray[np.floating], *, exposure: float = 0.0,
                      operator: str = "aces") -> None:
    """Tone-map (:func:`tonemap`) an (H, W, 3) image and save it as an 8-bit sRGB PNG."""
    Image.fromarray(tonemap(check_rgb_image(rgb, "the image"), exposure=exposure, operator=operator), "RGB").save(
        os.fspath(path), format="PNG")


