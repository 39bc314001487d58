"""End-to-end CLI: ``relight prefilter`` (non-radial) -> ``reflect`` -> ``render``; ``reference --view``; errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from relight import shrm
from relight.brdf.spec import parse_brdf
from relight.cli import main
from relight.envmap import read_envmap, read_image, resample_latlong, write_exr
from relight.reference_view import reference_view
from relight.shrm_io import read_shrm, sidecar_path

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"


@pytest.fixture(scope="module")
def small_env(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("env") / "court32.exr"
    write_exr(path, resample_latlong(read_envmap(DATA / "courtyard.exr").pixels, 32))
    return path


def test_prefilter_reflect_render_end_to_end(small_env: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m.exr"
    rep = tmp_path / "r.json"
    code = main(["prefilter", str(small_env), "--brdf", "microfacet:sigma=0.3", "--order", "8,2", "--size", "16",
                 "--out", str(out), "--report", str(rep)])
    assert code == 0
    line = capsys.readouterr().out.strip()
    assert line.count("\n") == 0 and "SHRM 16x32" in line and "F=8 P=2" in line
    assert out.exists() and sidecar_path(out).exists() and rep.exists()
    sm = read_shrm(out)
    assert sm.components[0].maps.shape == (9, 16, 32, 3)
    # issue 18: the --report JSON carries the predicted error per view band, as the typed report read back does
    by_view = json.loads(rep.read_text())["predicted"]["by_view"]
    assert [b["ndotv"] for b in by_view] == [[0.0, 0.3], [0.3, 0.7], [0.7, 1.0]]
    assert by_view[0]["rms"] > by_view[2]["rms"] > 0.0 and all(b["rms_appendix_b"] > 0.0 for b in by_view)
    assert [b.rms for b in sm.report.predicted.by_view] == [b["rms"] for b in by_view]  # type: ignore[attr-defined]

    mp = tmp_path / "map.exr"
    assert main(["reflect", str(out), "--view", "0,0.5,1", "--out", str(mp)]) == 0
    pixels, _ = read_image(mp)
    np.testing.assert_allclose(pixels, shrm.reflect(sm, np.array([0, 0.5, 1.0])).astype(np.float32), rtol=1e-6,
                               atol=1e-6)
    assert main(["reflect", str(out), "--view", "0,0.5,1", "--size", "8", "--out", str(tmp_path / "m8.exr")]) == 0
    assert read_image(tmp_path / "m8.exr")[0].shape == (8, 16, 3)

    sph, png = tmp_path / "s.exr", tmp_path / "s.png"
    assert main(["render", str(out), "--view", "0,0,1", "--size", "20", "--out", str(sph), "--png", str(png)]) == 0
    img, _ = read_image(sph)
    assert img.shape == (20, 20, 3) and png.exists() and img[0, 0].sum() == 0.0 and img[10, 10].sum() > 0
    assert main(["render", str(out), "--view", "0,0,1", "--size", "20", "--out", str(tmp_path / "l.exr"),
                 "--local"]) == 0
    loc, _ = read_image(tmp_path / "l.exr")
    assert np.abs(loc - img).max() < 0.05 * img.max()


def test_prefilter_names_the_bands_it_cannot_meet(small_env: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 18: Torrance-Sparrow alpha = 0.2 at epsilon = 0.01 cannot meet it at N.V in [0.1, 0.2] within P <= 16
    (relight.shrm.order_search): the CLI says so with what the band reaches (the report's achievable_by_view), and
    the --report JSON's by_view marks the band unmet with that figure; it answers in seconds, not minutes."""
    out, rep = tmp_path / "ts.exr", tmp_path / "ts.json"
    assert main(["prefilter", str(small_env), "--brdf", "torrance-sparrow:alpha=0.2", "--epsilon", "0.01",
                 "--size", "16", "--out", str(out), "--report", str(rep)]) == 0
    text = capsys.readouterr().out
    report = json.loads(rep.read_text())
    orders = report["components"][0]["report"]["orders"]
    assert orders["tolerance_met"] is False and [0.1, 0.2] in orders["unmet_bands"]
    reach = {tuple(a["ndotv"]): a["epsilon_brdf"] for a in orders["achievable_by_view"]}
    assert reach[(0.1, 0.2)] > 0.01
    assert f"tolerance 0.01 not met for N.V in [0.1, 0.2] (reaches {reach[(0.1, 0.2)]:.2g})" in text, text
    rim = report["predicted"]["by_view"][0]
    assert rim["enforced"] and rim["met"] is False and rim["achievable_epsilon_brdf"] >= reach[(0.1, 0.2)]


def test_prefilter_with_epsilon_and_sum_of_lobes(small_env: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "e.exr"
    assert main(["prefilter", str(small_env), "--brdf", "lambert+microfacet:sigma=0.4", "--epsilon", "0.05",
                 "--out", str(out)]) == 0
    assert "N:radial" in capsys.readouterr().out
    sm = read_shrm(out)
    assert [c.center for c in sm.components] == ["N", "R"]


def test_reference_view_command(small_env: Path, tmp_path: Path) -> None:
    out = tmp_path / "ref.exr"
    assert main(["reference", str(small_env), "--brdf", "microfacet:sigma=0.4", "--size", "8", "--view", "0,1,1",
                 "--out", str(out)]) == 0
    got, _ = read_image(out)
    env = read_envmap(small_env).pixels
    want = reference_view(env, parse_brdf("microfacet:sigma=0.4"), np.array([0.0, 1.0, 1.0]), 8)
    np.testing.assert_allclose(got, want.astype(np.float32), rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["reflect", "{shrm}", "--view", "1,2", "--out", "{tmp}/x.exr"], "three numbers"),
        (["reflect", "{shrm}", "--view", "0,0,0", "--out", "{tmp}/x.exr"], "zero"),
        (["reflect", "{tmp}/missing.exr", "--view", "0,0,1", "--out", "{tmp}/x.exr"], ""),
        (["reflect", "{env}", "--view", "0,0,1", "--out", "{tmp}/x.exr"], "manifest"),
        (["render", "{shrm}", "--view", "0,0,1", "--size", "0", "--out", "{tmp}/x.exr"], "size"),
        (["reference", "{env}", "--brdf", "microfacet:sigma=0.3", "--size", "4", "--view", "a,b,c",
          "--out", "{tmp}/x.exr"], "three numbers"),
    ],
)
def test_errors_exit_2_with_one_line(argv: list[str], message: str, small_env: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    shrm_path = tmp_path / "ok.exr"
    assert main(["prefilter", str(small_env), "--brdf", "microfacet:sigma=0.4", "--order", "4,1", "--size", "8",
                 "--out", str(shrm_path)]) == 0
    capsys.readouterr()
    args = [a.format(shrm=shrm_path, tmp=tmp_path, env=small_env) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("relight: error:") and "\n" not in err and message in err
