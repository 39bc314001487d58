"""Deterministic ``.npz`` archives: the same arrays always give the same bytes.

``numpy.savez_compressed`` stamps every zip member with the current local time, so two writes of one result differ
in their bytes (and in their SHA-256, which names a blob in the service's content-addressed store). Here each
member is an ``.npy`` file (``numpy.lib.format.write_array``, no pickles) stored with a fixed timestamp, in the
order the mapping gives, DEFLATE-compressed as ``savez_compressed`` does; ``numpy.load`` reads the archive exactly
as it reads ``savez_compressed``'s. Manifests kept in an archive must not carry timings either
(:func:`without_timings`): a recomputed result is byte-identical only when everything in it is.
"""

from __future__ import annotations

import io
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike

#: The timestamp of every member: the earliest an MS-DOS date (a zip header's) can hold (PKWARE APPNOTE 4.4.6).
FIXED_DATE_TIME: Final = (1980, 1, 1, 0, 0, 0)
#: Keys of timing measurements in manifests (``relight.sh_table`` reports, ``relight.visibility`` manifests).
TIMING_KEYS: Final = frozenset({"seconds", "mrays_per_second"})


def npz_bytes(arrays: Mapping[str, ArrayLike]) -> bytes:
    """The ``.npz`` of ``arrays`` (name -> array; members ``<name>.npy`` in the mapping's order), module docstring."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, value in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)  # as numpy.savez
            info = zipfile.ZipInfo(f"{name}.npy", date_time=FIXED_DATE_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def write_npz(path: str | os.PathLike[str], arrays: Mapping[str, ArrayLike]) -> None:
    """Write :func:`npz_bytes` of ``arrays`` to ``path``."""
    Path(path).write_bytes(npz_bytes(arrays))


def without_timings(obj: Any) -> Any:
    """``obj`` (JSON-like) with every :data:`TIMING_KEYS` key removed at every level."""
    if isinstance(obj, dict):
        return {k: without_timings(v) for k, v in obj.items() if k not in TIMING_KEYS}
    if isinstance(obj, list | tuple):
        return [without_timings(v) for v in obj]
    return obj
