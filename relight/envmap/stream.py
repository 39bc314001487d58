"""Lat-long EXR maps larger than memory should hold (Poly Haven's 8k and 16k): streamed scanline chunks, an
area-exact downsample and an exact streamed SH projection (issue 17, item 8).

A 16384 x 8192 map is 1.6 GB as float32 RGB and twice that in float64; nothing here holds it. OpenEXR reads any
range of scanlines (``OpenEXR.InputFile.channels(names, FLOAT, y0, y1)``, which decodes only the chunks holding
them), so the file is read ``chunk_rows`` rows at a time and each chunk is folded into

* the **area-exact downsample** to ``rows x 2 rows``: the same sparse overlap weights as
  :func:`relight.envmap.resample_latlong` (rows by ``cos theta`` of the overlap, columns by the ``phi`` length;
  each input row meets at most two output rows), so ``sum L Omega`` is kept per output pixel and the result
  equals ``resample_latlong`` of the whole map to rounding, in any chunking;
* optionally the map's **SH coefficients to ``lmax``** from the full-resolution rows: ducc0's adjoint synthesis
  of the chunk's rings (Fejér F1 ring weights of the *whole* map, :func:`relight.sh.quadrature_weights`), whose
  sum over chunks is :func:`relight.sh.project` of the whole map (the transform is linear in the rings), and
  the luminance energy of :func:`relight.prefilter.project_lighting`.

Memory: one chunk (its copies: :data:`CHUNK_BYTES_PER_PIXEL` bytes per pixel), the overlap matrices, the
output (``rows x 2 rows x 3`` float64) and the coefficients, whatever the file's height: :func:`memory_bound`
states it (a 16384 x 8192 map in 64-row chunks to 2048 rows and l = 256: 0.5 GiB, mostly the output).
Values are validated as :func:`relight.envmap.read_envmap` does (non-finite rejected with its position,
negatives clamped to 0 and counted).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix

from relight.errors import InputError

F32 = NDArray[np.float32]
FloatArray = NDArray[np.float64]

#: Pixels read per chunk by default (``chunk_rows = CHUNK_PIXELS // W``): 64 rows of a 16k map.
CHUNK_PIXELS = 1 << 20
#: Bytes held per chunk pixel at most (:func:`memory_bound`): OpenEXR's float32 planes and their stack (24), the
#: finite and negative masks (6), the float64 copy and its column-major copy (48), a channel for ducc0 (8), the
#: luminance and its square (16), and 10 spare.
CHUNK_BYTES_PER_PIXEL = 112
#: Bytes per input row or column for the sparse overlap matrices (COO, CSR and the transpose's copies).
WEIGHT_BYTES = 100


@dataclass(frozen=True)
class StreamedMap:
    """The downsample (``rows x 2 rows x 3`` float32), the source's size, what validation changed and, when asked
    for, the full-resolution SH coefficients (3, nalm) to ``lmax`` and luminance energy."""

    pixels: F32 = field(repr=False)
    source_height: int
    source_width: int
    negatives_clamped: int
    min_negative: float
    lmax: int | None
    alm: NDArray[np.complex128] | None = field(repr=False)
    total_energy: float | None


def memory_bound(width: int, rows: int, chunk_rows: int, lmax: int | None = None) -> int:
    """Bytes the streaming of a ``width x width / 2`` map allocates at most (NumPy and OpenEXR's returned
    buffers): the chunk's copies (:data:`CHUNK_BYTES_PER_PIXEL` per pixel, plus its column-reduced rows), the
    overlap matrices, the float64 output twice (the sum and the float32 result's source) and two coefficient
    sets. Independent of the file's height but through ``width``."""
    chunk = chunk_rows * width * CHUNK_BYTES_PER_PIXEL + chunk_rows * 2 * rows * 3 * 8 * 2
    weights = WEIGHT_BYTES * (width + width // 2)
    out = rows * 2 * rows * 3 * 8 * 2
    coeffs = 0 if lmax is None else 2 * 3 * (lmax + 1) * (lmax + 2) // 2 * 16
    return chunk + weights + out + coeffs


def _overlap_matrix(n_in: int, n_out: int, rows: bool) -> csr_matrix:
    """(n_out, n_in) normalised overlap weights of :func:`relight.envmap.resample._area_weights`."""
    from relight.envmap.resample import _area_weights

    if rows:
        o, i, w, _ = _area_weights(n_in, n_out, lambda k: np.cos(np.pi * k / (n_in * n_out)))
    else:
        o, i, w, _ = _area_weights(n_in, n_out, lambda k: k / (n_in * n_out))
    return csr_matrix((w, (o, i)), shape=(n_out, n_in))


def exr_chunks(path: str | os.PathLike[str], chunk_rows: int) -> Iterator[tuple[int, F32]]:
    """(first row, (n, W, 3) float32 RGB) for consecutive row ranges of an EXR file's RGB (or luminance Y) channels."""
    import Imath
    import OpenEXR

    try:
        f = OpenEXR.InputFile(os.fspath(path))
    except OSError as exc:
        raise InputError(f"cannot read the EXR file {os.fspath(path)!r}: {exc}") from None
    try:
        dw = f.header()["dataWindow"]
        x0, y0, x1, y1 = dw.min.x, dw.min.y, dw.max.x, dw.max.y
        names = set(f.header()["channels"])
        chans = ["R", "G", "B"] if {"R", "G", "B"} <= names else ["Y"] * 3 if "Y" in names else None
        if chans is None:
            raise InputError(f"the EXR file has no R, G, B (or Y) channels, only {sorted(names)}")
        width = x1 - x0 + 1
        pt = Imath.PixelType(Imath.PixelType.FLOAT)
        for start in range(y0, y1 + 1, chunk_rows):
            stop = min(start + chunk_rows, y1 + 1)
            planes = f.channels(chans, pt, start, stop - 1)
            arr = np.stack([np.frombuffer(p, dtype=np.float32).reshape(stop - start, width) for p in planes], axis=-1)
            yield start - y0, arr
    finally:
        f.close()


def stream_latlong(path: str | os.PathLike[str], rows: int, *, lmax: int | None = None,
                   chunk_rows: int | None = None) -> StreamedMap:
    """Stream a lat-long EXR (W = 2H) into its area-exact ``rows``-row downsample (``rows`` <= H) and, with
    ``lmax``, its full-resolution SH coefficients (module docstring); ``chunk_rows`` defaults to
    ``CHUNK_PIXELS // W``."""
    import ducc0

    from relight import sh
    from relight.conventions import LUMINANCE_WEIGHTS, phi0
    from relight.envmap.headers import probe

    hdr = probe(path)
    if hdr.format != "exr":
        raise InputError(f"only EXR files are streamed, got {hdr.format}")
    h, w = hdr.height, hdr.width
    if w != 2 * h:
        raise InputError(f"image is {w} x {h}: a streamed lat-long map must have width = 2 x height")
    if not 1 <= rows <= h:
        raise InputError(f"the downsample must have 1 to {h} rows, got {rows}")
    if chunk_rows is None:
        chunk_rows = max(1, CHUNK_PIXELS // w)
    if chunk_rows < 1:
        raise InputError(f"chunk_rows must be positive, got {chunk_rows}")
    row_w = _overlap_matrix(h, rows, rows=True)
    col_w_t = _overlap_matrix(w, 2 * rows, rows=False).T.tocsr()  # (W, 2 rows)
    out = np.zeros((rows, 2 * rows * 3))
    ring_w = sh.quadrature_weights(h, "fejer")
    theta = (np.arange(h) + 0.5) * np.pi / h
    alm = None if lmax is None else np.zeros((3, (lmax + 1) * (lmax + 2) // 2), dtype=np.complex128)
    energy = 0.0
    count, min_neg = 0, 0.0
    for y, chunk in exr_chunks(path, chunk_rows):
        n = chunk.shape[0]
        finite = np.isfinite(chunk)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            raise InputError(f"{int((~finite).sum())} non-finite pixel values (NaN/Inf) in rows {y}..{y + n - 1}, "
                             f"first at row {y + int(bad[0])}, column {int(bad[1])}")
        neg = chunk < 0
        if neg.any():
            count += int(neg.sum())
            min_neg = min(min_neg, float(chunk.min()))
        px = chunk.astype(np.float64)
        np.maximum(px, 0.0, out=px)
        del neg, finite
        # columns first (each chunk row independently), then the rows this chunk touches
        cols = (col_w_t.T @ px.transpose(1, 0, 2).reshape(w, n * 3)).reshape(2 * rows, n, 3)
        out += row_w[:, y:y + n] @ cols.transpose(1, 0, 2).reshape(n, 2 * rows * 3)
        if alm is not None and lmax is not None:
            sel = slice(y, y + n)
            for c in range(3):
                alm[c] += ducc0.sht.experimental.adjoint_synthesis(
                    map=np.ascontiguousarray(px[..., c]).reshape(1, -1), theta=theta[sel], lmax=lmax, spin=0,
                    nphi=np.full(n, w, dtype=np.uintp), phi0=np.full(n, phi0(w)),
                    ringstart=np.arange(n, dtype=np.uintp) * w, ringfactor=ring_w[sel] / w,
                    nthreads=sh.NTHREADS)[0]
            lum = px @ LUMINANCE_WEIGHTS.astype(np.float64)
            energy += float(ring_w[sel] @ np.square(lum).mean(axis=1))
    return StreamedMap(pixels=out.reshape(rows, 2 * rows, 3).astype(np.float32), source_height=h, source_width=w,
                       negatives_clamped=count, min_negative=min_neg, lmax=lmax, alm=alm,
                       total_energy=None if lmax is None else energy)
