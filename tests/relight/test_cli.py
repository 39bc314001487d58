"""The `relight` CLI contract: prefilter / reference / compare / info, and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from relight.envmap import read_image, resample_latlong, write_exr, write_hdr

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "relight.cli", *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


@pytest.fixture(scope="module")
def small_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from relight.envmap import read_envmap

    px = resample_latlong(read_envmap(DATA / "sunset.exr").pixels, 64)
    path = tmp_path_factory.mktemp("maps") / "sunset64.exr"
    write_exr(path, px)
    return path


def test_prefilter_reference_compare_round_trip(small_map: Path, tmp_path: Path) -> None:
    out, rep, ref = tmp_path / "pf.exr", tmp_path / "pf.json", tmp_path / "ref.exr"
    r = run("prefilter", str(small_map), "--brdf", "phong:s=16", "--epsilon", "1e-3", "--size", "16",
            "--out", str(out), "--report", str(rep))  # fmt: skip
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    assert report["orders"]["F_B"] >= 1 and report["output"]["height"] == 16
    assert set(report["timings"]) >= {"lighting_projection", "synthesis"}
    img, _ = read_image(out)
    assert img.shape == (16, 32, 3) and np.all(np.isfinite(img))

    r = run("reference", str(small_map), "--brdf", "phong:s=16", "--size", "16", "--out", str(ref))
    assert r.returncode == 0, r.stderr
    r = run("compare", str(out), str(ref), "--json")
    assert r.returncode == 0, r.stderr
    cmp = json.loads(r.stdout)
    # the prefilter's measured error sits within its App. B prediction (plus the float32 file rounding)
    assert cmp["relative_rms"] <= report["orders"]["rms_appendix_b"] + 1e-5
    assert cmp["relative_rms"] < 0.05


def test_prefilter_reads_hdr_and_lambert(small_map: Path, tmp_path: Path) -> None:
    img, _ = read_image(small_map)
    hdr = tmp_path / "map.hdr"
    write_hdr(hdr, img)
    out = tmp_path / "irr.exr"
    r = run("prefilter", str(hdr), "--brdf", "lambert", "--order", "2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "F_B=2" in r.stdout


def test_info_reports_size_negatives_and_spectrum() -> None:
    r = run("info", str(DATA / "city.exr"), "--json", "--lmax", "16")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert (info["width"], info["height"]) == (1024, 512)
    assert info["negatives_clamped"] > 0 and info["max"] > 1e4
    assert len(info["sh_power_spectrum"]) == 17
    assert np.all(np.diff(info["energy_captured"]) >= 0) and info["energy_captured"][-1] <= 1.0 + 1e-9


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["prefilter", "missing.exr", "--brdf", "phong:s=8", "--out", "x.exr"], "missing.exr"),
        (["prefilter", "{map}", "--brdf", "phong:s=-3", "--out", "x.exr"], "s must"),
        (["prefilter", "{map}", "--brdf", "velvet", "--out", "x.exr"], "velvet"),
        (["prefilter", "{map}", "--brdf", "phong:s=8", "--epsilon", "2", "--out", "x.exr"], "epsilon"),
        (["prefilter", "{bad}", "--brdf", "phong:s=8", "--out", "x.exr"], "width = 2 x height"),
        (["prefilter", "{nan}", "--brdf", "phong:s=8", "--out", "x.exr"], "non-finite"),
        (["prefilter", "{trunc}", "--brdf", "phong:s=8", "--out", "x.exr"], ""),
        (["compare", "{map}", "{bad}"], "differ in size"),
    ],
)
def test_errors_exit_2_with_one_clear_line(
    args: list[str], message: str, small_map: Path, tmp_path: Path
) -> None:
    bad = tmp_path / "bad.exr"
    write_exr(bad, np.ones((20, 30, 3), np.float32))
    nan = tmp_path / "nan.exr"
    px = np.ones((8, 16, 3), np.float32)
    px[3, 4, 1] = np.nan
    write_exr(nan, px)
    trunc = tmp_path / "trunc.exr"
    trunc.write_bytes(small_map.read_bytes()[:300])
    subs = {"{map}": str(small_map), "{bad}": str(bad), "{nan}": str(nan), "{trunc}": str(trunc)}
    r = run(*[subs.get(a, a) for a in args], cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("relight: error:")]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.exr").exists()  # nothing half-written
