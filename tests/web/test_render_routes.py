"""``server/api/routes/render.py`` against a live server: render.png/.exr (OpenGL), reference.png/.exr (angular
brute force), the environment texture, and problem details for bad requests."""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from PIL import Image

from relight import shrm
from relight.envmap import read_envmap, read_exr_layers, resample_latlong
from relight.gl import layout as gl_layout
from tests.service.conftest import Server, assert_problem, exr_bytes, make_envmap

pytestmark = [pytest.mark.timeout(300),
              pytest.mark.filterwarnings("ignore:invalid value encountered in multiply:RuntimeWarning")]


@pytest.fixture(scope="module")
def http(viewer_server: Server) -> Any:
    with httpx.Client(base_url=viewer_server.url, timeout=120) as c:
        yield c


@pytest.fixture(scope="module")
def envmap(http: httpx.Client, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, bytes]:
    data = exr_bytes(make_envmap(32, seed=5), tmp_path_factory.mktemp("maps"))
    r = http.post("/envmaps", content=data)
    assert r.status_code in (200, 201), r.text
    return r.json()["id"], data


def finished(http: httpx.Client, body: dict[str, Any]) -> str:
    r = http.post("/shrms", json=body)
    assert r.status_code in (200, 202), r.text
    job_id = r.json()["id"]
    deadline = time.monotonic() + 120
    while True:
        state = http.get(f"/jobs/{job_id}").json()["state"]
        if state == "succeeded":
            return str(job_id)
        assert state in ("queued", "running") and time.monotonic() < deadline, state
        time.sleep(0.2)


@pytest.fixture(scope="module")
def general(http: httpx.Client, envmap: tuple[str, bytes]) -> str:
    return finished(http, {"envmap": envmap[0], "brdf": {"kind": "microfacet", "sigma": 0.4}, "order": 6,
                           "p_order": 2})


def exr_image(data: bytes) -> np.ndarray:
    layers, _ = read_exr_layers(data)
    return np.asarray(layers[""], dtype=np.float64)


def cpu_model(http: httpx.Client, shrm_id: str) -> Any:
    manifest = http.get(f"/shrms/{shrm_id}").json()
    lay = gl_layout.from_manifest(manifest)
    raw = http.get(f"/shrms/{shrm_id}/coefficients.bin").content
    stack = np.frombuffer(raw, dtype="<f2").astype(np.float64).reshape(-1, lay.height, lay.width, 3)
    return gl_layout.to_shrm(lay, stack)


@pytest.mark.parametrize("mode", ["distant", "near"])
def test_render_exr_is_eq12_or_eq6(http: httpx.Client, general: str, mode: str) -> None:
    view = np.array([0.2, 0.5, 0.8])
    r = http.get(f"/shrms/{general}/render.exr", params={"view": "0.2,0.5,0.8", "size": 48, "mode": mode})
    assert r.status_code == 200 and r.headers["content-type"] == "image/x-exr", r.text[:300]
    got = exr_image(r.content)
    want = shrm.render_sphere(cpu_model(http, general), view / np.linalg.norm(view), 48, local=(mode == "near"))
    np.testing.assert_allclose(got, want, atol=2e-3 * np.abs(want).max())


def test_render_png_objects_and_rotation(http: httpx.Client, general: str) -> None:
    images = {}
    for obj in ("sphere", "bunny", "teapot"):
        r = http.get(f"/shrms/{general}/render.png", params={"view": "0,0.3,1", "size": 64, "object": obj})
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        images[obj] = np.asarray(Image.open(io.BytesIO(r.content)))
        assert images[obj].shape == (64, 64, 3)
    assert not np.array_equal(images["sphere"], images["bunny"])
    rotated = http.get(f"/shrms/{general}/render.png", params={"view": "0,0.3,1", "size": 64, "rotation": 90})
    assert not np.array_equal(np.asarray(Image.open(io.BytesIO(rotated.content))), images["sphere"])


def test_reference_is_the_angular_brute_force(http: httpx.Client, general: str, envmap: tuple[str, bytes],
                                              tmp_path: Path) -> None:
    from relight.brdf.spec import parse_brdf
    from relight.reference_view import reference_sphere

    r = http.get(f"/shrms/{general}/reference.exr", params={"view": "0,0.6,0.8", "size": 24})
    assert r.status_code == 200, r.text[:500]
    got = exr_image(r.content)
    env = read_envmap(envmap[1]).pixels
    want = reference_sphere(env, parse_brdf({"kind": "microfacet", "sigma": 0.4}), np.array([0.0, 0.6, 0.8]), 24)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6 * np.abs(want).max())
    png = http.get(f"/shrms/{general}/reference.png", params={"view": "0,0.6,0.8", "size": 24})
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")


def test_environment_texture(http: httpx.Client, envmap: tuple[str, bytes]) -> None:
    r = http.get(f"/envmaps/{envmap[0]}/texture.bin", params={"rows": 16})
    assert r.status_code == 200
    h, w, c = (int(x) for x in r.headers["X-Texture-Shape"].split(","))
    assert (h, w, c) == (16, 32, 3)
    got = np.frombuffer(r.content, dtype="<f2").astype(np.float64).reshape(h, w, 3)
    want = resample_latlong(read_envmap(envmap[1]).pixels, 16)
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=1e-4)
    again = http.get(f"/envmaps/{envmap[0]}/texture.bin", params={"rows": 16},
                     headers={"If-None-Match": r.headers["ETag"]})
    assert again.status_code == 304


def test_bad_requests_are_problems(http: httpx.Client, general: str) -> None:
    assert_problem(http.get(f"/shrms/{general}/render.png", params={"view": "0,0,0"}), 422, "non-zero")
    assert_problem(http.get(f"/shrms/{general}/render.png", params={"view": "up"}), 422, "x,y,z")
    r = http.get(f"/shrms/{general}/render.png", params={"object": "cube"})
    assert r.status_code == 422 and r.headers["content-type"].startswith("application/problem+json")
    assert_problem(http.get(f"/shrms/{'0' * 64}/render.png"), 404)
    assert_problem(http.get(f"/envmaps/{'0' * 64}/texture.bin"), 404)


def test_mesh_reference_is_mitsubas_image_and_bad_requests_are_problems(
        http: httpx.Client, envmap: tuple[str, bytes], tmp_path: Path) -> None:
    """``GET /meshes/{id}/reference.exr``: Mitsuba's render of the uploaded mesh (the same call in this process
    gives the same image: Mitsuba is deterministic for a seed, so 1e-6 covers float32 storage), cached; bad
    parameters are 4xx problems and leave nothing behind."""
    from relight.conventions import luminance
    from relight.envmap import read_envmap
    from relight.mesh import geometry
    from relight.mitsuba_mesh import render_mesh_mitsuba
    from relight.resources import mesh_dir

    r = http.post("/meshes?name=teapot.obj", content=(mesh_dir() / "teapot.obj").read_bytes())
    assert r.status_code in (200, 201), r.text
    info = r.json()
    mesh = geometry.from_bytes(http.get(f"/meshes/{info['id']}/geometry.bin").content, info["vertices"],
                               info["faces"]).normalised()
    url = f"/meshes/{info['id']}/reference.exr"
    q = {"envmap": envmap[0], "view": "0,0.6,0.8", "size": 32, "spp": 16, "rotation": 30, "albedo": 0.5}
    r = http.get(url, params=q)
    assert r.status_code == 200, r.text
    got = exr_image(r.content)
    (tmp_path / "m.exr").write_bytes(envmap[1])
    px = np.asarray(read_envmap(tmp_path / "m.exr").pixels, dtype=np.float32)  # 32 rows: not resampled
    want = render_mesh_mitsuba(mesh, px, view=np.array([0.0, 0.6, 0.8]), size=32, spp=16, albedo=0.5,
                               env_rotation=np.radians(30.0))
    np.testing.assert_allclose(got, want.rgb, rtol=1e-6, atol=1e-6 * want.rgb.max())
    noise = float(np.sqrt(want.variance.sum() / np.sum(luminance(want.rgb) ** 2)))
    assert float(r.headers["X-Reference-Noise"]) == pytest.approx(noise, rel=1e-4)
    assert http.get(url, params=q).content == r.content  # cached by content
    png = http.get(f"/meshes/{info['id']}/reference.png", params=q)
    assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"

    meshes_before = http.get("/meshes").json()
    assert_problem(http.get(url, params={**q, "envmap": "0" * 64}), 404)
    assert_problem(http.get(f"/meshes/{'0' * 64}/reference.exr", params=q), 404)
    assert_problem(http.get(url, params={**q, "size": 512}), 422, "size")
    assert_problem(http.get(url, params={**q, "max_depth": 1}), 422, "max_depth")
    assert_problem(http.get(url, params={**q, "size": 256, "spp": 1024}), 422, "spp")
    assert_problem(http.get(url, params={**q, "view": "0,0,0"}), 422, "non-zero")
    assert_problem(http.get(url, params={k: v for k, v in q.items() if k != "envmap"}), 422, "envmap")
    assert http.get("/meshes").json() == meshes_before
