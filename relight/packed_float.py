"""Packed unsigned-float texels of the Vulkan specification ("Fundamentals", 10- and 11-bit unsigned floats and the
shared-exponent format), for KTX2 chains half the size of RGBA16F (``relight.ktx2``).

* ``VK_FORMAT_B10G11R11_UFLOAT_PACK32``: R in bits 0-10 and G in 11-21 (5-bit exponent, 6-bit mantissa), B in
  22-31 (5-bit exponent, 5-bit mantissa); exponent bias 15, denormals at exponent 0 (``m 2^-14 / 2^M``), no sign.
  Each channel is rounded to the nearest representable value (relative error <= 2^-7 for 11 bits, 2^-6 for 10)
  and clamped to the largest finite one (65024 and 64512).
* ``VK_FORMAT_E5B9G9R9_UFLOAT_PACK32``: three 9-bit mantissas (R bits 0-8, G 9-17, B 18-26) and one 5-bit exponent
  (27-31), value ``m 2^(e - 15 - 9)``: the encoding of the OpenGL ``EXT_texture_shared_exponent`` specification
  (the exponent chosen from the largest channel, rounded, bumped when rounding overflows 9 bits); every channel's
  error is at most half a step of the largest channel's (``max 2^-9``), so small channels beside a bright one lose
  relative precision. Largest value 65408.

Negative values (ringing) are clamped to 0 in both (counted by the writer).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
U32 = NDArray[np.uint32]

BIAS = 15
#: Largest finite values: (2 - 2^-M) 2^15 for M = 6 and 5, and (511 / 512) 2^16 for the shared exponent.
MAX_UF11 = (2.0 - 2.0**-6) * 2.0**15
MAX_UF10 = (2.0 - 2.0**-5) * 2.0**15
MAX_RGB9E5 = 511.0 / 512.0 * 2.0**16


def _pack_small(x: FloatArray, mbits: int, vmax: float) -> U32:
    """Non-negative values to (exponent << mbits | mantissa), round to nearest, clamped to ``vmax``."""
    v = np.clip(np.asarray(x, dtype=np.float64), 0.0, vmax)
    with np.errstate(divide="ignore"):
        e = np.maximum(np.floor(np.log2(np.where(v > 0, v, 1.0))), 1 - BIAS)
    e = np.where(v > 0, e, 1 - BIAS)
    q = np.round(v / np.exp2(e - mbits))  # in [0, 2^(mbits + 1)]
    carry = q >= 2 ** (mbits + 1)
    e = np.where(carry, e + 1, e)
    q = np.where(carry, 2**mbits, q)
    normal = q >= 2**mbits
    biased = np.where(normal, e + BIAS, 0)
    mant = np.where(normal, q - 2**mbits, q)
    return np.asarray(biased.astype(np.uint32) << np.uint32(mbits) | mant.astype(np.uint32), dtype=np.uint32)


def _unpack_small(bits: NDArray[np.integer[Any]], mbits: int) -> FloatArray:
    b = np.asarray(bits, dtype=np.int64)
    e = b >> mbits
    m = b & ((1 << mbits) - 1)
    return np.asarray(np.where(e == 0, m * 2.0 ** (1 - BIAS - mbits),
                               np.exp2(e - BIAS) * (1.0 + m / 2.0**mbits)), dtype=np.float64)


def pack_b10g11r11(rgb: NDArray[np.floating]) -> U32:
    """(..., 3) linear RGB to packed uint32 (module docstring)."""
    x = np.asarray(rgb, dtype=np.float64)
    r = _pack_small(x[..., 0], 6, MAX_UF11)
    g = _pack_small(x[..., 1], 6, MAX_UF11)
    b = _pack_small(x[..., 2], 5, MAX_UF10)
    return np.asarray(r | g << np.uint32(11) | b << np.uint32(22), dtype=np.uint32)


def unpack_b10g11r11(packed: U32) -> FloatArray:
    p = np.asarray(packed, dtype=np.uint32)
    return np.stack([_unpack_small(p & 0x7FF, 6), _unpack_small(p >> 11 & 0x7FF, 6),
                     _unpack_small(p >> 22 & 0x3FF, 5)], axis=-1)


def pack_e5b9g9r9(rgb: NDArray[np.floating]) -> U32:
    """(..., 3) linear RGB to packed uint32 (module docstring; EXT_texture_shared_exponent's encoding)."""
    c = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, MAX_RGB9E5)
    m = c.max(axis=-1)
    with np.errstate(divide="ignore"):
        lg = np.floor(np.log2(np.where(m > 0, m, 1.0)))
    e = np.maximum(np.where(m > 0, lg, -BIAS - 1), -BIAS - 1) + 1 + BIAS
    max_s = np.floor(m / np.exp2(e - BIAS - 9) + 0.5)
    e = np.where(max_s >= 512, e + 1, e)
    q = np.floor(c / np.exp2(e - BIAS - 9)[..., None] + 0.5).astype(np.uint32)
    return np.asarray(q[..., 0] | q[..., 1] << np.uint32(9) | q[..., 2] << np.uint32(18)
                      | e.astype(np.uint32) << np.uint32(27), dtype=np.uint32)


def unpack_e5b9g9r9(packed: U32) -> FloatArray:
    p = np.asarray(packed, dtype=np.uint32)
    scale = np.exp2((p >> 27).astype(np.float64) - BIAS - 9)
    return np.stack([(p & 0x1FF) * scale, (p >> 9 & 0x1FF) * scale, (p >> 18 & 0x1FF) * scale], axis=-1)
