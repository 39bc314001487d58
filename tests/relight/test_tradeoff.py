"""The accuracy–time explorer (``relight.tradeoff``) and ``relight tradeoff``.

Small maps (sample maps area-averaged to 32 x 64 and 16 x 32) and few settings keep these quick. The cost model's
built-in constants are used (no calibration run); its accuracy is tested in ``test_costmodel.py``.
"""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from relight import costmodel, tradeoff
from relight.brdf.models import Microfacet
from relight.brdf.radial import Phong
from relight.envmap import read_envmap, resample_latlong, write_exr
from relight.errors import InputError

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
CAL = costmodel.default_calibration()
REQUIRED = {"method", "orders", "predicted_error", "measured_error", "predicted_seconds", "measured_seconds",
            "pareto", "pareto_overall"}


@cache
def env(name: str, rows: int) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


def test_pareto_flags_by_hand() -> None:
    # (error, seconds): (b) beats (a) in both; (c) and (b) trade off; (d) ties (b) exactly: both stay
    errors = [0.5, 0.1, 0.01, 0.1]
    seconds = [2.0, 1.0, 5.0, 1.0]
    assert tradeoff.pareto_flags(errors, seconds) == [False, True, True, True]
    assert tradeoff.pareto_flags([0.1], [1.0]) == [True]


@cache
def phong_sweep() -> tradeoff.Tradeoff:
    return tradeoff.sweep(env("courtyard", 32), Phong(32.0), epsilons=(0.1, 0.01, 1e-3), truncations=(0.1, 0.01),
                          size=16, calibration=CAL)


def test_radial_sweep_points_and_errors() -> None:
    res = phong_sweep()
    assert [p.method for p in res.points] == ["frequency"] * 3 + ["angular"] * 2
    for p in res.points:
        assert REQUIRED <= set(p.to_json())
        assert p.measured_seconds > 0 and p.predicted_seconds > 0
        assert math.isfinite(p.measured_error)
    freq = [p for p in res.points if p.method == "frequency"]
    # a tighter tolerance never lowers the order and, on this map, lowers the measured error
    assert [p.orders["F_B"] for p in freq] == sorted(p.orders["F_B"] for p in freq)
    assert freq[0].measured_error > freq[-1].measured_error
    # App. B's bound is conservative (test_prefilter: plus the pixel grid's floor, below 2e-3 on this map)
    for p in freq:
        assert p.measured_error <= p.predicted_error_bound + 2e-3, p
    # the Pareto front of each method is non-empty and no front point is dominated within its method
    for method in ("frequency", "angular"):
        assert any(p.pareto for p in res.points if p.method == method)
    assert res.meta.reference.truncation == 0.0 and res.meta.view is None
    assert res.meta.time_ratio_range is not None
    lo, hi = res.meta.time_ratio_range
    assert 0 < lo <= hi


def test_angular_predicted_error_is_exact_for_a_uniform_environment() -> None:
    """For a uniform environment the angular method misses exactly the dropped fraction of the lobe's integral (its
    predicted error), up to the pixelisation of the cone (20 % on a 32-row map). The frequency method is exact
    (a constant is band-limited at l = 0): what remains is the reference's own point sampling of the lobe over the
    32 x 64 pixels, 8e-4 for s = 8."""
    res = tradeoff.sweep(np.full((32, 64, 3), 0.7), Phong(8.0), epsilons=(0.1,), truncations=(0.2, 0.05),
                         size=8, calibration=CAL)
    for p in res.points:
        if p.method == "angular":
            assert p.measured_error == pytest.approx(p.predicted_error, rel=0.2), p
        else:
            assert p.measured_error < 2e-3


def test_view_dependent_sweep() -> None:
    view = (0.3, 0.5, 0.8)
    # 32 rows: on 16 the tighter tolerance's orders reach F_B = H - 1, where the pixel quadrature of the lighting
    # no longer matches the angular reference's pixels and the measured error grows again
    res = tradeoff.sweep(env("sunset", 32), Microfacet(0.4), epsilons=(0.3, 0.1), truncations=(0.1,), size=8,
                         view=view, calibration=CAL)
    freq = [p for p in res.points if p.method == "frequency"]
    assert res.meta.representation == "shrm" and res.meta.view is not None
    assert np.allclose(res.meta.view, np.array(view) / np.linalg.norm(view))
    assert freq[1].orders["P_B"] >= freq[0].orders["P_B"] and freq[1].orders["F_B"] > freq[0].orders["F_B"]
    assert freq[1].measured_error < freq[0].measured_error
    assert "view" in freq[0].measured_stages and "angular_view" in res.points[-1].measured_stages


def test_write_tradeoff_json_and_plots(tmp_path: Path) -> None:
    paths = tradeoff.write_tradeoff(phong_sweep(), tmp_path, title="phong 32")
    points = json.loads((tmp_path / "tradeoff.json").read_text())  # strict JSON: no NaN
    assert isinstance(points, list) and all(REQUIRED <= set(p) for p in points)
    meta = json.loads((tmp_path / "tradeoff_meta.json").read_text())
    assert meta["calibration"]["calibrated"] is False
    for name in ("error_vs_time.png", "predicted_vs_measured_error.png", "predicted_vs_measured_time.png"):
        assert paths[name].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_invalid_sweeps_are_input_errors() -> None:
    px = env("courtyard", 16)
    for kwargs, fragment in [({"epsilons": (1.5,)}, "epsilon"), ({"truncations": (0.0,)}, "truncation"),
                             ({"size": 1000}, "size"), ({"epsilons": (), "truncations": ()}, "at least one")]:
        with pytest.raises(InputError, match=fragment):
            tradeoff.sweep(px, Phong(8.0), calibration=CAL, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="black"):
        tradeoff.sweep(np.zeros((16, 32, 3)), Phong(8.0), epsilons=(0.1,), truncations=(), calibration=CAL)
    bad = px.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        tradeoff.sweep(bad, Phong(8.0), calibration=CAL)


def test_cli_tradeoff(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from relight import cli

    monkeypatch.setattr(cli, "COMMAND_PROVIDERS", [*(p for p in cli.COMMAND_PROVIDERS if p != "relight.cli_plan"),
                                                   "relight.cli_plan"])
    monkeypatch.setenv("RELIGHT_CACHE_DIR", str(tmp_path / "cache"))
    costmodel.forget()
    costmodel.save_calibration(CAL, costmodel.cache_path())  # a cached calibration: the CLI does not calibrate
    src = tmp_path / "court.exr"
    write_exr(src, env("courtyard", 32))
    out = tmp_path / "out"
    code = cli.main(["tradeoff", str(src), "--brdf", "phong:s=16", "--out", str(out), "--rows", "16", "--size", "8",
                     "--epsilons", "0.1,0.01", "--truncations", "0.1"])
    assert code == 0
    line = capsys.readouterr().out
    assert "3 points" in line and "16 x 32 input" in line
    assert len(json.loads((out / "tradeoff.json").read_text())) == 3
    assert cli.main(["tradeoff", str(src), "--brdf", "phong:s=16", "--out", str(out), "--epsilons", "2"]) == 2
    assert "--epsilons" in capsys.readouterr().err
    costmodel.forget()


def test_matplotlib_is_optional_outside_the_plots() -> None:
    """matplotlib is the ``plots`` extra: with it made unimportable, the sweep, its JSON, scene and job planning and
    the service's app import and run; only ``plot`` fails, with an error naming the extra. A fresh interpreter, so
    that nothing imported earlier in this process hides an import."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent("""
        import sys

        class NoMatplotlib:
            def find_spec(self, name, path=None, target=None):
                if name == "matplotlib" or name.startswith("matplotlib."):
                    raise ImportError("matplotlib is blocked for this test")
                return None

        sys.meta_path.insert(0, NoMatplotlib())
        import json, tempfile
        import numpy as np
        from relight import costmodel, planning, tradeoff
        from relight.brdf.radial import Phong
        from relight.errors import RelightError
        import relight.server.main  # the service's app module

        cal = costmodel.default_calibration()
        px = np.random.default_rng(0).random((16, 32, 3)) + 0.1
        res = tradeoff.sweep(px, Phong(8.0), epsilons=(0.1,), truncations=(0.1,), size=8, calibration=cal,
                             mitsuba=False)
        json.dumps(res.as_dict(), allow_nan=False)
        scene = planning.scene_from_dict({"environment": "x", "epsilon": 0.1, "size": 8,
                                          "objects": [{"size": 1, "distance": 3, "material": "phong:s=8"}]})
        planning.run_plan(planning.plan_scene(scene, px, calibration=cal), write=False)
        try:
            tradeoff.write_tradeoff(res, tempfile.mkdtemp())
        except RelightError as exc:
            assert "relight[plots]" in str(exc), exc
        else:
            raise AssertionError("plot ran without matplotlib")
        assert not any(m == "matplotlib" or m.startswith("matplotlib.") for m in sys.modules)
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-3000:]
