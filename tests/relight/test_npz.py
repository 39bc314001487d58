"""relight.npz: deterministic archives that numpy.load reads like numpy.savez_compressed's."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from relight.npz import FIXED_DATE_TIME, npz_bytes, without_timings, write_npz


def arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(42)
    return {"coefficients": rng.standard_normal((3, 4, 5)).astype(np.float32),
            "fortran": np.asfortranarray(rng.standard_normal((4, 3))), "valid": rng.random((3, 4)) > 0.5,
            "manifest": np.array(json.dumps({"order": 2}))}  # 0-d unicode, as the SH table's manifest


def test_numpy_reads_what_savez_compressed_would_give(tmp_path: Path) -> None:
    want = arrays()
    write_npz(tmp_path / "a.npz", want)
    np.savez_compressed(tmp_path / "b.npz", **want)  # the reference: numpy's own writer
    with np.load(tmp_path / "a.npz") as got, np.load(tmp_path / "b.npz") as ref:
        assert list(got.keys()) == list(ref.keys()) == list(want)
        for name in want:
            assert got[name].dtype == ref[name].dtype and got[name].shape == ref[name].shape, name
            np.testing.assert_array_equal(got[name], ref[name])
    assert json.loads(str(np.load(tmp_path / "a.npz")["manifest"])) == {"order": 2}


def test_bytes_depend_on_the_arrays_only() -> None:
    first = npz_bytes(arrays())
    assert npz_bytes(arrays()) == first
    with zipfile.ZipFile(io.BytesIO(first)) as zf:  # every member stamped with the fixed time, compressed
        assert {i.date_time for i in zf.infolist()} == {FIXED_DATE_TIME}
        assert {i.compress_type for i in zf.infolist()} == {zipfile.ZIP_DEFLATED}
    changed = arrays()
    changed["coefficients"][0, 0, 0] += 1.0
    assert npz_bytes(changed) != first


def test_without_timings_drops_them_at_every_level() -> None:
    doc = {"order": 2, "seconds": 1.5, "report": {"seconds": 0.1, "refine": 2},
           "runs": [{"mrays_per_second": 3.0, "rays": 64}]}
    assert without_timings(doc) == {"order": 2, "report": {"refine": 2}, "runs": [{"rays": 64}]}
