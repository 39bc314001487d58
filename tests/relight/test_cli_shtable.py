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
