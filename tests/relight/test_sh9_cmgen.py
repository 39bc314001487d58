"""The ``filament`` SH9 convention against Filament's own cmgen 1.9.25 (Debian ``libfilament-tools``).

``cmgen --sh=3 --sh-irradiance --sh-shader --sh-window=no`` prints the nine pre-scaled irradiance coefficients
its shader evaluates as ``sum f_k P_k(n)`` (irradiance / pi). cmgen reads a lat-long a quarter turn about +Y away
from relight (docs/conventions.md, SH9: its direction n is relight's ``(n_z, n_y, -n_x)``), so the two
reconstructions are compared at n and at that turn of n. The issue's tolerance is 1 %; cmgen resamples the map
into a 256^2 cube first (bilinear), which on this smooth map costs far less than that.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from relight.conventions import latlong_dirs
from relight.envmap.exr import write_exr
from relight.sh9 import polynomials, sh9

#: cmgen's direction n shows relight's CMGEN_TURN @ n (bench/export.py measured it on its cube faces).
CMGEN_TURN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
_ROW = re.compile(r"\(\s*([-0-9.e]+),\s*([-0-9.e]+),\s*([-0-9.e]+)\);\s*//\s*L")


def test_filament_convention_matches_cmgen_sh_shader(tmp_path: Path) -> None:
    cmgen = shutil.which("cmgen")
    assert cmgen is not None, "cmgen is needed (Debian libfilament-tools, in the Makefile's SYSTEM_PKGS)"
    d = latlong_dirs(256, 512)
    a = np.array([0.3, 0.5, -0.81]) / np.linalg.norm([0.3, 0.5, -0.81])
    # a smooth sky with a broad warm lobe: every axis and band carries signal
    px = (1.0 + 0.5 * d[..., :1] + 0.3 * d[..., 1:2] - 0.4 * d[..., 2:3] + 0.8 * d[..., :1] * d[..., 2:3]
          + 3.0 * np.exp(8.0 * (d @ a - 1.0))[..., None]) * np.array([1.0, 0.8, 0.6])
    src = tmp_path / "sky.exr"
    write_exr(src, px.astype(np.float32), compression="zip")
    proc = subprocess.run([cmgen, "--sh=3", "--sh-irradiance", "--sh-shader", "--sh-window=no", "--size=256",
                           str(src)], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    f_cm = np.array([[float(v) for v in m.groups()] for m in _ROW.finditer(proc.stdout)])
    assert f_cm.shape == (9, 3), proc.stdout[-2000:]
    f_rel = np.asarray(sh9(px, "filament")["coefficients"])
    rng = np.random.default_rng(42)
    n = rng.normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e_cm = polynomials(n) @ f_cm
    e_rel = polynomials(n @ CMGEN_TURN.T) @ f_rel
    rel = np.sqrt(np.mean((e_cm - e_rel) ** 2) / np.mean(e_rel**2))
    assert rel < 0.01, rel
    # and the turn matters: without it the two disagree far beyond the tolerance
    e_plain = polynomials(n) @ f_rel
    assert np.sqrt(np.mean((e_cm - e_plain) ** 2) / np.mean(e_rel**2)) > 0.05
