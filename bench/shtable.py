"""Seed 003 SH tables and rotation on this machine (Kautz, Sloan & Snyder 2002, §3, §6, Appendix).

Measures, in one run:

* an analytic anisotropic 128 x 128 x 25 table (Ashikhmin–Shirley (48, 16), R_s = 0.05; issue target < 10 s;
  the paper: "a few minutes" with 1000 samples per integral);
* predicted seconds of both tables (``relight.sh_table_predict.predicted_table_seconds``) beside the measured;
* a MERL-format table: a MERL file synthesised from Torrance–Sparrow GGX 0.2 (``tabulate_merl``, no MERL file
  ships), read back by ``MERLBRDF`` (trilinear), 128 x 128 x 25 x RGB through the isotropic 1-D path (target
  < 60 s; the paper: "up to 90 minutes" for measured data);
* the table's agreement with a 2x finer quadrature (``refine=2``) in units of the largest coefficient, for views
  up to 85 degrees and overall (the rim);
* the interpolation error per byte of the two view maps (parabolic vs hemi-octahedral, R = 64, 400 random views);
* real SH rotation throughput: ``band_rotations`` for 100,000 frames at F = 4 (n = 25) and F = 8 (n = 81), and the
  local lighting rotation ``local_rotations`` + ``rotate_coefficients`` (RGB) at F = 4.

Prints a markdown table and writes JSON (``--json PATH``). ``--quick``: 32 x 32 tables, 10,000 frames.
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from relight.brdf.measured import MERLBRDF, tabulate_merl, write_merl
from relight.brdf.models import TorranceSparrow
from relight.brdf.spec import parse_frame_brdf
from relight.sh_rotation import band_rotations, local_rotations, rotate_coefficients
from relight.sh_table import build_table, project_views
from relight.sh_table_predict import predicted_table_seconds


def timed(fn: Any) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    res = 32 if args.quick else 128
    n_frames = 10_000 if args.quick else 100_000
    rows: list[tuple[str, str]] = []
    out: dict[str, Any] = {"machine": platform.platform(), "resolution": res}

    as48 = parse_frame_brdf("ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0")
    table, t_as = timed(lambda: build_table(as48, resolution=res))
    out["analytic_seconds"] = t_as
    rows.append((f"AS (48,16) table {res}x{res}x25", f"{t_as:.2f} s (target < 10 s)"))
    pred = predicted_table_seconds(as48, 4, res)
    out["analytic_predicted_seconds"] = pred
    rows.append(("  predicted (relight.sh_table_predict)", f"{pred:.2f} s"))

    fine, t_fine = timed(lambda: build_table(as48, resolution=res, refine=2))
    diff = np.abs(table.coefficients - fine.coefficients).max(axis=(2, 3)) / np.abs(fine.coefficients).max()
    inner = table.views[..., 2] > np.cos(np.radians(85.0))
    out["refine2"] = {"seconds": t_fine, "max_inner": float(diff[inner].max()), "max_all": float(diff.max())}
    rows.append(("vs 2x finer rule, views <= 85 deg", f"{diff[inner].max():.2e} of max |c|"))
    rows.append(("vs 2x finer rule, all texels (rim)", f"{diff.max():.2e} of max |c|"))

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ggx.binary"
        write_merl(path, tabulate_merl(TorranceSparrow(0.2, "ggx", "schlick", f0=[0.95, 0.64, 0.54])))
        merl = MERLBRDF(path)
        mtable, t_merl = timed(lambda: build_table(merl, resolution=res))
    out["merl_seconds"] = t_merl
    rows.append((f"MERL-format table {res}x{res}x25xRGB", f"{t_merl:.2f} s (target < 60 s)"))
    pred_merl = predicted_table_seconds(merl, 4, res)
    out["merl_predicted_seconds"] = pred_merl
    rows.append(("  predicted (relight.sh_table_predict)", f"{pred_merl:.2f} s"))
    out["merl_albedo_max"] = float(mtable.albedo().max())

    rng = np.random.default_rng(2)
    v = rng.normal(size=(400, 3))
    v[:, 2] = np.abs(v[:, 2])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    as12 = parse_frame_brdf("ashikhmin-shirley:nu=12,nv=4")
    ref = project_views(as12, v, 4)
    for lay in ("parabolic", "hemi-octahedral"):
        err = float(np.sqrt(np.mean((build_table(as12, resolution=64, layout=lay).lookup(v) - ref) ** 2)))
        out[f"layout_rms_{lay}"] = err
        rows.append((f"{lay} 64x64 RMS interpolation error (AS 12,4)", f"{err:.2e}"))

    rots = Rotation.random(n_frames, random_state=1).as_matrix()
    for order in (4, 8):
        _, t_rot = timed(lambda order=order: band_rotations(rots, order))
        out[f"rotations_per_s_F{order}"] = n_frames / t_rot
        rows.append((f"band_rotations F={order} ({(order + 1) ** 2} coeffs)", f"{n_frames / t_rot:,.0f} frames/s"))
    light = rng.normal(size=(25, 3))
    _, t_loc = timed(lambda: rotate_coefficients(local_rotations(rots, 4), light[None]))
    out["local_lighting_per_s_F4"] = n_frames / t_loc
    rows.append(("local lighting F=4 RGB (parity rule incl.)", f"{n_frames / t_loc:,.0f} points/s"))

    print("| quantity | value |\n|---|---|")
    for k, val in rows:
        print(f"| {k} | {val} |")
    print(json.dumps(out, sort_keys=True))
    if args.json:
        args.json.write_text(json.dumps(out, indent=2, sort_keys=True))


if __name__ == "__main__":
    main()
