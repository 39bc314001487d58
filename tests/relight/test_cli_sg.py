"""``relight fit`` and ``relight chain`` (relight.cli_sg): the JSON contract, files and errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from relight.cli import main
from relight.envmap import read_envmap, resample_latlong, write_exr

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"


def test_fit_writes_the_contract(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fit.json"
    code = main(["fit", "torrance-sparrow:alpha=0.2,fresnel=none", "--lobes", "2", "--elevations", "3",
                 "--theta-max", "40", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "theta_o" in text and "error %" in text
    data = json.loads(out.read_text())
    assert data["kind"] == "gaussian-lobes"
    el = data["elevations"]
    # 3 fitted elevations, 20 degrees apart, and those the bisection inserted where interpolation failed
    assert len(el) == 3 + data["fit"]["elevations_inserted"] and data["fit"]["elevations_fitted"] == 3
    assert el[0]["theta_o"] == 0.0 and el[-1]["theta_o"] == pytest.approx(math.radians(40))
    for e in el:
        assert 0.0 <= e["error"] < 0.05 and len(e["lobes"]) == 2
        for lobe in e["lobes"]:
            assert set(lobe) == {"mu", "sigma", "weight"} and len(lobe["weight"]) == 3
    # the file is itself a material: it fits back to itself
    assert main(["fit", str(out), "--lobes", "2", "--elevations", "3", "--theta-max", "40",
                 "--out", str(tmp_path / "again.json")]) == 0
    again = json.loads((tmp_path / "again.json").read_text())
    assert max(e["error"] for e in again["elevations"]) < 1e-3
    # --max-inserted 0: exactly the N elevations asked for
    assert main(["fit", "torrance-sparrow:alpha=0.2,fresnel=none", "--lobes", "2", "--elevations", "3",
                 "--theta-max", "40", "--max-inserted", "0", "--out", str(tmp_path / "n.json")]) == 0
    assert len(json.loads((tmp_path / "n.json").read_text())["elevations"]) == 3


def test_chain_writes_levels(tmp_path: Path) -> None:
    env = tmp_path / "env.exr"
    write_exr(env, np.asarray(resample_latlong(read_envmap(DATA / "courtyard.exr").pixels, 32), dtype=np.float32))
    assert main(["chain", str(env), "--levels", "3", "--ratio", "sqrt2", "--out", str(tmp_path / "c")]) == 0
    man = json.loads((tmp_path / "c" / "chain.json").read_text())
    assert len(man["levels"]) == 3 and man["dtype"] == "float16"
    assert man["levels"][1]["sigma"] == pytest.approx(man["levels"][0]["sigma"] * math.sqrt(2))
    assert all((tmp_path / "c" / e["file"]).is_file() for e in man["levels"])


def test_chain_epsilon_sets_every_levels_order(tmp_path: Path) -> None:
    """``relight chain ENVMAP --epsilon E``: the same levels (sigma0 to 90 degrees), each level's order from E (a
    tighter tolerance never lowers an order and raises some); ``--levels`` and ``--epsilon`` together are a usage
    error (the issue's ``[--levels L | --epsilon E]``)."""
    env = tmp_path / "env.exr"
    write_exr(env, np.asarray(resample_latlong(read_envmap(DATA / "courtyard.exr").pixels, 32), dtype=np.float32))
    for eps, name in ((1e-2, "loose"), (1e-5, "tight")):
        assert main(["chain", str(env), "--epsilon", str(eps), "--out", str(tmp_path / name)]) == 0
    loose, tight = (json.loads((tmp_path / n / "chain.json").read_text())["levels"] for n in ("loose", "tight"))
    assert [e["sigma"] for e in loose] == [e["sigma"] for e in tight] and len(loose) >= 3
    assert loose[-1]["sigma"] >= math.pi / 4  # the last level reaches the widest lobes (doubling up to 90 degrees)
    f_loose = [e["orders"]["F_B"] for e in loose]
    f_tight = [e["orders"]["F_B"] for e in tight]
    assert all(b >= a for a, b in zip(f_loose, f_tight, strict=True)) and f_tight != f_loose, (f_loose, f_tight)
    with pytest.raises(SystemExit) as ex:
        main(["chain", str(env), "--levels", "3", "--epsilon", "1e-3", "--out", str(tmp_path / "both")])
    assert ex.value.code == 2 and not (tmp_path / "both").exists()


def test_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fit", "phong:s=10", "--lobes", "0", "--out", str(tmp_path / "x.json")]) == 2
    assert "lobes" in capsys.readouterr().err
    assert main(["fit", "kajiya-kay:s=8", "--out", str(tmp_path / "x.json")]) == 2
    assert "isotropic" in capsys.readouterr().err


def test_render_with_fit_and_chain(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from relight.brdf.spec import parse_brdf
    from relight.envmap import read_image
    from relight.gaussian_chain import read_chain
    from relight.sg_render import render_sphere_gaussian

    env = tmp_path / "env.exr"
    write_exr(env, np.asarray(resample_latlong(read_envmap(DATA / "courtyard.exr").pixels, 32), dtype=np.float32))
    fit, chain = tmp_path / "fit.json", tmp_path / "chain"
    assert main(["fit", "torrance-sparrow:alpha=0.3,fresnel=none", "--elevations", "4", "--out", str(fit)]) == 0
    assert main(["chain", str(env), "--levels", "6", "--ratio", "sqrt2", "--out", str(chain)]) == 0
    view = ["--view", "0,0.3,1", "--size", "24"]
    out = tmp_path / "sphere.exr"
    assert main(["render", "--fit", str(fit), "--chain", str(chain), *view, "--supersample", "1",
                 "--out", str(out)]) == 0
    # the file is the CPU renderer's image of the same material and chain (stored as float32 EXR)
    want = render_sphere_gaussian(parse_brdf(str(fit)), read_chain(chain), np.array([0, 0.3, 1]), 24)  # type: ignore[arg-type]
    np.testing.assert_allclose(read_image(out)[0], want, rtol=1e-6, atol=1e-6)
    capsys.readouterr()
    mesh_out = tmp_path / "bunny.exr"
    assert main(["render", "--fit", str(fit), "--chain", str(chain), *view, "--mesh", "bunny", "--visibility",
                 "sh", "--rays", "64", "--out", str(mesh_out)]) == 0
    text = capsys.readouterr().out
    assert "mesh bunny" in text and "visibility before clamping" in text
    img = read_image(mesh_out)[0]
    assert img.shape == (24, 24, 3) and np.all(np.isfinite(img)) and img.max() > 0.0
    # errors: no SHRM and no fit; visibility on the sphere; a non-Gaussian material as --fit
    assert main(["render", *view, "--out", str(out)]) == 2
    assert "SHRM" in capsys.readouterr().err
    assert main(["render", "--fit", str(fit), "--chain", str(chain), *view, "--visibility", "ao",
                 "--out", str(out)]) == 2
    assert "--mesh" in capsys.readouterr().err
    phong = tmp_path / "phong.json"
    phong.write_text(json.dumps({"kind": "phong", "s": 10}))
    assert main(["render", "--fit", str(phong), "--chain", str(chain), *view, "--out", str(out)]) == 2
    assert "gaussian-lobes" in capsys.readouterr().err
