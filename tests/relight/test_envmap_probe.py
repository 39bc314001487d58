"""Tests for header probing and size limits (relight.envmap.headers, relight.envmap.formats).

Every expected value comes from an independent source: the OpenEXR bindings read directly, byte strings and
formulas written here from the format specifications (Radiance RGBE, PNG filters, sRGB), the OpenGL cube-map
table re-typed here, and closed-form solid angles.
"""

from __future__ import annotations

import importlib
import io
import struct
import subprocess
import sys
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
from envmap_refs import (
    crafted_exr_header,
    png_chunk,
    rgb_exr_bytes,
)
from PIL import Image

from relight import envmap as E
from relight.envmap import formats, rgbe
from relight.errors import InputError


def test_wrong_magic_and_empty(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"unrecognised image format .*OpenEXR.*Radiance.*PNG.*JPEG"):
        E.probe(b"GIF89a" + bytes(100))
    with pytest.raises(InputError, match="empty file"):
        E.read_envmap(b"")
    with pytest.raises(InputError, match="cannot read"):
        E.read_envmap(tmp_path / "missing.exr")


def test_zero_size_images() -> None:
    with pytest.raises(InputError, match="empty EXR image"):
        E.probe(crafted_exr_header(0, 0))
    with pytest.raises(InputError, match="empty Radiance HDR image"):
        E.probe(b"#?RADIANCE\n\n-Y 0 +X 0\n")
    with pytest.raises(InputError, match="empty or unsupported PNG image"):  # a complete file, zero width
        E.probe(b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", 0, 10, 8, 2, 0, 0, 0))
                + png_chunk(b"IDAT", zlib.compress(b"")) + png_chunk(b"IEND", b""))
    with pytest.raises(InputError, match="truncated PNG file"):  # the file ends after IHDR
        E.probe(b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", 0, 10, 8, 2, 0, 0, 0)))
    with pytest.raises(InputError, match="cannot be empty|width"):
        E.envmap_from_array(np.zeros((0, 0, 3)))


@pytest.mark.parametrize("header", [crafted_exr_header(100_000, 100_000),
                                    b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n"])
def test_huge_header_rejected_without_allocation(header: bytes) -> None:
    tracemalloc.start()
    try:
        hdr = E.probe(header)
        assert (hdr.width, hdr.height) == (100_000, 100_000)
        with pytest.raises(InputError, match="100000 x 100000 = 10000000000 pixels, more than the limit of 8388608"):
            E.read_envmap(header, max_pixels=4096 * 2048)
        with pytest.raises(InputError, match="more than the limit"):
            E.read_envmap(header)  # the hard limit applies without max_pixels too
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20  # refused from the header: no pixel buffer was allocated


def test_probe_reads_only_the_header_of_a_file(tmp_path: Path) -> None:
    path = tmp_path / "huge.exr"
    path.write_bytes(crafted_exr_header(100_000, 100_000) + bytes(1 << 20))
    assert E.probe(path).pixels == 10**10


# ------------------------------------------------------------------------------------------------------------------
# The format-sniff table (relight.envmap.formats) and the lazy package


@pytest.mark.parametrize(("head", "fmt"), [
    (b"\x76\x2f\x31\x01\x02\x00\x00\x00", "exr"),  # OpenEXR magic number + version 2
    (b"#?RADIANCE\n", "hdr"),
    (b"#?RGBE\n", "hdr"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR", "png"),  # ISO/IEC 15948 signature
    (b"\xff\xd8\xff\xe0\x00\x10JFIF", "jpeg"),  # SOI + APP0
    (b"GIF89a", None),
    (b"\x89PNG\r\n", None),  # a PNG signature cut short is not a PNG
    (b"", None),
])
def test_sniff_table(head: bytes, fmt: str | None) -> None:
    assert formats.sniff(head) == fmt
    assert formats.sniff(bytearray(head) + bytes(32)) == fmt  # trailing bytes never change the answer


def test_sniff_agrees_with_the_encoders() -> None:
    """Files written by the project's writers and by Pillow are recognised by their first SNIFF_BYTES bytes."""
    rgb = np.ones((2, 4, 3), np.float32)
    for fmt, data in [("exr", rgb_exr_bytes(rgb)), ("hdr", rgbe.encode(rgb))]:
        assert formats.sniff(data[: formats.SNIFF_BYTES]) == fmt
    for fmt in ("PNG", "JPEG"):
        buf = io.BytesIO()
        Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(buf, format=fmt)
        assert formats.sniff(buf.getvalue()[: formats.SNIFF_BYTES]) == fmt.lower()


def test_probe_reads_a_png_header_lazily(tmp_path: Path) -> None:
    """A PNG claiming 100000 x 100000 pixels followed by 1 MiB of (garbage) IDAT: the header alone is read."""
    ihdr = struct.pack(">IIBBBBB", 100_000, 100_000, 16, 2, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", bytes(1 << 20))
    path = tmp_path / "huge.png"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        assert E.probe(path) == E.ImageHeader("png", 100_000, 100_000, 3, 16)
        with pytest.raises(InputError, match="100000 x 100000 = 10000000000 pixels, more than the limit"):
            E.read_envmap(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20  # the 1 MiB IDAT is never read into memory, let alone decoded


def test_package_imports_modules_lazily() -> None:
    """``relight.envmap.formats`` alone loads neither OpenEXR nor Pillow; every re-exported name resolves."""
    code = ("import sys, relight.envmap.formats; "
            "print(sorted(m for m in ('OpenEXR', 'PIL', 'relight.envmap.exr') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    assert sorted(E.__all__) == sorted(E._EXPORTS)
    for name in E.__all__:
        module = importlib.import_module(f"relight.envmap.{E._EXPORTS[name]}")
        assert getattr(E, name) is getattr(module, name)
    with pytest.raises(AttributeError, match="no_such_name"):
        E.no_such_name  # noqa: B018
