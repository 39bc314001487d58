"""The mesh commands of the CLI contract: ``relight mesh info`` and ``relight visibility`` (relight/cli_mesh.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from relight.cli import main
from relight.mesh import sample_mesh


def test_mesh_info_reports_counts_bounds_and_defects(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mesh", "info", "teapot", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["vertices"] == 529 and info["faces"] == 992 and info["boundary_edges"] == 64
    assert info["bounds"]["max"] == pytest.approx([16.070313, 7.875, 10.0])
    assert main(["mesh", "info", "bunny"]) == 0
    assert "1839 vertices, 3674 triangles" in capsys.readouterr().out


@pytest.mark.parametrize("kind", ["visibility", "diffuse_transfer", "shadow_matrix"])
def test_visibility_writes_the_contract_arrays(tmp_path, kind: str) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "v.npz"
    assert main(["visibility", "teapot", "--order", "2", "--rays", "64", "--out", str(out), "--kind", kind]) == 0
    d = np.load(out)
    mesh = sample_mesh("teapot")
    v = mesh.n_vertices
    assert np.array_equal(d["positions"], mesh.positions.astype(np.float32))
    assert d["normals"].shape == (v, 3) and d["ao"].shape == (v,) and d["visibility"].shape == (v, 9)
    assert d["visibility_error"].shape == (v, 9) and d["ao_error"].shape == (v,)
    manifest = json.loads(str(d["manifest"]))
    assert manifest["kind"] == kind and manifest["order"] == 2 and manifest["rays"] == 64
    assert manifest["monte_carlo_error_rms"]["visibility_error"] > 0
    # ao is the cosine-weighted unoccluded fraction: in [0, 1] up to its Monte Carlo error
    assert np.all((d["ao"] >= -4 * d["ao_error"]) & (d["ao"] <= 1 + 4 * d["ao_error"] + 1e-6))
    if kind == "diffuse_transfer":
        assert d["transfer"].shape == (v, 9)
    if kind == "shadow_matrix":
        assert d["shadow_matrix"].shape == (v, 9, 9)


def test_visibility_errors_exit_2(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:  # type: ignore[no-untyped-def]
    assert main(["visibility", "bunny", "--order", "12", "--rays", "64", "--out", str(tmp_path / "x.npz")]) == 2
    assert "order must be" in capsys.readouterr().err
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    assert main(["mesh", "info", str(bad)]) == 2
    assert "index 7 out of range" in capsys.readouterr().err
