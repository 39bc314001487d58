"""``relight sh-table``: the .npz contract (coefficients R x R x (F+1)^2 x C, views, valid), the .exr form, errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from relight.brdf.spec import parse_frame_brdf
from relight.cli import main
from relight.envmap.exr import read_exr_layers
from relight.sh_table import project_views


def test_npz_contract(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = "torrance-sparrow:alpha_u=0.2,alpha_v=0.5,distribution=ggx,fresnel=none"
    out = tmp_path / "t.npz"
    assert main(["sh-table", spec, "--order", "2", "--resolution", "8", "--out", str(out)]) == 0
    line = json.loads(capsys.readouterr().out)
    assert line["order"] == 2 and line["coefficients"] == 9 and line["layout"] == "parabolic"
    z = np.load(out)
    assert z["coefficients"].shape == (8, 8, 9, 1) and z["coefficients"].dtype == np.float32
    assert z["views"].shape == (8, 8, 3) and z["valid"].shape == (8, 8) and z["valid"].dtype == bool
    # any tool can use it without knowing the map: each texel is the projection at its own view
    v = z["views"].reshape(-1, 3)
    direct = project_views(parse_frame_brdf(spec), v, 2).reshape(8, 8, 9, 1)
    assert np.allclose(z["coefficients"], direct, rtol=1e-6, atol=1e-7)
    assert json.loads(str(z["manifest"]))["brdf"]["alpha_u"] == 0.2


def test_exr_layers(tmp_path: Path) -> None:
    out = tmp_path / "t.exr"
    assert main(["sh-table", "ashikhmin-shirley:nu=12,nv=4", "--order", "1", "--resolution", "4",
                 "--layout", "hemi-octahedral", "--out", str(out)]) == 0
    layers, attrs = read_exr_layers(out)
    assert {"c0", "c1", "c2", "c3", "views", "valid"} <= set(layers)
    assert layers["c0"].shape == (4, 4, 3)
    man = json.loads(attrs["relight.shtable"])
    assert man["layout"] == "hemi-octahedral" and man["float16_clamped"] == 0


@pytest.mark.parametrize(("argv", "message"), [
    (["sh-table", "ashikhmin-shirley:nu=0,nv=4", "--out", "x.npz"], "nu"),
    (["sh-table", "lambert", "--order", "15", "--out", "x.npz"], "order"),
    (["sh-table", "lambert", "--resolution", "1", "--out", "x.npz"], "resolution"),
    (["sh-table", "lambert", "--resolution", "4", "--out", "x.png"], ".npz or .exr"),
])
def test_errors_exit_2_with_one_line(argv: list[str], message: str, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    argv = [a if not a.startswith("x.") else str(tmp_path / a) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("relight: error:") and "\n" not in err and message in err


def test_registration_defaults_are_the_tables() -> None:
    from relight import cli_shtable, sh_table

    assert (cli_shtable.DEFAULT_ORDER, cli_shtable.DEFAULT_RESOLUTION, cli_shtable.DEFAULT_LAYOUT) == (
        sh_table.DEFAULT_ORDER, sh_table.DEFAULT_RESOLUTION, sh_table.DEFAULT_LAYOUT)


def test_read_table_round_trips_both_formats(tmp_path: Path) -> None:
    from relight.sh_table import build_table, read_table, write_table

    table = build_table(parse_frame_brdf("ashikhmin-shirley:nu=12,nv=4"), order=2, resolution=6)
    for name, tol in (("t.npz", 1e-6), ("t.exr", 2.0**-11)):  # float32, float16 (unit roundoff 2^-11)
        write_table(tmp_path / name, table)
        back = read_table(tmp_path / name)
        assert back.order == 2 and back.layout == "parabolic" and back.coefficients.shape == (6, 6, 9, 1)
        assert np.allclose(back.coefficients, table.coefficients, rtol=tol, atol=1e-7)
        assert np.array_equal(back.valid, table.valid)


def test_render_table_sphere_is_sh_render(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The command's image is relight.sh_render.render_sphere of the same table and lighting (cap lights, Hann
    window with its stated cost), tangents from a brushing direction."""
    from relight.sh_render import cap_light, render_sphere, window_lighting
    from relight.sh_table import read_table

    table_path = tmp_path / "t.npz"
    assert main(["sh-table", "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0", "--resolution", "16",
                 "--out", str(table_path)]) == 0
    out = tmp_path / "s.exr"
    argv = ["render", "--table", str(table_path), "--cap", "0.3,0.8,0.5,0.6,4,3,2", "--cap=-1,0.2,0.1,1.2,1,1,1",
            "--window", "hann", "--tangent", "project:1,0.2,0.3", "--view", "0.2,0.3,1", "--size", "20",
            "--supersample", "1", "--out", str(out)]
    capsys.readouterr()
    assert main(argv) == 0
    line = json.loads(capsys.readouterr().out)
    light = cap_light([0.3, 0.8, 0.5], 0.6, [4, 3, 2], 4) + cap_light([-1, 0.2, 0.1], 1.2, [1, 1, 1], 4)
    light, cost = window_lighting(light, "hann")
    assert line["window"]["lighting_l2_change"] == pytest.approx(cost) and 0.0 < cost < 1.0
    view = np.array([0.2, 0.3, 1.0]) / np.linalg.norm([0.2, 0.3, 1.0])
    want = render_sphere(read_table(table_path), light, view, 20, tangent={"kind": "project",
                         "direction": [1.0, 0.2, 0.3]}, exact_azimuth=False)
    got = read_exr_layers(out)[0][""]
    assert np.abs(want).max() > 0.01
    assert np.allclose(got, want, rtol=1e-6, atol=1e-7)


def test_render_table_mesh_with_shadow_transfer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The bunny with PRT shadows from 'relight visibility --kind shadow_matrix' under light from every side (a
    constant environment): the exact shadowed integral can only remove light, so the image must be darker on
    average (measured 3 % at order 4: most visible points are unoccluded above their horizon, and the order-4
    product only approximates the rest) and differ where the bunny occludes itself; a transfer computed for
    another mesh is refused naming both. (The transfer's correctness itself: tests/relight/test_sh_prt.py.)"""

    table_path, vis = tmp_path / "t.npz", tmp_path / "v.npz"
    assert main(["sh-table", "ashikhmin-shirley:nu=12,nv=4,rs=0.05,rd=0.3", "--resolution", "16",
                 "--out", str(table_path)]) == 0
    assert main(["visibility", "bunny", "--kind", "shadow_matrix", "--order", "4", "--rays", "256",
                 "--out", str(vis)]) == 0
    base = ["render", "--table", str(table_path), "--cap", "0,1,0,12.566370614359172,1,1,1", "--mesh", "bunny",
            "--view", "0,0.3,1", "--size", "24", "--supersample", "1"]
    assert main([*base, "--out", str(tmp_path / "u.exr")]) == 0
    assert main([*base, "--transfer", str(vis), "--out", str(tmp_path / "s.exr")]) == 0
    unshadowed, shadowed = (read_exr_layers(tmp_path / f)[0][""] for f in ("u.exr", "s.exr"))
    on = unshadowed[..., 0] > 0
    assert on.mean() > 0.2
    assert shadowed[on].mean() < 0.99 * unshadowed[on].mean()
    assert np.abs(shadowed - unshadowed).max() > 0.1 * unshadowed.max()
    capsys.readouterr()
    other = ["teapot" if a == "bunny" else a for a in base]
    assert main([*other, "--transfer", str(vis), "--out", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err
    assert "another mesh" in err and "teapot" in err


def test_render_table_mesh_with_interreflections(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--bounces 1``: the teapot's vertices shaded with the interreflected transfer of the table's BRDF equal
    the core's ``vertex_transfer`` + ``shade_prt`` interpolated the same way (float32 EXR: 1e-6 relative); under
    a constant white environment the bounce adds the light the teapot reflects onto itself (measured 1.7 % on
    average; asserted > 1 %); --bounces with --transfer, or without --mesh, is refused."""
    from relight.mesh import sample_mesh
    from relight.mesh_render import interpolate, surface_samples
    from relight.sh_prt import folded_transfer, shade_prt
    from relight.sh_prt_bounce import BounceSettings, vertex_transfer
    from relight.sh_render import cap_light, frames_for
    from relight.sh_table import read_table

    table_path = tmp_path / "t.npz"
    assert main(["sh-table", "ashikhmin-shirley:nu=12,nv=4,rs=0.5,rd=0.3", "--resolution", "16",
                 "--out", str(table_path)]) == 0
    base = ["render", "--table", str(table_path), "--cap", "0,1,0,12.566370614359172,1,1,1", "--mesh", "teapot",
            "--view", "0,0.3,1", "--size", "24", "--supersample", "1"]
    assert main([*base, "--bounces", "1", "--rays", "128", "--out", str(tmp_path / "b.exr")]) == 0
    assert main([*base, "--bounces", "0", "--rays", "128", "--out", str(tmp_path / "d.exr")]) == 0
    got, direct = (read_exr_layers(tmp_path / f)[0][""] for f in ("b.exr", "d.exr"))

    table, mesh = read_table(table_path), sample_mesh("teapot")
    view = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    frames = frames_for(mesh.normals, {"kind": "azimuthal"})
    light = cap_light([0.0, 1.0, 0.0], 4.0 * np.pi, [1.0, 1.0, 1.0], table.order)
    total = vertex_transfer(table, mesh, frames, BounceSettings(rays=128, bounces=1)).total()
    vertex = shade_prt(table, light, frames, view, folded_transfer(frames, total, table.order), exact_azimuth=False)
    norm = mesh.normalised()
    samples = surface_samples(norm, view, 24, 1)
    want = samples.image(interpolate(samples, norm, vertex))
    assert np.abs(want).max() > 0.01
    assert np.allclose(got, want, rtol=1e-6, atol=1e-7)
    on = direct[..., 0] > 0
    assert got[on].mean() > 1.01 * direct[on].mean()
    capsys.readouterr()
    assert main([*base, "--bounces", "1", "--transfer", str(table_path), "--out", str(tmp_path / "x.exr")]) == 2
    assert "--bounces" in capsys.readouterr().err
    sphere = [a for a in base if a not in ("--mesh", "teapot")]
    assert main([*sphere, "--bounces", "1", "--out", str(tmp_path / "y.exr")]) == 2
    assert "need --mesh" in capsys.readouterr().err
