"""The JavaScript unit tests (``node --test web/test/``) and the freshness of their Python-made fixtures."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

from tests.web import make_js_fixtures

REPO = Path(__file__).resolve().parents[2]


def test_js_fixtures_are_current() -> None:
    for name, text in make_js_fixtures.fixtures().items():
        path = make_js_fixtures.FIXTURES / name
        assert path.exists() and path.read_text(encoding="utf-8") == text, (
            f"{path} is stale: run python3 tests/web/make_js_fixtures.py")


def test_node_unit_tests_pass() -> None:
    node = shutil.which("node")
    assert node is not None, "node is not installed (the README's prerequisites: Node.js >= 20)"
    proc = subprocess.run([node, "--test", "test/"], cwd=REPO / "web", capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
