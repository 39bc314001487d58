"""The deployment, checked without a Docker engine (issue 12, item 11).

* The compose file validates against the Compose specification's JSON schema (the copy ``check-jsonschema``
  ships), and the check rejects a broken file; every ``relight`` command in it parses with relight's own CLI and
  every ``RELIGHT_*`` variable is a setting the server reads.
* The Dockerfile installs the package from a wheel (not editable) with the viewer (``web/``, whose three.js the
  wheel carries) and the EGL libraries the render routes need (the Makefile's list for the tests).
* The same wheel, installed in a fresh virtual environment outside the checkout (the ``installed`` fixture of
  :mod:`tests.service.test_wheel_install`), runs as the compose file runs it: a Dask scheduler, two
  ``relight worker`` processes and ``relight serve`` as separate processes against PostgreSQL; upload -> job ->
  viewer page -> render, the result bit-identical to the library's. The Dask nodes speak TLS with a
  certificate from ``relight tls init``, as in the compose file.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import yaml

from .postgres import start_postgres
from .support import REPO, URL_LINE, exr_bytes, library_map, make_envmap, read_exr, wait_until
from .test_scale_out import free_port
from .test_wheel_install import _env, installed  # noqa: F401 - the fixture: a fresh venv with the wheel

pytestmark = pytest.mark.timeout(600)
COMPOSE = REPO / "docker" / "compose.yaml"
DOCKERFILE = REPO / "docker" / "Dockerfile"


def check_jsonschema(path: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).with_name("check-jsonschema")
    return subprocess.run([str(exe), "--builtin-schema", "vendor.compose-spec", str(path)], capture_output=True,
                          text=True, timeout=120)


def test_compose_file_follows_the_compose_spec(tmp_path: Path) -> None:
    ok = check_jsonschema(COMPOSE)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    doc = yaml.safe_load(COMPOSE.read_text())
    doc["services"]["server"]["ports"] = "8000:8000"  # a string where the spec wants a list
    doc["services"]["worker"]["deploy"]["replicas"] = "two"
    broken = tmp_path / "compose.yaml"
    broken.write_text(yaml.safe_dump(doc))
    assert check_jsonschema(broken).returncode != 0  # the check can fail


def test_compose_commands_and_settings_are_relights() -> None:
    """Every relight command of the compose file parses with relight's own parser; every RELIGHT_* variable is a
    field of the server's settings; the workers and the server share the blob store at the same path (tasks
    receive the store root as a path)."""
    from relight.cli import build_parser
    from relight.server.config import Settings

    doc = yaml.safe_load(COMPOSE.read_text())
    services: dict[str, Any] = doc["services"]
    parser = build_parser()
    commands = 0
    for name, svc in services.items():
        cmd = svc.get("command")
        if cmd and cmd[:3] == ["python", "-m", "relight.cli"]:
            parser.parse_args(cmd[3:])  # SystemExit (a failure) on an unknown command or option
            commands += 1
        for key in svc.get("environment") or {}:
            if key.startswith("RELIGHT_"):
                assert key.removeprefix("RELIGHT_").lower() in Settings.model_fields, f"{name}: {key}"
    assert commands == 4  # the certificate, the scheduler, the workers and the server
    # The Dask cluster speaks only TLS (issue 12, item 7): the scheduler, the workers and the server's client take
    # the certificate written by the one-shot certs service, and every address is tls://.
    assert services["certs"]["command"][3:5] == ["tls", "init"]
    certs_dir = services["certs"]["command"][5]
    for name in ("scheduler", "worker", "server"):
        env = services[name]["environment"]
        assert {"RELIGHT_TLS_CA_FILE", "RELIGHT_TLS_CERT", "RELIGHT_TLS_KEY"} <= set(env), name
        assert all(env[k].startswith(certs_dir + "/") for k in env if k.startswith("RELIGHT_TLS_")), name
        assert f"certs:{certs_dir}:ro" in services[name]["volumes"], name
        assert services[name]["depends_on"].get("certs", {}).get("condition") == "service_completed_successfully" \
            or "scheduler" in services[name]["depends_on"], name  # the scheduler waits for certs, the rest for it
    assert services["scheduler"]["command"][3] == "scheduler"
    assert services["worker"]["command"][services["worker"]["command"].index("--scheduler") + 1].startswith("tls://")
    assert services["server"]["environment"]["RELIGHT_SCHEDULER"].startswith("tls://")
    mounts = {name: {v.split(":")[1] for v in svc.get("volumes", []) if v.startswith("blobs:")}
              for name, svc in services.items() if name in ("server", "worker")}
    assert mounts["server"] == mounts["worker"] == {"/data/blobs"}
    assert services["server"]["environment"]["RELIGHT_BLOB_DIR"] == "/data/blobs"


def test_dockerfile_installs_a_wheel_with_the_viewer_and_egl() -> None:
    text = DOCKERFILE.read_text()
    runs = " ".join(re.findall(r"^RUN (.+?)(?<!\\)$", text, re.M | re.S))
    assert re.search(r'pip install "/src\[service', runs) and " -e " not in runs  # non-editable install
    for folder in ("relight", "server", "worker", "client", "contract", "web", "data"):
        assert re.search(rf"^COPY {folder} /src/{folder}$", text, re.M), folder
    egl = {p for p in re.search(r"^SYSTEM_PKGS := (.+)$", (REPO / "Makefile").read_text(), re.M).group(1).split()
           if "egl" in p or "mesa" in p}
    assert egl and egl <= set(shlex.split(runs)), f"the image lacks {egl - set(shlex.split(runs))}"
    assert "node_modules/three/build/three.module.js" in (REPO / "pyproject.toml").read_text()  # in the wheel


# ------------------------------------------------------------------------------------------------ scale-out
@dataclass
class Started:
    proc: subprocess.Popen[bytes]
    log: Path

    def text(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait(timeout=30)


def launch(args: list[str], home: Path, env: dict[str, str], log: str) -> Started:
    path = home / log
    with open(path, "ab") as fh:  # the child keeps its own descriptor
        proc = subprocess.Popen(args, cwd=home, env=env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
    return Started(proc, path)


@pytest.fixture(scope="module")
def deployment(installed: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:  # noqa: F811
    home = tmp_path_factory.mktemp("deployment")
    assert REPO not in home.parents
    env = _env(home)
    pg = start_postgres()
    port = free_port()
    started: list[Started] = []
    try:
        relight = str(installed / "bin" / "relight")
        # as the compose file does it: the certs service, then every Dask node on TLS with the files from the env
        out = subprocess.run([relight, "tls", "init", str(home / "certs")], cwd=home, env=env, capture_output=True,
                             text=True, timeout=120, check=True).stdout
        env = {**env, **dict(ln.split("=", 1) for ln in out.splitlines() if ln.startswith("RELIGHT_TLS_"))}
        sched = launch([relight, "scheduler", "--host", "127.0.0.1", "--port", str(port)], home, env,
                       "scheduler.log")
        started.append(sched)
        wait_until(lambda: "relight: scheduler at tls://" in sched.text(), 90, "the scheduler to start")
        for i in range(2):
            started.append(launch([relight, "worker", "--scheduler", f"tls://127.0.0.1:{port}", "--name", f"w{i}",
                                   "--host", "127.0.0.1", "--memory-limit", "2GiB"], home, env, f"worker{i}.log"))
        server_env = {**env, "RELIGHT_SCHEDULER": f"tls://127.0.0.1:{port}", "RELIGHT_DATABASE_URL": pg.url,
                      "RELIGHT_BLOB_DIR": str(home / "blobs")}
        server = launch([relight, "serve", "--host", "127.0.0.1", "--port", "0", "--data", str(home / "data"),
                         "--no-preload"], home, server_env, "server.log")
        started.append(server)

        def url() -> str | None:
            assert server.proc.poll() is None, server.text()[-4000:]
            m = URL_LINE.search(server.text())
            return m.group(1) if m else None

        base = wait_until(url, 120, "the installed server to print its URL", interval=0.1)
        with httpx.Client(base_url=base, timeout=60) as http:
            wait_until(lambda: http.get("/health").json()["workers"] == 2, 120, "both workers to join", interval=0.2)
        yield base
        assert pg.count("SELECT count(*) FROM jobs WHERE state = 'succeeded'") >= 1  # the job went to PostgreSQL
    finally:
        for s in reversed(started):
            s.stop()
        pg.stop()


def test_scale_out_from_the_wheel_on_postgres(deployment: str, tmp_path: Path) -> None:
    exr = exr_bytes(make_envmap(32, seed=600), tmp_path)
    with httpx.Client(base_url=deployment, timeout=120) as http:
        health = http.get("/health").json()
        assert health["scheduler"] == "external" and health["workers"] == 2
        up = http.post("/envmaps", content=exr)
        assert up.status_code == 201, up.text
        job = http.post("/shrms", json={"envmap": up.json()["id"], "brdf": "phong:s=32", "epsilon": 0.02})
        assert job.status_code == 202, job.text
        job_id = job.json()["id"]
        done = wait_until(lambda: (j := http.get(f"/jobs/{job_id}").json())["state"] in ("succeeded", "failed")
                          and j, 300, "the job", interval=0.2)
        assert done["state"] == "succeeded", done
        assert done["worker"].startswith("tls://127.0.0.1:")
        got = read_exr(http.get(f"/shrms/{job_id}/coefficients.exr").content)[""]
        want = library_map(exr, "phong:s=32", epsilon=0.02)
        assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
        page = http.get("/")
        assert page.status_code == 200 and '<script type="importmap">' in page.text
        assert http.get("/vendor/three/build/three.module.js").status_code == 200
        png = http.get(f"/shrms/{job_id}/render.png", params={"view": "0,0.3,1", "size": 32, "object": "bunny"})
        assert png.status_code == 200 and png.headers["content-type"] == "image/png", png.text[:300]
