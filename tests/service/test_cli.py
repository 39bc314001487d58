"""The service subcommands of the ``relight`` CLI against the shared server."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from .support import REPO, Server, base_env, exr_bytes, make_envmap

pytestmark = pytest.mark.timeout(120)


def relight(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "relight.cli", *args], env=base_env(), cwd=REPO,
                          capture_output=True, text=True, timeout=90)


def test_upload_submit_wait_out_and_jobs(server: Server, tmp_path: Path) -> None:
    src = tmp_path / "sky.exr"
    src.write_bytes(exr_bytes(make_envmap(32, seed=31), tmp_path))
    up = relight("upload", str(src), "--server", server.url, "--json")
    assert up.returncode == 0, up.stderr
    env_id = json.loads(up.stdout)["id"]

    out = tmp_path / "out.exr"
    sub = relight("submit", str(src), "--brdf", "phong:s=16", "--epsilon", "0.02", "--server", server.url,
                  "--wait", "--out", str(out))
    assert sub.returncode == 0, sub.stderr
    job_id = sub.stdout.split()[0]
    assert "succeeded" in sub.stdout and out.exists()
    from relight.envmap import read_exr_layers

    layers, _ = read_exr_layers(out.read_bytes())
    assert layers[""].shape == (layers[""].shape[0], 2 * layers[""].shape[0], 3) and np.isfinite(layers[""]).all()

    by_id = relight("submit", env_id, "--brdf", "phong:s=16", "--epsilon", "0.02", "--server", server.url,
                    "--json")
    assert by_id.returncode == 0 and json.loads(by_id.stdout)["cached"] is True

    jobs = relight("jobs", "--server", server.url, "--json")
    assert jobs.returncode == 0 and job_id in {j["id"] for j in json.loads(jobs.stdout)}


def test_errors_are_one_line_and_exit_2(server: Server, tmp_path: Path) -> None:
    src = tmp_path / "sky.exr"
    src.write_bytes(exr_bytes(make_envmap(32, seed=32), tmp_path))
    bad = relight("submit", str(src), "--brdf", "phong:s=-1", "--server", server.url)
    assert bad.returncode == 2
    assert bad.stderr.startswith("relight: error: 422") and "s must" in bad.stderr
    down = relight("jobs", "--server", "http://127.0.0.1:9", "--timeout", "5")
    assert down.returncode == 2 and "relight: error:" in down.stderr and "ConnectError" in down.stderr
