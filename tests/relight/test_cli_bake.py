"""``relight bake`` (relight.cli_bake): outputs equal ``relight export`` / ``relight sh``, a rerun skips everything,
an interrupt leaves no partial file and a rerun completes only what is missing, one bad map fails alone."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import relight.cube_chain as cube_chain
from relight import cli
from relight.envmap.exr import write_exr
from relight.ktx2 import read_ktx2

REPO = Path(__file__).resolve().parents[2]


def _maps(tmp: Path) -> list[Path]:
    rng = np.random.default_rng(7)
    out = []
    for name in ("a", "b"):
        p = tmp / f"{name}.exr"
        write_exr(p, (0.2 + rng.random((16, 32, 3))).astype(np.float32))
        out.append(p)
    return out


def _bake(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", "bake", *args], capture_output=True, text=True,
                          timeout=600)


def test_bake_then_rerun_skips(tmp_path: Path) -> None:
    maps = _maps(tmp_path)
    out = tmp_path / "out"
    proc = _bake(*map(str, maps), "--target", "gltf", "--size", "4", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "4 done, 0 skipped, 0 failed" in proc.stdout
    assert sorted(p.name for p in out.iterdir()) == ["a.gltf.ktx2", "a.gltf.ktx2.json", "a.sh.json",
                                                     "b.gltf.ktx2", "b.gltf.ktx2.json", "b.sh.json"]
    # the same file relight export writes, byte for byte (the KTX2 carries no timings)
    ref = tmp_path / "ref.ktx2"
    subprocess.run([sys.executable, "-m", "relight.cli", "export", str(maps[0]), "--target", "gltf", "--size", "4",
                    "--out", str(ref)], check=True, capture_output=True)
    mine, theirs = read_ktx2((out / "a.gltf.ktx2").read_bytes()), read_ktx2(ref.read_bytes())
    assert len(mine.levels) == len(theirs.levels) == 3
    for a, b in zip(mine.levels, theirs.levels, strict=True):
        np.testing.assert_array_equal(a, b)
    assert (out / "a.gltf.ktx2").read_bytes() == ref.read_bytes()
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = _bake(*map(str, maps), "--target", "gltf", "--size", "4", "--out", str(out), "--json")
    assert again.returncode == 0, again.stderr
    rows = json.loads(again.stdout)["items"]
    assert [r["status"] for r in rows] == ["skipped"] * 4
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == mtimes
    # a changed parameter is a different item: redone (the pixel format too; the default keeps earlier keys)
    packed = _bake(str(maps[0]), "--target", "gltf", "--size", "4", "--format", "ktx2", "--pixel-format",
                   "b10g11r11", "--out", str(out))
    assert "1 done" in packed.stdout and read_ktx2((out / "a.gltf.ktx2").read_bytes()).vk_format == 122
    third = _bake(*map(str, maps), "--target", "gltf", "--size", "4", "--sun", "clamp=0.5", "--out", str(out))
    assert "4 done" in third.stdout


def test_interrupt_leaves_no_partial_file_and_rerun_completes(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    maps = _maps(tmp_path)
    out = tmp_path / "out"
    # relight.cli_export imports prefilter_chain inside its function: patch the module it comes from

    calls = {"n": 0}
    original = cube_chain.prefilter_chain

    def interrupted(*a: object, **k: object) -> object:
        calls["n"] += 1
        if calls["n"] == 2:  # Ctrl-C while the second map's chain is computed
            raise KeyboardInterrupt
        return original(*a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(cube_chain, "prefilter_chain", interrupted)
    with pytest.raises(KeyboardInterrupt):
        cli.main(["bake", *map(str, maps), "--target", "three", "--size", "4", "--out", str(out)])
    names = sorted(p.name for p in out.iterdir())
    assert names == ["a.sh.json", "a.three.ktx2", "a.three.ktx2.json"]  # no temporary or partial file
    monkeypatch.setattr(cube_chain, "prefilter_chain", original)
    proc = _bake(*map(str, maps), "--target", "three", "--size", "4", "--out", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    assert [r["status"] for r in json.loads(proc.stdout)["items"]] == ["skipped", "skipped", "done", "done"]
    assert read_ktx2((out / "b.three.ktx2").read_bytes()).levels


def test_one_bad_map_fails_alone(tmp_path: Path) -> None:
    maps = _maps(tmp_path)
    broken = tmp_path / "broken.exr"
    broken.write_bytes(b"not an exr at all")
    out = tmp_path / "out"
    proc = _bake(str(maps[0]), str(broken), str(maps[1]), "--target", "three", "--format", "sh", "--out", str(out))
    assert proc.returncode == 1
    lines = proc.stdout.strip().splitlines()
    assert lines[0].endswith(")") and "done" in lines[0] and "done" in lines[2]
    assert "broken.exr sh: FAILED: " in lines[1] and len(lines) == 4
    assert sorted(p.name for p in out.iterdir()) == ["a.sh.json", "b.sh.json"]
    bad = _bake(str(maps[0]), "--target", "three", "--format", "obj", "--out", str(out))
    assert bad.returncode == 2 and "--format" in bad.stderr


def test_gltf_items(tmp_path: Path) -> None:
    """gltf items: a GLB per map (relight export --format gltf's bytes, skipped on a rerun); with another target
    each fails alone, naming --target gltf."""
    maps = _maps(tmp_path)
    out = tmp_path / "out"
    wrong = _bake(*map(str, maps), "--target", "three", "--format", "gltf,sh", "--size", "4", "--out", str(out))
    assert wrong.returncode == 1
    assert wrong.stdout.count("FAILED: gltf (EXT_lights_image_based) needs --target gltf") == 2
    assert sorted(p.name for p in out.iterdir()) == ["a.sh.json", "b.sh.json"]
    ok = _bake(*map(str, maps), "--target", "gltf", "--format", "gltf", "--size", "4", "--out", str(out), "--json")
    assert ok.returncode == 0, ok.stderr
    ref = tmp_path / "ref.glb"
    subprocess.run([sys.executable, "-m", "relight.cli", "export", str(maps[0]), "--target", "gltf", "--format",
                    "gltf", "--size", "4", "--out", str(ref)], check=True, capture_output=True)
    assert (out / "a.glb").read_bytes() == ref.read_bytes()
    again = _bake(*map(str, maps), "--target", "gltf", "--format", "gltf", "--size", "4", "--out", str(out), "--json")
    assert [r["status"] for r in json.loads(again.stdout)["items"]] == ["skipped", "skipped"]


def test_one_output_set_per_map_and_material(tmp_path: Path) -> None:
    """``--brdf SPEC [--brdf SPEC...]``: a chain per map x material, named by relight.cli_bake.material_tag, each
    the bytes of ``relight export --brdf SPEC``; SH9 once per map; a rerun skips everything, a new material is
    the only work of the next run; a bad spec is an argument error (exit 2) before any item runs."""
    from relight.cli_bake import material_tag

    maps = _maps(tmp_path)
    out = tmp_path / "out"
    metal, phong = "gltf-pbr:base=0.9/0.6/0.2,metallic=1", "phong:s=32"
    args = [*map(str, maps), "--target", "three", "--size", "4", "--out", str(out), "--json"]
    first = _bake(*args, "--brdf", metal, "--brdf", phong)
    assert first.returncode == 0, first.stderr
    rows = json.loads(first.stdout)["items"]
    assert [(Path(r["map"]).name, r["format"], r.get("brdf")) for r in rows] == [
        ("a.exr", "ktx2", metal), ("a.exr", "ktx2", phong), ("a.exr", "sh", None),
        ("b.exr", "ktx2", metal), ("b.exr", "ktx2", phong), ("b.exr", "sh", None)]
    tags = [material_tag(metal), material_tag(phong)]
    assert tags[0].startswith("gltf-pbr_base=0.9_0.6_0.2_metallic=1-") and len(set(tags)) == 2
    expect = sorted([f"{m}.{t}.three.ktx2{j}" for m in "ab" for t in tags for j in ("", ".json")]
                    + ["a.sh.json", "b.sh.json"])
    assert sorted(p.name for p in out.iterdir()) == expect
    ref = tmp_path / "ref.ktx2"
    subprocess.run([sys.executable, "-m", "relight.cli", "export", str(maps[1]), "--target", "three", "--size", "4",
                    "--brdf", metal, "--out", str(ref)], check=True, capture_output=True)
    assert (out / f"b.{tags[0]}.three.ktx2").read_bytes() == ref.read_bytes()
    assert json.loads((out / f"b.{tags[0]}.three.ktx2.json").read_text())["brdf"] == metal
    assert read_ktx2(ref.read_bytes()).metadata["brdf"] == metal
    again = _bake(*args, "--brdf", metal, "--brdf", phong, "--brdf", "lambert:albedo=0.5")
    assert [r["status"] for r in json.loads(again.stdout)["items"]] == ["skipped", "skipped", "done", "skipped"] * 2
    bad = _bake(*args, "--brdf", "kajiya-kay:s=8")
    assert bad.returncode == 2 and "tangent" in bad.stderr
