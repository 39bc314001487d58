"""KTX 2.0 containers for prefiltered cube chains, written from the Khronos KTX 2.0 specification.

No KTX library is installable here (pyktx is source-only, libktx is not packaged), so the container is written
directly: the 12-byte identifier, the header, the index, the level index (level 0 first), a Basic Data Format
Descriptor, sorted key/value data, then the mip levels from the smallest to the largest, each aligned to
``lcm(texel block size, 4)`` (spec §3.9). Uncompressed formats only: ``VK_FORMAT_R16G16B16A16_SFLOAT`` (vkFormat
97, the default: 8-byte texels, alpha 1), ``VK_FORMAT_B10G11R11_UFLOAT_PACK32`` (122) and
``VK_FORMAT_E5B9G9R9_UFLOAT_PACK32`` (123), 4-byte texels packed by ``relight.packed_float`` (half the size; three
r187's KTX2Loader maps them to ``RGBFormat`` with ``UnsignedInt101111Type`` / ``UnsignedInt5999Type``). DFD
samples: unsigned-float R, G, B at bit offsets 0, 11, 22 (lengths 11, 11, 10; qualifier FLOAT, lower 0.0f, upper
1.0f), and for the shared exponent, as KTX-Software's DFD utilities write it, each channel's 9-bit mantissa (lower
0, upper 8448) followed by its exponent sample (bits 27-31, qualifier EXPONENT, lower 15, upper 31).
2-D textures (``faceCount = 1``, e.g. ``relight dfg``'s table) are written the same way with one face.
Cube maps have ``faceCount = 6`` and faces in the Vulkan / OpenGL order
+X, -X, +Y, -Y, +Z, -Z with the OpenGL face orientation (docs/conventions.md), which is what ``relight.envmap``'s
cube functions use; KTX2 has no orientation key for cube maps.

Key/value entries other than ``KTXwriter`` are JSON (UTF-8, NUL-terminated) under ``relight.*`` keys.
:func:`read_ktx2` parses what :func:`write_ktx2` writes (for tests and tools); the independent check is the npm
``ktx-parse`` reader, which re-serialises these files byte for byte (tests/relight/test_ktx2.py).
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
VK_FORMAT_R16G16B16A16_SFLOAT = 97
VK_FORMAT_B10G11R11_UFLOAT_PACK32 = 122
VK_FORMAT_E5B9G9R9_UFLOAT_PACK32 = 123
#: ``--pixel-format`` names -> vkFormat.
PIXEL_FORMATS = {"rgba16f": VK_FORMAT_R16G16B16A16_SFLOAT, "b10g11r11": VK_FORMAT_B10G11R11_UFLOAT_PACK32,
                 "e5b9g9r9": VK_FORMAT_E5B9G9R9_UFLOAT_PACK32}
_HEADER = struct.Struct("<9I4I2Q")  # header (9 x u32) + index (4 x u32, 2 x u64)
_LEVEL = struct.Struct("<3Q")
_TEXEL_BYTES = 8
#: Khronos Data Format: colour model RGBSDA, primaries BT.709, linear transfer; sample qualifiers float | signed.
_KHR_DF_MODEL_RGBSDA = 1
_KHR_DF_PRIMARIES_BT709 = 1
_KHR_DF_TRANSFER_LINEAR = 1
_KHR_DF_SAMPLE_FLOAT_SIGNED = 0x80 | 0x40
_KHR_DF_SAMPLE_FLOAT = 0x80
_KHR_DF_SAMPLE_EXPONENT = 0x20
_CHANNELS = (0, 1, 2, 15)  # R, G, B, A channel ids
_ONE_F32_BITS = 0x3F800000  # 1.0f: sampleUpper of a float channel; sampleLower is -1.0f
_MINUS_ONE_F32_BITS = -0x40800000  # 0xBF800000 as a signed 32-bit integer (the field is signed for signed samples)
HALF_MAX = 65504.0


def _sample(offset: int, length: int, channel: int, lower: int, upper: int) -> bytes:
    return struct.pack("<HBB4BiI" if upper >= 0 else "<HBB4Bii", offset, length - 1, channel, 0, 0, 0, 0, lower,
                       upper)


def _dfd(vk_format: int) -> bytes:
    if vk_format == VK_FORMAT_R16G16B16A16_SFLOAT:
        samples = b"".join(_sample(16 * i, 16, ch | _KHR_DF_SAMPLE_FLOAT_SIGNED, _MINUS_ONE_F32_BITS, _ONE_F32_BITS)
                           for i, ch in enumerate(_CHANNELS))
    elif vk_format == VK_FORMAT_B10G11R11_UFLOAT_PACK32:
        samples = b"".join(_sample(off, n, ch | _KHR_DF_SAMPLE_FLOAT, 0, _ONE_F32_BITS)
                           for off, n, ch in ((0, 11, 0), (11, 11, 1), (22, 10, 2)))
    elif vk_format == VK_FORMAT_E5B9G9R9_UFLOAT_PACK32:
        samples = b"".join(_sample(9 * ch, 9, ch, 0, 8448) + _sample(27, 5, ch | _KHR_DF_SAMPLE_EXPONENT, 15, 31)
                           for ch in range(3))
    else:
        raise InputError(f"unsupported vkFormat {vk_format}; use one of {sorted(PIXEL_FORMATS.values())}")
    block_size = 24 + len(samples)
    block = struct.pack("<HHHH4B4B8B", 0, 0, 2, block_size, _KHR_DF_MODEL_RGBSDA, _KHR_DF_PRIMARIES_BT709,
                        _KHR_DF_TRANSFER_LINEAR, 0, 0, 0, 0, 0, _texel_bytes(vk_format), 0, 0, 0, 0, 0, 0, 0) + samples
    return struct.pack("<I", 4 + len(block)) + block


def _texel_bytes(vk_format: int) -> int:
    return _TEXEL_BYTES if vk_format == VK_FORMAT_R16G16B16A16_SFLOAT else 4


def _encode(arr: NDArray[np.floating], vk_format: int) -> bytes:
    from relight import packed_float

    if vk_format == VK_FORMAT_R16G16B16A16_SFLOAT:
        half, _ = to_half_rgba(arr)
        return bytes(half.astype("<f2").tobytes())
    validate.finite_array("cube faces", arr)
    pack = (packed_float.pack_b10g11r11 if vk_format == VK_FORMAT_B10G11R11_UFLOAT_PACK32
            else packed_float.pack_e5b9g9r9)
    return bytes(pack(arr).astype("<u4").tobytes())


def _kvd(entries: Mapping[str, bytes]) -> bytes:
    out = bytearray()
    for key in sorted(entries):
        if "\x00" in key or not key:
            raise InputError(f"KTX2 keys must be non-empty without NUL, got {key!r}")
        payload = key.encode("utf-8") + b"\x00" + entries[key]
        out += struct.pack("<I", len(payload)) + payload + b"\x00" * (-len(payload) % 4)
    return bytes(out)


def to_half_rgba(faces: NDArray[np.floating]) -> tuple[NDArray[np.float16], int]:
    """(..., 3) linear RGB to (..., 4) float16 with alpha 1, clamping to the finite half range; also the count of
    clamped values (a float16 texel cannot hold more than 65504)."""
    rgb = np.asarray(faces, dtype=np.float64)
    validate.finite_array("cube faces", rgb)
    clamped = int(np.count_nonzero(np.abs(rgb) > HALF_MAX))
    out = np.ones(rgb.shape[:-1] + (4,), dtype=np.float16)
    out[..., :3] = np.clip(rgb, -HALF_MAX, HALF_MAX).astype(np.float16)
    return out, clamped


def write_ktx2(levels: Sequence[NDArray[np.floating]], metadata: Mapping[str, Any] | None = None,
               *, writer: str = "relight", vk_format: int = VK_FORMAT_R16G16B16A16_SFLOAT) -> bytes:
    """A cube-map KTX2 file from mip levels ``levels[i]`` of shape (6, s_i, s_i, 3), s_i = s_0 >> i, or a 2-D
    texture from levels of shape (1, s_i, s_i, 3) (``faceCount`` 1).

    ``metadata`` entries are stored as JSON under ``relight.<key>``. Values are converted to float16 (clamped) or
    packed (``vk_format`` 122 or 123, module docstring).
    """
    dfd = _dfd(vk_format)
    if not levels:
        raise InputError("a KTX2 chain needs at least one level")
    size = int(np.asarray(levels[0]).shape[1])
    n_faces = int(np.asarray(levels[0]).shape[0])
    if n_faces not in (1, 6):
        raise InputError(f"a KTX2 texture here has 1 face (2-D) or 6 (cube), got {n_faces}")
    payloads: list[bytes] = []
    for i, lv in enumerate(levels):
        arr = np.asarray(lv)
        want = (n_faces, max(size >> i, 1), max(size >> i, 1), 3)
        if arr.shape != want:
            raise InputError(f"level {i} must have shape {want}, got {arr.shape}")
        payloads.append(_encode(arr, vk_format))
    entries = {"KTXwriter": writer.encode("utf-8") + b"\x00"}
    for key, value in (metadata or {}).items():
        entries[f"relight.{key}"] = json.dumps(value, sort_keys=True).encode("utf-8") + b"\x00"
    kvd = _kvd(entries)
    n = len(payloads)
    dfd_offset = len(IDENTIFIER) + _HEADER.size + n * _LEVEL.size
    kvd_offset = dfd_offset + len(dfd)
    align = math.lcm(_texel_bytes(vk_format), 4)
    offsets = [0] * n
    body = bytearray()
    cursor = kvd_offset + len(kvd)
    for i in range(n - 1, -1, -1):  # smallest level first (spec §3.9)
        pad = -cursor % align
        body += b"\x00" * pad
        cursor += pad
        offsets[i] = cursor
        body += payloads[i]
        cursor += len(payloads[i])
    header = _HEADER.pack(vk_format, 2 if vk_format == VK_FORMAT_R16G16B16A16_SFLOAT else 4, size, size, 0, 0,
                          n_faces, n, 0, dfd_offset, len(dfd), kvd_offset, len(kvd), 0, 0)
    index = b"".join(_LEVEL.pack(offsets[i], len(p), len(p)) for i, p in enumerate(payloads))
    return IDENTIFIER + header + index + dfd + kvd + bytes(body)


@dataclass(frozen=True)
class Ktx2Cube:
    """What :func:`read_ktx2` returns: float32 levels (faces, s, s, 4) (6 faces, or 1 for a 2-D texture) and the
    decoded key/value data."""

    vk_format: int
    size: int
    levels: list[NDArray[np.float32]]
    metadata: dict[str, Any]
    writer: str


def read_ktx2(data: bytes) -> Ktx2Cube:
    """Parse an uncompressed cube-map KTX2 file of the forms :func:`write_ktx2` writes (packed texels decoded,
    alpha 1)."""
    from relight import packed_float

    if data[:12] != IDENTIFIER:
        raise InputError("not a KTX 2.0 file (identifier mismatch)")
    if len(data) < 12 + _HEADER.size:
        raise InputError("KTX2 file is truncated in its header")
    (vk, type_size, width, height, depth, layers, faces, n, scheme, dfd_off, dfd_len, kvd_off, kvd_len,
     _sgd_off, _sgd_len) = _HEADER.unpack_from(data, 12)
    if vk not in PIXEL_FORMATS.values() or type_size != (2 if vk == VK_FORMAT_R16G16B16A16_SFLOAT else 4) \
            or faces not in (1, 6) or scheme != 0:
        raise InputError("only uncompressed RGBA16F, B10G11R11 and E5B9G9R9 cube maps and 2-D textures are read here "
                         f"(vkFormat {vk}, "
                         f"faces {faces}, supercompression {scheme})")
    texel = _texel_bytes(vk)
    if width != height or depth != 0 or layers != 0 or not 1 <= n <= 32:
        raise InputError(f"unexpected cube geometry {width}x{height}x{depth}, {layers} layers, {n} levels")
    levels: list[NDArray[np.float32]] = []
    for i in range(n):
        off, length, _ = _LEVEL.unpack_from(data, 12 + _HEADER.size + i * _LEVEL.size)
        s = max(width >> i, 1)
        if length != faces * s * s * texel or off + length > len(data):
            raise InputError(f"level {i} has {length} bytes at {off}; expected {faces * s * s * texel}")
        if vk == VK_FORMAT_R16G16B16A16_SFLOAT:
            arr = np.frombuffer(data, dtype="<f2", count=faces * s * s * 4, offset=off)
            levels.append(arr.astype(np.float32).reshape(faces, s, s, 4))
            continue
        words = np.frombuffer(data, dtype="<u4", count=faces * s * s, offset=off).reshape(faces, s, s)
        rgb = (packed_float.unpack_b10g11r11(words) if vk == VK_FORMAT_B10G11R11_UFLOAT_PACK32
               else packed_float.unpack_e5b9g9r9(words))
        levels.append(np.concatenate([rgb, np.ones((faces, s, s, 1))], axis=-1).astype(np.float32))
    meta: dict[str, Any] = {}
    writer = ""
    pos, end = kvd_off, kvd_off + kvd_len
    while pos < end:
        (length,) = struct.unpack_from("<I", data, pos)
        entry = data[pos + 4:pos + 4 + length]
        key, _, value = entry.partition(b"\x00")
        text = value.rstrip(b"\x00").decode("utf-8")
        if key == b"KTXwriter":
            writer = text
        elif key.startswith(b"relight."):
            meta[key.decode("utf-8")[len("relight."):]] = json.loads(text)
        pos += 4 + length + (-length % 4)
    del dfd_off, dfd_len
    return Ktx2Cube(vk_format=vk, size=width, levels=levels, metadata=meta, writer=writer)
