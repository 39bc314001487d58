"""Radiance RGBE (``.hdr``) reading and writing (own reader and writer: no maintained Python library reads RGBE
without pulling in a large imaging stack, and the header parser must stop at a size limit before decoding).

Source: Greg Ward, "Real Pixels" (Graphics Gems II, 1991) and the Radiance file-format notes
(Radiance reference manual, "Picture file format"; ``src/common/color.c`` and ``header.c`` of Radiance 5).

File layout::

    #?RADIANCE                    (or #?RGBE) program signature
    FORMAT=32-bit_rle_rgbe        header lines "NAME=value" (others are ignored)
    EXPOSURE=2.0                  optional; several multiply
                                  an empty line ends the header
    -Y 512 +X 1024                resolution line: rows top to bottom, columns left to right
    <scanlines>

Each pixel is four bytes ``(r, g, b, e)``: a shared exponent ``e`` (bias 128) and 8-bit mantissas. Radiance
decodes ``c = (m + 0.5) 2^(e - 136)`` (``colr_color``; ``e = 0`` is black) and encodes with
``frexp(max(r, g, b))`` and truncation (``setcolr``). A scanline is either *flat* (``4 W`` bytes, pixel
interleaved) or *new-style run-length encoded*: the bytes ``2, 2, W >> 8, W & 255`` then the four components
one after another, each as packets ``n <= 128`` (``n`` literal bytes follow) or ``n > 128`` (one byte repeated
``n - 128`` times). New-style RLE is only used for ``8 <= W < 32768``. The older "1, 1, 1, count" repeat
encoding is not supported (it is rejected with a clear error).

``EXPOSURE`` says the pixels were multiplied by that factor; the reader divides it out so the returned values
are the original radiance (Radiance manual, "EXPOSURE").
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from relight.envmap.formats import ImageHeader, NeedMoreData, check_rgb_image
from relight.errors import InputError

log = logging.getLogger("relight.envmap")

#: Radiance exponent bias (``COLXS`` in ``color.h``).
_COLXS = 128
#: New-style RLE is defined for scanline widths in [_MINELEN, _MAXELEN] (``color.c``).
_MINELEN = 8
_MAXELEN = 0x7FFF
#: Shortest run the encoder writes as a run packet (``MINRUN`` in ``color.c``).
_MINRUN = 4
#: Largest header accepted, in bytes: a guard against a stream that never ends its header.
MAX_HEADER_BYTES = 1 << 20

SIGNATURES = (b"#?RADIANCE", b"#?RGBE")


@dataclass(frozen=True)
class HdrHeader:
    """What the header and resolution line of a Radiance file say."""

    width: int
    height: int
    exposure: float  # product of all EXPOSURE values (1.0 if none)
    data_offset: int  # byte offset of the first scanline

    @property
    def image(self) -> ImageHeader:
        """The format-independent header: RGB, 8-bit mantissas with a shared exponent."""
        return ImageHeader("hdr", self.width, self.height, 3, 8)


def parse_header(buf: bytes, *, complete: bool = True) -> HdrHeader:
    """Parse the Radiance header and resolution line of ``buf``.

    With ``complete=False`` a buffer that ends inside the header raises :class:`NeedMoreData` instead of
    :class:`~relight.errors.InputError`, so a caller can read more of a file and try again.
    """
    first = buf.split(b"\n", 1)[0]
    if not buf.startswith(b"#?"):
        raise InputError(f"not a Radiance HDR file: it starts with {bytes(buf[:10])!r}, not '#?RADIANCE'")
    if b"\n" in buf and first.rstrip(b"\r") not in SIGNATURES:
        raise InputError(f"unsupported Radiance signature {first[:40]!r}: expected '#?RADIANCE' or '#?RGBE'")
    pos = 0
    exposure = 1.0
    while True:
        end = buf.find(b"\n", pos)
        if end < 0:
            if len(buf) > MAX_HEADER_BYTES:
                raise InputError(f"Radiance HDR header longer than {MAX_HEADER_BYTES} bytes")
            if not complete:
                raise NeedMoreData
            raise InputError("truncated Radiance HDR file: the header has no end (no empty line)")
        line = buf[pos:end].rstrip(b"\r")
        pos = end + 1
        if pos > MAX_HEADER_BYTES:
            raise InputError(f"Radiance HDR header longer than {MAX_HEADER_BYTES} bytes")
        if not line:
            break
        if line.startswith(b"FORMAT="):
            fmt = line[7:].strip()
            if fmt != b"32-bit_rle_rgbe":
                raise InputError(f"unsupported Radiance pixel format {fmt.decode('latin-1')!r}: "
                                 "only FORMAT=32-bit_rle_rgbe is supported")
        elif line.startswith(b"EXPOSURE="):
            try:
                value = float(line[9:].strip())
            except ValueError:
                raise InputError(f"bad Radiance EXPOSURE line {line[:60]!r}") from None
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"bad Radiance EXPOSURE value {value}: it must be positive and finite")
            exposure *= value
    end = buf.find(b"\n", pos)
    if end < 0:
        if not complete and len(buf) - pos < 64:
            raise NeedMoreData
        raise InputError("truncated Radiance HDR file: the resolution line is missing")
    res = buf[pos:end].rstrip(b"\r").decode("latin-1")
    parts = res.split()
    if len(parts) != 4 or not all(p.isascii() and p.isdigit() for p in (parts[1], parts[3])):  # not '3²'
        raise InputError(f"bad Radiance resolution line {res[:60]!r}: expected '-Y <height> +X <width>'")
    if parts[0] != "-Y" or parts[2] != "+X":
        raise InputError(f"unsupported Radiance orientation {res[:60]!r}: only '-Y <height> +X <width>' "
                         "(rows top to bottom, columns left to right) is supported")
    height, width = int(parts[1]), int(parts[3])
    if height == 0 or width == 0:
        raise InputError(f"empty Radiance HDR image: {width} x {height}")
    return HdrHeader(width=width, height=height, exposure=exposure, data_offset=end + 1)


def decode(buf: bytes, header: HdrHeader | None = None) -> NDArray[np.float32]:
    """Decode a whole Radiance file to an (H, W, 3) float32 array of linear RGB.

    The run-length structure is walked once per packet in Python (an RLE stream is inherently sequential), each
    packet copied straight into the planar output: memory is the output's, whatever the packets (the worst case,
    packets of one byte, once needed a gather plan of 60 bytes per pixel); flat scanlines are moved by one
    vectorised gather at the end.
    """
    hdr = header if header is not None else parse_header(buf)
    width, height = hdr.width, hdr.height
    n = len(buf)
    rle_ok = _MINELEN <= width <= _MAXELEN
    planar_bytes = bytearray(height * 4 * width)  # (scanline, component, column)
    flat_rows: list[int] = []
    flat_srcs: list[int] = []
    p = hdr.data_offset
    row_bytes = 4 * width
    for y in range(height):
        if p + 4 > n:
            raise InputError(f"truncated Radiance HDR data at scanline {y} of {height}")
        if rle_ok and buf[p] == 2 and buf[p + 1] == 2 and buf[p + 2] < 128:
            w = (buf[p + 2] << 8) | buf[p + 3]
            if w != width:
                raise InputError(f"bad Radiance RLE scanline {y}: it says width {w}, the image is {width} wide")
            p += 4
            o = y * row_bytes
            o_end = o + row_bytes
            # Components follow each other, so the planar output offset simply runs over 4 W bytes.
            while o < o_end:
                if p >= n:
                    raise InputError(f"truncated Radiance HDR data at scanline {y} of {height}")
                c = buf[p]
                count = c - 128 if c > 128 else c
                if count == 0 or (o % width) + count > width:
                    raise InputError(f"bad Radiance RLE data in scanline {y}: a packet of {count} bytes "
                                     f"at column {o % width} overruns the width {width}")
                end = p + 2 if c > 128 else p + 1 + c
                if end > n:
                    raise InputError(f"truncated Radiance HDR data at scanline {y} of {height}")
                planar_bytes[o:o + count] = buf[p + 1:p + 2] * count if c > 128 else buf[p + 1:end]
                p = end
                o += count
        else:
            if p + row_bytes > n:
                raise InputError(f"truncated Radiance HDR data at scanline {y} of {height}")
            flat_rows.append(y)
            flat_srcs.append(p)
            p += row_bytes
    data = np.frombuffer(buf, dtype=np.uint8)
    planar = np.frombuffer(planar_bytes, dtype=np.uint8).reshape(height, 4, width)
    if flat_rows:
        fs = np.asarray(flat_srcs, dtype=np.int64)[:, None] + np.arange(row_bytes)
        flat = data[fs].reshape(len(flat_rows), width, 4)
        if np.any((flat[..., 0] == 1) & (flat[..., 1] == 1) & (flat[..., 2] == 1)):
            bad = int(np.flatnonzero(np.any((flat[..., 0] == 1) & (flat[..., 1] == 1) & (flat[..., 2] == 1),
                                            axis=1))[0])
            raise InputError(f"old-style Radiance RLE (1,1,1,n repeat pixels) in scanline {flat_rows[bad]} "
                             "is not supported")
        planar[np.asarray(flat_rows)] = flat.transpose(0, 2, 1)
    rgb = rgbe_to_float(planar.transpose(0, 2, 1))
    if hdr.exposure != 1.0:
        rgb /= np.float32(hdr.exposure)
    return rgb


def rgbe_to_float(rgbe: NDArray[np.uint8]) -> NDArray[np.float32]:
    """(..., 4) RGBE bytes to (..., 3) float32: ``(m + 0.5) 2^(e - 136)``, ``e = 0`` -> 0 (``colr_color``)."""
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(np.float32(1.0), e - (_COLXS + 8)), np.float32(0.0)).astype(np.float32)
    return ((rgbe[..., :3].astype(np.float32) + np.float32(0.5)) * scale[..., None]).astype(np.float32)


def float_to_rgbe(rgb: NDArray[np.floating]) -> NDArray[np.uint8]:
    """(..., 3) non-negative floats to (..., 4) RGBE bytes, as Radiance's ``setcolr``.

    ``v = max(r, g, b)``; ``v = f 2^e`` with ``f`` in [0.5, 1) (frexp); mantissas ``floor(c f 256 / v)``,
    exponent ``e + 128``. Values below ``1e-32`` (and whatever underflows the exponent) become black; values
    of ``2^127`` or more are clamped to the largest representable pixel.
    """
    x = np.asarray(rgb, dtype=np.float64)
    v = x.max(axis=-1)
    frac, exp = np.frexp(v)
    big = exp > 127
    ok = (v > 1e-32) & (exp + _COLXS >= 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(ok, frac * 256.0 / np.where(ok, v, 1.0), 0.0)
    mant = np.clip(np.floor(x * scale[..., None]), 0, 255)
    mant[big] = np.where(x[big] >= v[big][..., None], 255, np.floor(x[big] / v[big][..., None] * 256.0))
    out = np.empty(x.shape[:-1] + (4,), dtype=np.uint8)
    out[..., :3] = np.where(ok[..., None], mant, 0)
    out[..., 3] = np.where(ok, np.minimum(exp, 127) + _COLXS, 0)
    return out


def _rle_encode(planar: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """New-style RLE of (H, 4, W) component-planar bytes, vectorised over the whole image.

    Runs of at least ``_MINRUN`` equal bytes become run packets (split at 127); everything between them
    becomes literal packets (split at 128). Every scanline is prefixed by ``2, 2, W >> 8, W & 255``.
    """
    height, _, width = planar.shape
    flat = planar.reshape(-1)
    total = flat.size
    k = np.arange(total)
    new_run = np.ones(total, dtype=bool)
    new_run[1:] = flat[1:] != flat[:-1]
    new_run[k % width == 0] = True  # runs never cross a component/scanline boundary
    run_start = np.flatnonzero(new_run)
    run_len = np.diff(np.append(run_start, total))
    long_run = run_len >= _MINRUN
    in_long = np.repeat(long_run, run_len)
    # Long runs -> pieces of at most 127.
    lr_start, lr_len = run_start[long_run], run_len[long_run]
    n_pieces = -(-lr_len // 127)
    piece_run = np.repeat(np.arange(lr_len.size), n_pieces)
    piece_idx = np.arange(piece_run.size) - np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
    rp_src = lr_start[piece_run] + 127 * piece_idx
    rp_len = np.minimum(127, lr_len[piece_run] - 127 * piece_idx)
    # Literal segments: maximal stretches outside long runs, within one component stream.
    lit = ~in_long
    seg_start_mask = lit.copy()
    seg_start_mask[1:] &= ~lit[:-1] | (k[1:] % width == 0)
    seg_start = np.flatnonzero(seg_start_mask)
    seg_end_mask = lit.copy()
    seg_end_mask[:-1] &= ~lit[1:] | (k[1:] % width == 0)
    seg_len = np.flatnonzero(seg_end_mask) + 1 - seg_start
    n_lp = -(-seg_len // 128)
    lp_seg = np.repeat(np.arange(seg_len.size), n_lp)
    lp_idx = np.arange(lp_seg.size) - np.repeat(np.cumsum(n_lp) - n_lp, n_lp)
    lp_src = seg_start[lp_seg] + 128 * lp_idx
    lp_len = np.minimum(128, seg_len[lp_seg] - 128 * lp_idx)
    # Merge packets in source order; output size of a packet is 1 header byte + payload.
    src = np.concatenate([rp_src, lp_src])
    length = np.concatenate([rp_len, lp_len])
    run = np.concatenate([np.ones(rp_src.size, bool), np.zeros(lp_src.size, bool)])
    order = np.argsort(src, kind="stable")
    src, length, run = src[order], length[order], run[order]
    payload = np.where(run, 1, length)
    row = src // (4 * width)
    out_pos = np.cumsum(1 + payload) - (1 + payload) + 4 * (row + 1)  # 4 bytes of scanline header per row
    out = np.empty(int(np.sum(1 + payload)) + 4 * height, dtype=np.uint8)
    out[out_pos] = np.where(run, 128 + length, length).astype(np.uint8)
    out[out_pos[run] + 1] = flat[src[run]]
    lit_bytes = np.flatnonzero(lit)
    lit_piece = np.flatnonzero(~run)
    shift = out_pos[lit_piece] + 1 - src[lit_piece]
    out[lit_bytes + np.repeat(shift, length[lit_piece])] = flat[lit_bytes]
    # Scanline headers sit just before the first packet of each row.
    first_of_row = np.searchsorted(row, np.arange(height))
    hdr_pos = out_pos[first_of_row] - 4
    out[hdr_pos] = 2
    out[hdr_pos + 1] = 2
    out[hdr_pos + 2] = width >> 8
    out[hdr_pos + 3] = width & 255
    return out


def encode(rgb: NDArray[np.floating]) -> bytes:
    """Encode an (H, W, 3) non-negative finite array as a complete Radiance file (header + scanlines)."""
    height, width = rgb.shape[:2]
    header = (b"#?RADIANCE\n# written by relight\nFORMAT=32-bit_rle_rgbe\n\n"
              + f"-Y {height} +X {width}\n".encode("ascii"))
    rgbe = float_to_rgbe(rgb)
    if _MINELEN <= width <= _MAXELEN:
        body = _rle_encode(np.ascontiguousarray(rgbe.transpose(0, 2, 1)))
    else:
        body = rgbe.reshape(-1)
    return header + body.tobytes()


def write(path: str | os.PathLike[str], rgb: NDArray[np.floating]) -> None:
    """Write an (H, W, 3) non-negative finite array to ``path`` as Radiance RGBE with new-style RLE."""
    with open(path, "wb") as fh:
        fh.write(encode(rgb))


def write_hdr(path: str | os.PathLike[str], rgb: NDArray[np.floating]) -> None:
    """Write (H, W, 3) linear RGB as Radiance RGBE with new-style RLE scanlines.

    RGBE has no sign: negative values are written as 0 (the count is logged). Non-finite values are an error.
    """
    arr = np.asarray(check_rgb_image(rgb, "the image"), dtype=np.float64)
    if not np.isfinite(arr).all():
        raise InputError(f"cannot write {int(np.sum(~np.isfinite(arr)))} non-finite values to a Radiance HDR file")
    n = int(np.sum(arr < 0))
    if n:
        log.warning("write_hdr %s: %d negative values written as 0", path, n)
    write(path, np.maximum(arr, 0.0))
