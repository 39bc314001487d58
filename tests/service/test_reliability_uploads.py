"""Issue 12, item 3 (uploads), against a real server on loopback whose workers have a 1 GiB memory limit and whose
pixel limit is 2 M texels: the header bombs of the issue are refused before decoding with a message that says what
is wrong, the worst-case RLE ``.hdr`` at the pixel limit decodes without killing a worker, and after every
rejection nothing is stored (blob files, map list and job table checked).
"""

from __future__ import annotations

import io
import struct
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import OpenEXR
import pytest

from .postgres import Backend
from .support import Server, assert_problem, exr_bytes, fresh_health, make_envmap, start_server

pytestmark = pytest.mark.timeout(300)

MAX_PIXELS = 2048 * 1024


@pytest.fixture(scope="module")
def uploader(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[Server]:
    srv = start_server(tmp_path_factory.mktemp("uploads"), {
        "RELIGHT_MAX_PIXELS": str(MAX_PIXELS), "RELIGHT_MAX_UPLOAD_BYTES": str(24 << 20),
        "RELIGHT_WORKER_MEMORY_LIMIT": "1GiB"}, database=database)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def uh(uploader: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=uploader.url, timeout=120.0) as c:
        yield c


def stored(server: Server, http: httpx.Client) -> tuple[set[str], list[str], list[str]]:
    """Blob files (tmp included), listed maps, jobs: what a rejected upload must leave unchanged."""
    root = Path(server.args[server.args.index("--data") + 1]) / "blobs"
    files = {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}
    maps = [m["id"] for m in http.get("/envmaps").json()["items"]]
    jobs = [j["id"] for j in http.get("/jobs").json()["items"]]
    return files, maps, jobs


def two_part_exr(small: tuple[int, int], big: tuple[int, int]) -> bytes:
    window = (np.array([0, 0], np.int32), np.array([big[1] - 1, big[0] - 1], np.int32))
    parts = []
    for name, (h, w) in (("small", small), ("big", big)):
        z = np.zeros((h, w), np.float16)
        parts.append(OpenEXR.Part({"type": OpenEXR.scanlineimage, "compression": OpenEXR.ZIP_COMPRESSION,
                                   "displayWindow": window}, {"R": z, "G": z, "B": z}, name))
    buf = io.BytesIO()
    with OpenEXR.File(parts) as f:
        f.write(buf)
    return buf.getvalue()


def _attr(name: str, type_name: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + type_name.encode() + b"\0" + struct.pack("<i", len(value)) + value


def _part(name: str, part_type: str, w: int, h: int) -> bytes:
    chlist = b"".join(c + b"\0" + struct.pack("<iB3xii", 1, 0, 1, 1) for c in (b"B", b"G", b"R")) + b"\0"
    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    return b"".join([
        _attr("channels", "chlist", chlist), _attr("compression", "compression", b"\x00"),
        _attr("dataWindow", "box2i", box), _attr("displayWindow", "box2i", box),
        _attr("lineOrder", "lineOrder", b"\x00"), _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attr("screenWindowCenter", "v2f", struct.pack("<2f", 0, 0)),
        _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        _attr("name", "string", name.encode()), _attr("type", "string", part_type.encode()),
        _attr("chunkCount", "int", struct.pack("<i", h)),
    ]) + b"\0"


def deep_behind_scanline_exr() -> bytes:
    """A multi-part file by the File Layout: part 0 a 16 x 8 scanline image, part 1 a deep scanline part; the
    offset tables and chunks are zeros (the refusal must come from the headers)."""
    head = b"\x76\x2f\x31\x01" + struct.pack("<i", 2 | 0x1000)
    return head + _part("a", "scanlineimage", 16, 8) + _part("b", "deepscanline", 16, 8) + b"\0" + bytes(8 * 16 + 64)


def tile_bomb_exr(tile_rows: int) -> bytes:
    """A 16 x 8 tiled image (written by the bindings with 16 x 16 tiles) whose tile description is then set to
    16 x ``tile_rows``: one tile still covers the image, so the file stays valid; the decoder's memory grows with
    the tile (3 GB at 16 M rows, measured), far past the workers' 1 GiB here."""
    td = OpenEXR.TileDescription()
    td.xSize, td.ySize, td.mode = 16, 16, OpenEXR.ONE_LEVEL
    z = np.ones((8, 16), np.float32)
    buf = io.BytesIO()
    with OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.tiledimage, "tiles": td},
                      {"R": z, "G": z, "B": z}) as f:
        f.write(buf)
    data = bytearray(buf.getvalue())
    at = data.index(b"tiles\0tiledesc\0") + len(b"tiles\0tiledesc\0") + 4
    data[at:at + 8] = struct.pack("<2I", 16, tile_rows)
    return bytes(data)


def worst_case_rle(width: int, height: int) -> bytes:
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, width)
    row = bytes([2, 2, width >> 8, width & 255]) + bytes([1, 128]) * (4 * width)
    return head + row * height


@pytest.mark.parametrize(("make", "fragments"), [
    (lambda: two_part_exr((8, 16), (2048, 4096)), ("parts", "8388736 pixels", "every part is decoded")),
    (deep_behind_scanline_exr, ("deep", "part 1", "deepscanline")),
    (lambda: tile_bomb_exr(100_000_000), ("tile size 16 x 100000000 is too large", "16 x 8")),
], ids=["big-part-behind-small", "deep-part-behind-scanline", "huge-tiles"])
def test_exr_header_bombs_are_refused_and_nothing_is_stored(uploader: Server, uh: httpx.Client, make: object,
                                                            fragments: tuple[str, ...]) -> None:
    assert callable(make)
    before = stored(uploader, uh)
    body = assert_problem(uh.post("/envmaps", content=make()), 422, *fragments)
    assert "Error" not in body["detail"]  # words, not an exception's name
    assert stored(uploader, uh) == before
    assert fresh_health(uh)["workers"] == 2


def test_corrupt_exr_chunks_say_what_is_wrong(uploader: Server, uh: httpx.Client, tmp_path: Path) -> None:
    good = exr_bytes(make_envmap(32, seed=9), tmp_path)
    before = stored(uploader, uh)
    bad = bytearray(good)
    bad[len(bad) // 2: len(bad) // 2 + 64] = bytes(range(64))
    body = assert_problem(uh.post("/envmaps", content=bytes(bad)), 422, "corrupt or truncated EXR pixel data")
    assert "IndexError" not in body["detail"] and "list index" not in body["detail"]
    assert stored(uploader, uh) == before


def test_worst_case_rle_hdr_at_the_pixel_limit_decodes(uploader: Server, uh: httpx.Client) -> None:
    """2048 x 1024 (the limit) in one-byte packets: 16 MB, 8.4 M packets. The previous decoder's gather plan
    (~60 bytes per texel in Python lists and index arrays) would pass the 1 GiB worker limit and be killed; the
    map is accepted, decoded exactly (RGBE 128 everywhere: 0.50195) and both workers stay."""
    data = worst_case_rle(2048, 1024)
    r = uh.post("/envmaps", content=data)
    assert r.status_code in (200, 201), r.text
    info = r.json()
    assert (info["width"], info["height"]) == (2048, 1024)
    np.testing.assert_allclose(info["max"], [128.5 / 256] * 3, rtol=1e-6)
    np.testing.assert_allclose(info["min"], [128.5 / 256] * 3, rtol=1e-6)
    assert fresh_health(uh)["workers"] == 2
