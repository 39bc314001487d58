"""``relight factorize`` (relight.cli_factorize): the JSON contract, the printed summary and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from relight.brdf.spec import parse_brdf
from relight.factorization import factorize


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", *args], capture_output=True, text=True, timeout=300)


def test_factorize_writes_the_json_contract(tmp_path: Path) -> None:
    out = tmp_path / "f"
    r = run("factorize", "phong:s=10", "--resolution", "24", "--out", str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "factorization.json").read_text())
    lib = factorize(parse_brdf("phong:s=10"), n_theta=24, n_values=400)
    assert doc["terms"] == {"0.9": lib.terms[0.9], "0.95": lib.terms[0.95], "0.99": lib.terms[0.99]}
    assert set(doc["predicted_terms"]) == {"0.9", "0.95", "0.99"}
    assert all(isinstance(v, int) and v > 0 for v in doc["predicted_terms"].values())
    np.testing.assert_allclose(doc["singular_values"][:40], lib.singular_values[:40], rtol=1e-12)
    assert doc["domain"] == "hemisphere" and doc["include_cosine"] is True and doc["n_theta"] == 24
    assert doc["convergence"]["resolutions"] == [[24, 24], [36, 36]] and doc["convergence"]["converged"]
    g = np.load(out / "factors_g.npy")
    assert g.shape == (8, 24, 24) and np.load(out / "factors_h.npy").shape == g.shape
    grid = np.load(out / "grid.npz")
    # factor images are orthonormal under the grid's weights (float32 files: 1e-6)
    assert np.sum(grid["weights"] * g[0].astype(np.float64) ** 2) == pytest.approx(1.0, abs=1e-5)
    for key in ("0.9", "0.95", "0.99"):
        assert f"K = {doc['terms'][key]}" in r.stdout


def test_factorize_anisotropic_spec(tmp_path: Path) -> None:
    out = tmp_path / "a"
    r = run("factorize", "ward:alpha_x=0.2,alpha_y=0.4,rho_d=0,rho_s=1", "--resolution", "8", "--no-convergence",
            "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "factorization.json").read_text())
    assert doc["method"] == "dense" and doc["predicted_terms"] is None and "anisotropic" in doc["prediction"]["note"]
    assert doc["brdf"]["kind"] == "ward" and doc["brdf"]["alpha_y"] == 0.4


def test_factorize_sphere_measured_prediction_and_dense(tmp_path: Path) -> None:
    out = tmp_path / "g"
    r = run("factorize", "microfacet:sigma=0.3", "--domain", "hemisphere", "--resolution", "12", "--method",
            "dense", "--no-convergence", "--factors", "0", "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "factorization.json").read_text())
    assert doc["method"] == "dense" and doc["convergence"] is None and "factors" not in doc
    assert doc["prediction"]["method"] == "half-angle-curve" and doc["prediction"]["l_star"]["0.99"] > 0
    sph = tmp_path / "s"
    r = run("factorize", "phong:s=5", "--domain", "sphere", "--resolution", "24", "--no-convergence",
            "--out", str(sph))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert json.loads((sph / "factorization.json").read_text())["terms"]["0.99"] == 25


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["phong:s=-1"], "s must"),
        (["nosuch:x=1"], "nosuch"),
        (["phong:s=10", "--resolution", "1"], "n_theta"),
        (["phong:s=10", "--phi", "0"], "n_phi"),
        (["phong:s=10", "--domain", "sphere", "--no-cosine"], "hemisphere"),
    ],
)
def test_factorize_errors_exit_2(tmp_path: Path, args: list[str], match: str) -> None:
    r = run("factorize", *args, "--out", str(tmp_path / "x"))
    assert r.returncode == 2
    assert match in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
