"""``relight sh`` and the SH9 / Babylon parts of ``relight export`` (relight.cli_export), as whole commands."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from relight.cli_export import SH_CONVENTIONS
from relight.cube_chain import BABYLON_LOD_SCALE
from relight.envmap import read_envmap
from relight.ktx2 import read_ktx2
from relight.sh9 import CONVENTIONS, all_conventions, sh9

REPO = Path(__file__).resolve().parents[2]
STUDIO = REPO / "data" / "envmaps" / "studio.exr"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", *args], capture_output=True, text=True, timeout=600)


def test_registered_conventions_are_the_modules() -> None:
    assert tuple(SH_CONVENTIONS) == tuple(CONVENTIONS)


def test_building_the_parser_imports_nothing_heavy() -> None:
    """Every ``relight`` process builds the whole parser (``relight export`` included): the constants its
    options repeat agree with their modules, and building it imports neither numba nor SciPy (measured: they
    were a third of ``relight export``'s start-up, bench/export.py)."""
    from relight.cli import REFERENCE_TRUNCATION
    from relight.cli_mesh import VISIBILITY_KINDS
    from relight.reference import DEFAULT_TRUNCATION
    from relight.visibility import KINDS

    assert REFERENCE_TRUNCATION == DEFAULT_TRUNCATION and tuple(VISIBILITY_KINDS) == tuple(KINDS)
    heavy = "('numba', 'scipy', 'relight.visibility', 'relight.reference')"
    code = f"import sys, relight.cli as c; c.build_parser(); print(sorted(m for m in {heavy} if m in sys.modules))"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_sh_command_prints_and_writes_the_convention(tmp_path: Path) -> None:
    px = read_envmap(STUDIO).pixels
    proc = _run("sh", str(STUDIO), "--convention", "gltf")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["convention"] == "gltf" and doc["quantity"] == "irradiance" and len(doc["coefficients"]) == 9
    np.testing.assert_allclose(doc["coefficients"], sh9(px, "gltf")["coefficients"], rtol=1e-12)
    out = tmp_path / "sh.json"
    assert _run("sh", str(STUDIO), "--convention", "filament", "--out", str(out)).returncode == 0
    assert json.loads(out.read_text())["quantity"] == "irradiance/pi"
    bad = _run("sh", str(STUDIO), "--out", str(tmp_path / "missing" / "sh.json"))
    assert bad.returncode == 2 and "does not exist" in bad.stderr


def test_babylon_export_embeds_every_sh_convention(tmp_path: Path) -> None:
    out = tmp_path / "studio.ktx2"
    proc = _run("export", str(STUDIO), "--target", "babylon", "--size", "16", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((tmp_path / "studio.ktx2.json").read_text())
    assert manifest["roughness_mapping"] == "log2"
    rough = np.array([row["roughness"] for row in manifest["levels"]])
    # Babylon reads level lod at alphaG = 2^(lod / 0.8) / size (level 0: the mirror)
    np.testing.assert_allclose(rough[1:] ** 2, np.exp2(np.arange(1, 5) / BABYLON_LOD_SCALE) / 16, rtol=1e-12)
    expect = all_conventions(read_envmap(STUDIO).pixels)
    for conv in CONVENTIONS:
        np.testing.assert_allclose(manifest["sh9"][conv]["coefficients"], expect[conv]["coefficients"], rtol=1e-12)
    assert read_ktx2(out.read_bytes()).metadata["sh9"] == manifest["sh9"]
