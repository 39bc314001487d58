"""A non-editable install is self-contained: build the wheel, install it into a fresh virtual environment outside
the checkout, run ``relight serve`` from another directory, and check that the viewer page, every module it imports
(three.js included), the shaders, the sample maps and meshes, and ``render.png`` all answer from the installed files.

The fresh environment gets relight only from the wheel (``pip install --no-deps``). Its third-party dependencies
come from this test environment's site-packages through a ``.pth`` line: they are not what is under test, and
installing them again would take minutes. Such a line only appends a folder to ``sys.path`` (the ``.pth`` files in
that folder, among them the editable install's finder that maps ``relight`` to the checkout, are not run), and the
fresh environment's own site-packages comes first, so ``import relight`` finds the wheel; the test checks that it
does, and the server runs with no ``PYTHONPATH`` and its working directory outside the checkout.
"""

from __future__ import annotations

import io
import json
import os
import re
import signal
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urljoin, urlparse

import httpx
import numpy as np
import pytest
from PIL import Image

from relight import shrm
from relight.envmap import read_exr_layers
from relight.gl import layout as gl_layout
from tests.service.support import REPO, TEST_ENV, URL_LINE, exr_bytes, make_envmap, wait_until

pytestmark = [pytest.mark.timeout(600)]

SAMPLE_MAPS = {"city.exr", "courtyard.exr", "forest.exr", "studio.exr", "sunset.exr"}
#: ES module imports: ``import x from 'a'``, ``import 'a'``, ``export {x} from 'a'``, ``import('a')``.
_IMPORT = re.compile(r"""(?:\bimport|\bexport)\s*(?:[\w*{}\s,$]+?\s*from\s*)?\(?\s*['"]([^'"]+)['"]""")


def _run(args: list[str], **kw: object) -> None:
    proc = subprocess.run(args, capture_output=True, text=True, **kw)  # type: ignore[call-overload]
    assert proc.returncode == 0, f"{' '.join(args)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv (outside the checkout) with relight installed from a wheel built from the checkout."""
    root = tmp_path_factory.mktemp("wheel")
    assert REPO not in root.parents
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(root / "dist"), str(REPO)])
    (wheel,) = (root / "dist").glob("relight-*.whl")
    venv = root / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    python = venv / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--no-index", "--quiet",
          str(wheel)])
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    ours = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (Path(purelib) / "_relight_test_dependencies.pth").write_text("\n".join(sorted(ours)) + "\n")
    return venv


def _env(home: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("RELIGHT_", "PYTHON"))}
    env.update(TEST_ENV)
    env["RELIGHT_CACHE_DIR"] = str(home / "cache")
    return env


def test_relight_is_imported_from_the_wheel(installed: Path, tmp_path: Path) -> None:
    code = ("import relight, relight.server, relight.contract, relight.resources as r; "
            "print(relight.__file__); print(r.shader_dir()); print(r.mesh_dir()); print(r.sample_envmaps())")
    out = subprocess.run([str(installed / "bin" / "python"), "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, env=_env(tmp_path), check=True).stdout.split()
    assert len(out) == 4
    for path in out:
        assert Path(path).is_relative_to(installed), f"{path} is not inside the fresh environment {installed}"
        assert not Path(path).is_relative_to(REPO)
    assert {p.name for p in Path(out[3]).glob("*.exr")} == SAMPLE_MAPS


@pytest.fixture(scope="module")
def server(installed: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    home = tmp_path_factory.mktemp("elsewhere")
    log = home / "server.log"
    with open(log, "wb") as fh:
        proc = subprocess.Popen([str(installed / "bin" / "relight"), "serve", "--host", "127.0.0.1", "--port", "0",
                                 "--data", str(home / "data")], cwd=home, env=_env(home), stdout=fh,
                                stderr=subprocess.STDOUT, start_new_session=True)
        try:
            def ready() -> str | None:
                text = log.read_text(errors="replace")
                assert proc.poll() is None, f"server exited early:\n{text[-4000:]}"
                m = URL_LINE.search(text)
                return m.group(1) if m else None

            yield str(wait_until(ready, 120, "the installed server to print its URL", interval=0.1))
        finally:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                pass
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(timeout=30)


@pytest.fixture(scope="module")
def http(server: str) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=server, timeout=120) as c:
        yield c


def _resolve(spec: str, base: str, page: str, import_map: dict[str, str]) -> str:
    """A module specifier in the module at ``base``; import-map addresses are relative to the page."""
    if spec.startswith(("./", "../", "/")):
        return urljoin(base, spec)
    if spec in import_map:
        return urljoin(page, import_map[spec])
    prefix = max((k for k in import_map if k.endswith("/") and spec.startswith(k)), key=len, default=None)
    assert prefix is not None, f"bare specifier {spec!r} (in {base}) is not in the import map"
    return urljoin(page, import_map[prefix] + spec[len(prefix):])


def test_viewer_page_and_every_module_it_imports(http: httpx.Client, server: str, installed: Path) -> None:
    """Crawl the page's module graph as a browser would: every static and dynamic import answers 200 with
    JavaScript; the wheel carries exactly the three.js files the graph reaches (pyproject.toml's list), and they
    are the checkout's node_modules copies."""
    page = http.get("/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    import_map = json.loads(re.search(r'<script type="importmap">(.*?)</script>', page.text, re.S).group(1))["imports"]
    root = server + "/"
    todo = [urljoin(root, src) for src in re.findall(r'<script type="module" src="([^"]+)"', page.text)]
    todo += [urljoin(root, href) for href in re.findall(r'<link rel="stylesheet" href="([^"]+)"', page.text)]
    assert todo, "the page loads no module"
    seen: set[str] = set()
    while todo:
        url = todo.pop()
        if url in seen:
            continue
        seen.add(url)
        r = http.get(urlparse(url).path)
        assert r.status_code == 200, f"{url}: {r.status_code}"
        if url.endswith(".js"):
            assert "javascript" in r.headers["content-type"], url
            todo += [_resolve(spec, url, root, import_map) for spec in _IMPORT.findall(r.text)]
    three = {u.split("/vendor/three/", 1)[1] for u in seen if "/vendor/three/" in u}
    (packaged,) = installed.glob("lib/python*/site-packages/relight/web/node_modules/three")
    assert three == {p.relative_to(packaged).as_posix() for p in packaged.rglob("*.js")}
    assert {"build/three.module.js", "build/three.core.js"} <= three
    for rel in three:
        served = http.get(f"/vendor/three/{rel}").content
        assert served == (REPO / "web" / "node_modules" / "three" / rel).read_bytes(), rel


def test_shaders_and_meshes_are_the_checkouts(http: httpx.Client) -> None:
    shaders = sorted((REPO / "web" / "shaders").rglob("*.glsl"))
    assert shaders
    for path in shaders:
        rel = path.relative_to(REPO / "web" / "shaders").as_posix()
        r = http.get(f"/shaders/{rel}")
        assert r.status_code == 200 and r.content == path.read_bytes(), rel
    for name in ("bunny.obj", "teapot.obj"):
        r = http.get(f"/samples/meshes/{name}")
        assert r.status_code == 200 and r.content == (REPO / "data" / "meshes" / name).read_bytes()


def test_sample_maps_are_preloaded(http: httpx.Client) -> None:
    def names() -> set[str] | None:
        got = {e.get("name") for e in http.get("/envmaps").json()["items"]}
        return got if SAMPLE_MAPS <= got else None

    wait_until(names, 300, "the installed sample maps to be preloaded", interval=0.5)


def test_render_png_and_exr(http: httpx.Client, tmp_path: Path) -> None:
    """render.exr is eq. 12 evaluated on the CPU from the job's own coefficient texture (float16: tolerance as in
    tests/web/test_render_routes.py), so the server found its shaders; render.png draws the installed bunny."""
    up = http.post("/envmaps", content=exr_bytes(make_envmap(32, seed=7), tmp_path))
    assert up.status_code in (200, 201), up.text
    job = http.post("/shrms", json={"envmap": up.json()["id"], "brdf": {"kind": "microfacet", "sigma": 0.4},
                                    "order": 6, "p_order": 2})
    assert job.status_code in (200, 202), job.text
    job_id = job.json()["id"]
    wait_until(lambda: http.get(f"/jobs/{job_id}").json()["state"] == "succeeded", 300, "the job", interval=0.2)

    view = np.array([0.2, 0.5, 0.8])
    r = http.get(f"/shrms/{job_id}/render.exr", params={"view": "0.2,0.5,0.8", "size": 48})
    assert r.status_code == 200 and r.headers["content-type"] == "image/x-exr", r.text[:300]
    layers, _ = read_exr_layers(r.content)
    manifest = http.get(f"/shrms/{job_id}").json()
    lay = gl_layout.from_manifest(manifest)
    raw = http.get(f"/shrms/{job_id}/coefficients.bin").content
    stack = np.frombuffer(raw, dtype="<f2").astype(np.float64).reshape(-1, lay.height, lay.width, 3)
    want = shrm.render_sphere(gl_layout.to_shrm(lay, stack), view / np.linalg.norm(view), 48)
    np.testing.assert_allclose(np.asarray(layers[""], dtype=np.float64), want, atol=2e-3 * np.abs(want).max())

    images = {}
    for obj in ("sphere", "bunny"):
        png = http.get(f"/shrms/{job_id}/render.png", params={"view": "0,0.3,1", "size": 64, "object": obj})
        assert png.status_code == 200 and png.headers["content-type"] == "image/png"
        images[obj] = np.asarray(Image.open(io.BytesIO(png.content)))
        assert images[obj].shape == (64, 64, 3) and images[obj].std() > 0
    assert not np.array_equal(images["sphere"], images["bunny"])

