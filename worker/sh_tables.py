"""The ``sh_table`` job's task: a per-view SH table of a BRDF (seed 003 §3, ``relight.sh_table``) into the blob store.

Files: ``table.npz`` (``relight.sh_table.write_table``: float32 ``coefficients`` R x R x (F+1)^2 x C, ``views``,
``valid``, ``manifest``) and ``table.bin`` (the viewer's texture: little-endian float16 ``[(F+1)^2, R, R, C]``,
values beyond 65504 clamped and counted in the manifest's ``float16_clamped``). The result is the manifest (order,
layout, resolution, BRDF, seconds: the file's manifest leaves the seconds out, so that a table computed again is
byte-identical) plus the files. A measured BRDF arrives as ``{"kind": "merl", "sha256": ...}``
and is read from the blob store (``relight.worker.specs``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from relight.worker.progress import JobContext
from relight.worker.specs import from_core, to_core

OCTET = "application/octet-stream"


def compute_sh_table(ctx: JobContext, request: dict[str, Any]) -> dict[str, Any]:
    from relight.brdf.spec import parse_frame_brdf
    from relight.envmap.exr import to_half_safe
    from relight.sh_table import build_table, write_table

    ctx.report("tabulating", 0.05)
    table = build_table(parse_frame_brdf(to_core(request["brdf"], ctx.store)), order=int(request["order"]),
                        resolution=int(request["resolution"]), layout=str(request["layout"]))
    table.brdf = from_core(table.brdf, ctx.store)  # no blob path in the manifest or the file
    ctx.report("writing", 0.9)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "table.npz"
        manifest = write_table(path, table)
        npz = ctx.store.put_bytes(path.read_bytes())
    half = np.ascontiguousarray(np.transpose(to_half_safe(table.coefficients)[0], (2, 0, 1, 3)), dtype="<f2")
    texture = ctx.store.put_bytes(half.tobytes())
    manifest["files"] = {"table.bin": {"dtype": "float16", "byte_order": "little",
                                       "shape": list(half.shape), "order": "coefficient, row, column, channel"}}
    return {"manifest": manifest, "compute_seconds": table.report.get("seconds"),
            "files": {"table.npz": {"sha256": npz, "media_type": OCTET},
                      "table.bin": {"sha256": texture, "media_type": OCTET}}}
