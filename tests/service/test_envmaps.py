"""``/envmaps``: uploads and every way an upload can be bad (the server stays healthy after each)."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest

from relight.client.sdk import RelightClient

from .support import assert_healthy, assert_problem, exr_bytes, hdr_bytes, make_envmap

pytestmark = pytest.mark.timeout(120)


def exr_header_only(width: int, height: int) -> bytes:
    """A syntactically valid scanline EXR header claiming width x height, with no pixel data."""

    def attr(name: str, typ: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iBBBBii", 2, 0, 0, 0, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = (
        attr("channels", "chlist", chlist)
        + attr("compression", "compression", b"\0")
        + attr("dataWindow", "box2i", box)
        + attr("displayWindow", "box2i", box)
        + attr("lineOrder", "lineOrder", b"\0")
        + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
        + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
        + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
        + b"\0"
    )
    return b"\x76\x2f\x31\x01" + struct.pack("<i", 2) + header


def png_header_only(width: int, height: int) -> bytes:
    """Signature, IHDR, an empty IDAT and IEND: the chunks a PNG reader walks to learn the size, no pixel data."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", b"") + chunk(b"IEND", b"")


def test_upload_returns_metadata_and_is_idempotent(client: RelightClient, http: httpx.Client,
                                                   data_tmp: Path) -> None:
    img = make_envmap(32, seed=3)
    img[0, 0, 0] = -0.002  # lossy-compression negatives are clamped and counted
    data = exr_bytes(img, data_tmp)
    r = http.post("/envmaps", content=data, params={"name": "neg.exr"})
    assert r.status_code in (200, 201), r.text
    body = r.json()
    assert body["width"] == 64 and body["height"] == 32 and body["format"] == "exr"
    assert body["negatives_clamped"] == 1 and body["min_negative"] == pytest.approx(-0.002, rel=1e-3)
    assert body["non_finite"] == 0
    assert len(body["sh_power_spectrum"]) == body["spectrum_lmax"] + 1 == 32
    assert body["max"][0] == pytest.approx(float(img[..., 0].max()), rel=1e-6)
    assert r.headers["location"] == f"/envmaps/{body['id']}"
    again = http.put("/envmaps", content=data)
    assert again.status_code == 200 and again.json()["id"] == body["id"]
    assert client.get_envmap(body["id"]).id == body["id"]
    assert body["id"] in {e.id for e in client.list_envmaps()}
    png = client.envmap_preview(body["id"])
    assert png.startswith(b"\x89PNG")


def test_hdr_upload(client: RelightClient, data_tmp: Path) -> None:
    env = client.upload_envmap(hdr_bytes(make_envmap(32, seed=4), data_tmp))
    assert env.format == "hdr" and env.width == 64


def test_oversized_body_by_content_length(http: httpx.Client) -> None:
    r = http.post("/envmaps", content=b"\x76\x2f\x31\x01" + bytes((1 << 20) + 100))
    assert_problem(r, 413, "limit")
    assert_healthy(http)


def test_oversized_streamed_body(http: httpx.Client) -> None:
    def chunks() -> Iterator[bytes]:
        yield b"\x76\x2f\x31\x01"
        for _ in range(24):
            yield bytes(64 * 1024)

    r = http.post("/envmaps", content=chunks())  # chunked: no Content-Length, counted while streaming
    assert_problem(r, 413, "limit")
    assert_healthy(http)


@pytest.mark.parametrize("body", [b"GIF89a" + bytes(100), b"%PDF-1.7\n" + bytes(100), b"hello"])
def test_wrong_magic(http: httpx.Client, body: bytes) -> None:
    assert_problem(http.post("/envmaps", content=body), 415, "accepted formats")
    assert_healthy(http)


def test_empty_body(http: httpx.Client) -> None:
    assert_problem(http.post("/envmaps", content=b""), 422, "empty")


def test_truncated_exr(http: httpx.Client, sample_exr: bytes) -> None:
    assert_problem(http.post("/envmaps", content=sample_exr[: len(sample_exr) // 2]), 422)
    assert_problem(http.post("/envmaps", content=sample_exr[:40]), 422, "truncated")
    assert_healthy(http)


def test_corrupted_exr(http: httpx.Client, sample_exr: bytes) -> None:
    bad = bytearray(sample_exr)
    rng = np.random.default_rng(5)
    start = len(bad) // 3
    bad[start:] = rng.integers(0, 256, len(bad) - start, dtype=np.uint8).tobytes()
    assert_problem(http.post("/envmaps", content=bytes(bad)), 422)
    assert_healthy(http)


def test_truncated_and_corrupted_hdr(http: httpx.Client, data_tmp: Path) -> None:
    data = hdr_bytes(make_envmap(32, seed=6), data_tmp)
    assert_problem(http.post("/envmaps", content=data[: len(data) // 2]), 422)
    assert_problem(http.post("/envmaps", content=data.replace(b"-Y 32 +X 64", b"-Y 32 +X 6x")), 422)
    assert_healthy(http)


@pytest.mark.parametrize("make", [exr_header_only, png_header_only])
def test_huge_dimensions_rejected_from_the_header(http: httpx.Client, make: object) -> None:
    data = make(100_000, 100_000)  # type: ignore[operator]
    r = http.post("/envmaps", content=data)
    assert_problem(r, 422, "100000 x 100000", "limit")
    assert len(data) < 1000  # nothing but the header was sent: the check cannot have decoded pixels
    assert_healthy(http)


def test_wrong_aspect_rejected_from_the_header(http: httpx.Client) -> None:
    assert_problem(http.post("/envmaps", content=exr_header_only(300, 200)), 422, "300 x 200")


def test_nan_pixels(http: httpx.Client, data_tmp: Path) -> None:
    img = make_envmap(32, seed=8)
    img[5, 7, 1] = np.nan
    img[9, 3, 2] = np.nan
    assert_problem(http.post("/envmaps", content=exr_bytes(img, data_tmp)), 422, "2 non-finite", "row 5")
    assert_healthy(http)


def test_unknown_envmap_ids(http: httpx.Client) -> None:
    assert_problem(http.get("/envmaps/" + "0" * 64), 404, "0" * 64)
    assert_problem(http.get("/envmaps/not-an-id"), 404, "not-an-id")
    assert_problem(http.get("/envmaps/" + "0" * 64 + "/preview.png"), 404)
