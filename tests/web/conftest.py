"""Browser fixtures: a real relight server with the viewer (uvicorn on a free loopback port, real Dask worker
processes; ``tests/web/serve_viewer.py``) and Debian's Chromium driven by Playwright with the flags of
``docs/facts.md`` (SwiftShader WebGL2). Screenshots go to ``test-artifacts/web/`` (gitignored).

Skips (with the reason) only when the Playwright package or ``/usr/bin/chromium`` is missing; never downloads a
browser.
"""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.service.conftest import Server

REPO = Path(__file__).resolve().parents[2]
#: Small limits, one worker process: the browser tests share two CPU cores with everything else.
SERVER_ENV = {
    "RELIGHT_MAX_UPLOAD_BYTES": str(1 << 20),
    "RELIGHT_MAX_PIXELS": str(512 * 1024),
    "RELIGHT_WORKER_MEMORY_LIMIT": "2GiB",
    "RELIGHT_N_WORKERS": "1",
    "RELIGHT_THREADS": "1",
    "RELIGHT_LOG_LEVEL": "warning",
}
ARTIFACTS = REPO / "test-artifacts" / "web"
CHROMIUM = os.environ.get("RELIGHT_CHROMIUM", "/usr/bin/chromium")
#: docs/facts.md: WebGL2 on SwiftShader, headless, no network side channels (the user-data-dir is added per run).
CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox",
    "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--disable-quic", "--force-color-profile=srgb",
]


def start_viewer_server(data_dir: Path, extra_env: dict[str, str] | None = None) -> Server:
    data_dir.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith("RELIGHT_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    env.update(SERVER_ENV)
    env.update(extra_env or {})
    args = [sys.executable, "-m", "tests.web.serve_viewer", "--data", str(data_dir), "--port", "0"]
    server = Server(args=args, env=env, log=data_dir / "server.log")
    server.start()
    try:
        return server.wait_ready()
    except BaseException:
        server.stop()
        raise


@pytest.fixture(scope="session")
def viewer_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    if not (REPO / "web" / "node_modules" / "three" / "build" / "three.module.js").is_file():
        pytest.fail("three.js is not installed: run `npm ci --prefix web`")
    # every job first waits 1 s reporting progress (TEST ONLY setting), so the page shows a running job
    srv = start_viewer_server(tmp_path_factory.mktemp("viewer-server"), {"RELIGHT_TEST_JOB_DELAY_S": "1.0"})
    yield srv
    srv.stop()


@pytest.fixture(scope="session")
def chromium(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """A persistent Chromium context (new empty user-data-dir) from Playwright."""
    from playwright import sync_api  # the dev extra; never a downloaded browser

    assert shutil.which(CHROMIUM) or Path(CHROMIUM).is_file(), f"{CHROMIUM} is missing: `make test` installs it"
    with sync_api.sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")), executable_path=CHROMIUM, args=CHROMIUM_FLAGS,
            headless=True, viewport={"width": 1200, "height": 760}, device_scale_factor=1,
        )
        yield ctx
        ctx.close()


@pytest.fixture
def page(chromium: Any, viewer_server: Server) -> Iterator[Any]:
    """The viewer page, loaded and ready; console errors and page errors fail the test."""
    pg = chromium.new_page()
    problems: list[str] = []
    pg.on("pageerror", lambda exc: problems.append(f"page error: {exc}"))
    pg.on("console", lambda msg: problems.append(f"console {msg.type}: {msg.text}")
          if msg.type == "error" and "Failed to load resource" not in msg.text else None)
    pg.goto(viewer_server.url + "/")
    pg.wait_for_function("window.relight && window.relight.ready === true", timeout=60_000)
    yield pg
    pg.close()
    assert not problems, "\n".join(problems)


def screenshot(pg: Any, name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    pg.screenshot(path=str(path))
    return path
