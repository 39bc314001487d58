"""The JavaScript unit tests (``node --test web/test/``) and the freshness of their Python-made fixtures."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

from tests.web import make_js_fixtures

REPO = Path(__file__).resolve().parents[2]


#: Float fixtures are made by NumPy, ducc0 and BLAS, whose last bits move between releases and kernels (sh.json's
#: near-zero coefficients moved by 4e-17, its O(1) ones by one ulp, after a dependency update); a stale fixture
#: (the Python code changed) moves them by far more than this, so the freshness check compares numbers to it.
FIXTURE_ATOL = 1e-12


def same_json(a: object, b: object) -> bool:
    """Equal structure, keys and strings; numbers within FIXTURE_ATOL (absolute, and relative to the larger)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_json(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_json(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, int | float) or not isinstance(b, int | float):
        return a == b
    return math.isclose(a, b, rel_tol=FIXTURE_ATOL, abs_tol=FIXTURE_ATOL)


def test_js_fixtures_are_current() -> None:
    for name, text in make_js_fixtures.fixtures().items():
        path = make_js_fixtures.FIXTURES / name
        assert path.exists() and same_json(json.loads(path.read_text(encoding="utf-8")), json.loads(text)), (
            f"{path} is stale: run python3 tests/web/make_js_fixtures.py")


def test_fixture_comparison_sees_a_stale_number() -> None:
    assert same_json({"a": [1.0, "x"]}, {"a": [1.0 + 1e-15, "x"]})
    assert not same_json({"a": [1.0, "x"]}, {"a": [1.0 + 1e-9, "x"]})
    assert not same_json({"a": [1.0, "x"]}, {"a": [1.0, "y"]})
    assert not same_json({"a": 1.0}, {"b": 1.0})


def test_node_unit_tests_pass() -> None:
    node = shutil.which("node")
    assert node is not None, "node is not installed (the README's prerequisites: Node.js >= 20)"
    proc = subprocess.run([node, "--test", "test/"], cwd=REPO / "web", capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


PACKAGE = REPO / "web" / "packages" / "relight-three"


def test_three_package_unit_tests_pass() -> None:
    # the package's own `node --test` units; `three` resolves from web/node_modules (the parent folder's)
    node = shutil.which("node")
    assert node is not None, "node is not installed (the README's prerequisites: Node.js >= 20)"
    proc = subprocess.run([node, "--test", "test/"], cwd=PACKAGE, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


def test_three_package_packs_and_imports(tmp_path: Path) -> None:
    # `npm pack` builds the tarball a user installs; installed next to three (the peer dependency) in a fresh
    # folder, `import '@relight/three'` gives the loader, the light probe and the material, and the tarball holds
    # the types and the viewer's copied shaders but not the tests
    import json
    import tarfile

    npm, node = shutil.which("npm"), shutil.which("node")
    assert npm is not None and node is not None, "npm and node are needed"
    proc = subprocess.run([npm, "pack", "--json", "--pack-destination", str(tmp_path)], cwd=PACKAGE,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    info = json.loads(proc.stdout)[0]
    names = {f["path"] for f in info["files"]}
    assert {"package.json", "README.md", "src/index.js", "types/index.d.ts", "src/viewer/glsl.js"} <= names
    assert not any(n.startswith(("test/", "scripts/")) for n in names)
    modules = tmp_path / "app" / "node_modules"
    (modules / "@relight").mkdir(parents=True)
    with tarfile.open(tmp_path / info["filename"]) as tar:
        tar.extractall(tmp_path / "unpacked", filter="data")
    (tmp_path / "unpacked" / "package").rename(modules / "@relight" / "three")
    (modules / "three").symlink_to(REPO / "web" / "node_modules" / "three")
    script = ("import * as R from '@relight/three'; import { LightProbe } from 'three';\n"
              "const c = Array.from({length: 9}, (_, k) => [k, 0, 0]);\n"
              "const p = R.lightProbeFromSH({convention: 'three', coefficients: c});\n"
              "console.log(JSON.stringify({probe: p instanceof LightProbe, x: p.sh.coefficients[8].x,\n"
              "  exports: Object.keys(R).sort()}));\n")
    (tmp_path / "app" / "check.mjs").write_text(script, encoding="utf-8")
    run = subprocess.run([node, "check.mjs"], cwd=tmp_path / "app", capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout)
    assert out["probe"] is True and out["x"] == 8
    assert {"cubeChainTexture", "lightProbeFromSH", "ShrmMaterial", "RelightCubeChainLoader"} <= set(out["exports"])
