"""Streamed lat-long EXR maps (relight.envmap.stream, read_envmap above the streaming size): the area-exact
downsample in any chunking, the full-resolution SH from the chunks, memory bounded by the chunk, not the file.

References: ``resample_latlong`` of the whole decoded map (the in-memory downsample), a direct 2 x 2 block mean
weighted by exact pixel solid angles (independent of the sparse weights), ``relight.sh.project`` of the whole map
(the in-memory projection). Both sides sum the same float64 products in another order, so they agree to float32
output rounding (2^-24 relative) for pixels and to ~1e-15 for coefficients; 1e-6 is the issue's bound for SH.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from relight import sh
from relight.envmap import read_envmap, resample_latlong
from relight.envmap.exr import write_exr
from relight.envmap.stream import memory_bound, stream_latlong
from relight.errors import InputError
from relight.prefilter import project_lighting


def _map(h: int, seed: int = 1) -> np.ndarray:
    """Heavy-tailed random radiance with a few negative texels (as lossy EXR leaves) and a 'sun' pixel."""
    rng = np.random.default_rng(seed)
    px = (rng.random((h, 2 * h, 3)) ** 6 * 20.0).astype(np.float32)
    px[rng.integers(0, h, 5), rng.integers(0, 2 * h, 5), 1] = -0.01
    px[h // 5, h // 3] = 5.0e4
    return px


def _exr(tmp: Path, px: np.ndarray, name: str = "m.exr") -> Path:
    path = tmp / name
    write_exr(path, px)
    return path


@pytest.mark.parametrize("chunk", [1, 13, 500])
def test_downsample_equals_the_in_memory_area_average(tmp_path: Path, chunk: int) -> None:
    px = _map(96)
    path = _exr(tmp_path, px)
    full = np.asarray(read_envmap(path).pixels, dtype=np.float64)  # 96 rows: decoded whole, negatives clamped
    for rows in (96, 48, 33, 7):
        got = stream_latlong(path, rows, chunk_rows=chunk)
        np.testing.assert_allclose(got.pixels, resample_latlong(full, rows), rtol=3e-7, atol=0)
        assert got.negatives_clamped == 5 and got.min_negative == pytest.approx(-0.01)
    # independent: factor 2, each output pixel the solid-angle-weighted mean of its 2 x 2 block
    omega = np.cos(np.arange(96) * np.pi / 96) - np.cos(np.arange(1, 97) * np.pi / 96)
    wsum = full * omega[:, None, None]
    block = (wsum[0::2, 0::2] + wsum[0::2, 1::2] + wsum[1::2, 0::2] + wsum[1::2, 1::2])
    expect = block / (2 * (omega[0::2] + omega[1::2]))[:, None, None]
    np.testing.assert_allclose(stream_latlong(path, 48, chunk_rows=chunk).pixels, expect, rtol=3e-7)


def test_streamed_sh_equals_the_full_resolution_projection(tmp_path: Path) -> None:
    """SH to l = H - 1 = 255 from 37-row chunks against ``sh.project`` of the whole 256 x 512 map (the issue asks
    1e-6 at l = 256 of a 16k map; bench/big_map.py measures that one)."""
    px = _map(256, seed=2)
    path = _exr(tmp_path, px)
    full = np.asarray(read_envmap(path).pixels, dtype=np.float64)
    got = stream_latlong(path, 64, lmax=255, chunk_rows=37)
    ref = project_lighting(full, 255)
    assert got.alm is not None and got.total_energy is not None
    assert np.max(np.abs(got.alm - ref.alm)) <= 1e-6 * np.max(np.abs(ref.alm))
    assert got.total_energy == pytest.approx(ref.total_energy, rel=1e-9)
    # and it is the full resolution's, not the downsample's: those differ well above 1e-6 at high l
    low = sh.project(np.asarray(got.pixels, dtype=np.float64), 63)
    assert np.max(np.abs(sh.truncate(got.alm, 255, 63) - low)) > 1e-4 * np.max(np.abs(low))


def test_memory_is_bounded_by_the_chunk_not_the_file(tmp_path: Path) -> None:
    """A 1024 x 2048 map (24 MiB as float32 RGB) streamed in 8-row chunks to 64 rows: the peak of Python-side
    allocations (tracemalloc: NumPy's buffers and OpenEXR's returned scanline bytes) stays under
    ``memory_bound`` and under an eighth of the float32 map; decoding it whole needs at least the map."""
    h = 1024
    path = _exr(tmp_path, _map(h, seed=3))
    size = h * 2 * h * 3 * 4
    tracemalloc.start()
    try:
        stream_latlong(path, 64, lmax=32, chunk_rows=8)
        _, peak_stream = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        read_envmap(path)
        _, peak_whole = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak_stream < min(memory_bound(2 * h, 64, 8, 32), size // 8), (peak_stream, size)
    assert peak_whole >= size  # the comparison can fail: decoding whole holds the map


def test_read_envmap_streams_above_the_size_it_keeps(tmp_path: Path) -> None:
    px = _map(128, seed=4)
    path = _exr(tmp_path, px)
    env = read_envmap(path, max_rows=32)
    assert env.pixels.shape == (32, 64, 3) and env.source_format == "exr" and env.negatives_clamped == 5
    full = np.asarray(read_envmap(path).pixels, dtype=np.float64)
    np.testing.assert_allclose(env.pixels, resample_latlong(full, 32), rtol=3e-7)
    # bytes are decoded whole (the service's path), a taller max_rows leaves the map as it is
    assert read_envmap(path.read_bytes()).pixels.shape == (128, 256, 3)
    assert read_envmap(path, max_rows=512).pixels.shape == (128, 256, 3)
    with pytest.raises(InputError, match="max_rows"):
        read_envmap(path, max_rows=0)
    with pytest.raises(InputError, match="rows"):
        stream_latlong(path, 129)
    bad = px.copy()
    bad[70, 9, 2] = np.nan
    with pytest.raises(InputError, match="row 70, column 9"):
        stream_latlong(_exr(tmp_path, bad, "nan.exr"), 16, chunk_rows=16)
