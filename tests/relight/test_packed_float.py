"""Packed KTX2 texels (relight.packed_float, ``relight export --pixel-format``): every 10/11-bit code checked
against the Vulkan specification's decoding written out here, the encoder picking the nearest code, the shared
exponent within half a step of the largest channel, and ktx-parse reading (and re-serialising byte for byte) the
packed chains with their vkFormat and DFD samples."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_ktx2 import ktx_parse

from relight import packed_float as pf
from relight.ktx2 import (
    VK_FORMAT_B10G11R11_UFLOAT_PACK32,
    VK_FORMAT_E5B9G9R9_UFLOAT_PACK32,
    read_ktx2,
    write_ktx2,
)

REPO = Path(__file__).resolve().parents[2]


def _spec_small(code: int, mbits: int) -> float:
    """Vulkan "Unsigned 11-bit / 10-bit floating-point numbers": E = 0: 2^-14 (M / 2^mbits); 0 < E < 31:
    2^(E - 15) (1 + M / 2^mbits)."""
    e, m = code >> mbits, code & ((1 << mbits) - 1)
    return 2.0**-14 * (m / 2**mbits) if e == 0 else 2.0 ** (e - 15) * (1 + m / 2**mbits)


@pytest.mark.parametrize(("mbits", "shift", "channel"), [(6, 0, 0), (6, 11, 1), (5, 22, 2)])
def test_small_floats_decode_as_the_spec_and_encode_to_the_nearest(mbits: int, shift: int, channel: int) -> None:
    codes = np.arange(31 << mbits, dtype=np.uint32)  # every finite code (exponent 31 is Inf/NaN)
    values = np.array([_spec_small(int(c), mbits) for c in codes])
    np.testing.assert_array_equal(pf.unpack_b10g11r11(codes << np.uint32(shift))[..., channel], values)
    # the encoder returns each representable value's own code, and for any value the nearest code
    rgb = np.zeros((codes.size, 3))
    rgb[:, channel] = values
    np.testing.assert_array_equal(pf.pack_b10g11r11(rgb) >> np.uint32(shift) & np.uint32((1 << (mbits + 5)) - 1),
                                  codes)
    rng = np.random.default_rng(mbits)
    x = np.exp(rng.uniform(np.log(1e-7), np.log(6e4), 20000))
    rgb = np.zeros((x.size, 3))
    rgb[:, channel] = x
    got = pf.unpack_b10g11r11(pf.pack_b10g11r11(rgb))[:, channel]
    nearest = values[np.argmin(np.abs(values[None, :] - x[:, None]), axis=1)]
    np.testing.assert_array_equal(np.abs(got - x), np.abs(nearest - x))


def test_shared_exponent_within_half_a_step_of_the_largest_channel() -> None:
    rng = np.random.default_rng(9)
    x = np.exp(rng.uniform(np.log(1e-6), np.log(6e4), (20000, 3)))
    packed = pf.pack_e5b9g9r9(x)
    got = pf.unpack_e5b9g9r9(packed)
    e = (packed >> 27).astype(np.float64)
    step = np.exp2(e - 15 - 9)  # the decoded value is m * step (EXT_texture_shared_exponent)
    assert np.all(np.abs(got - x) <= 0.5 * step[:, None] * (1 + 1e-12))
    # the exponent is the smallest that holds the largest channel in 9 bits: one less would overflow 511
    big, above = x.max(axis=1), e > 0
    assert np.all(np.floor(big[above] / (0.5 * step[above]) + 0.5) >= 512) and np.any(~above)
    assert np.all((packed & 0x1FF) <= 511)
    # closed forms: 1.0 = 256 x 2^(16 - 24); the largest value 511 x 2^(31 - 24)
    assert pf.unpack_e5b9g9r9(pf.pack_e5b9g9r9(np.array([1.0, 0.5, 0.0])))[()].tolist() == [1.0, 0.5, 0.0]
    assert pf.unpack_e5b9g9r9(pf.pack_e5b9g9r9(np.array([1e9, 0.0, 0.0])))[0] == pf.MAX_RGB9E5 == 511 * 2.0**7


@pytest.mark.parametrize(("vk", "samples"), [
    (VK_FORMAT_B10G11R11_UFLOAT_PACK32, [[0, 10, 128], [11, 10, 129], [22, 9, 130]]),
    (VK_FORMAT_E5B9G9R9_UFLOAT_PACK32, [[0, 8, 0], [27, 4, 32], [9, 8, 1], [27, 4, 33], [18, 8, 2], [27, 4, 34]]),
])
def test_ktx_parse_reads_packed_chains(tmp_path: Path, vk: int, samples: list[list[int]]) -> None:
    rng = np.random.default_rng(vk)
    levels = [rng.uniform(0.0, 8.0, (6, 8 >> i, 8 >> i, 3)) for i in range(4)]
    path = tmp_path / "packed.ktx2"
    path.write_bytes(write_ktx2(levels, {"target": "three"}, writer="relight test", vk_format=vk))
    info = ktx_parse(path)
    assert info["identical"] is True and info["vkFormat"] == vk and info["typeSize"] == 4
    assert info["faces"] == 6 and info["levelCount"] == 4 and info["bytesPlane0"] == 4
    assert info["levels"] == [[6 * s * s * 4] * 2 for s in (8, 4, 2, 1)]
    assert info["samples"] == samples
    decode = pf.unpack_b10g11r11 if vk == VK_FORMAT_B10G11R11_UFLOAT_PACK32 else pf.unpack_e5b9g9r9
    pack = pf.pack_b10g11r11 if vk == VK_FORMAT_B10G11R11_UFLOAT_PACK32 else pf.pack_e5b9g9r9
    for got, lv in zip(read_ktx2(path.read_bytes()).levels, levels, strict=True):
        np.testing.assert_array_equal(got[..., :3], decode(pack(lv)).astype(np.float32))


def test_export_pixel_format(tmp_path: Path) -> None:
    out = tmp_path / "c.ktx2"
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "export", str(REPO / "data/envmaps/studio.exr"),
                           "--target", "three", "--size", "8", "--pixel-format", "e5b9g9r9", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert read_ktx2(out.read_bytes()).vk_format == VK_FORMAT_E5B9G9R9_UFLOAT_PACK32
    assert json.loads((tmp_path / "c.ktx2.json").read_text())["pixel_format"] == "e5b9g9r9"
