"""Engine exports through the service (issue 17): ``GET /envmaps/{id}/ibl`` computes an ``ibl`` job and serves its
file, byte-identical to the core's ``relight.engine_export`` in the test process; the SDK and ``relight export /
bake --server`` read it; bad parameters are 4xx problems naming the parameter."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from relight.client.sdk import RelightClient
from relight.engine_export import chain_export, gltf_export, sh_export, without_seconds
from relight.envmap import read_envmap
from relight.ktx2 import read_ktx2

from ..postgres import Backend
from ..support import assert_problem, exr_bytes, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[dict[str, Any]]:
    data = tmp_path_factory.mktemp("ibl")
    server = start_server(data, database=database)
    exr = exr_bytes(make_envmap(32, seed=11), data)
    path = data / "map.exr"
    path.write_bytes(exr)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            r = http.post("/envmaps", content=exr)
            assert r.status_code in (200, 201), r.text
            yield {"url": server.url, "env": r.json()["id"], "path": path, "data": data}
    finally:
        server.stop()


@pytest.fixture
def http(served: dict[str, Any]) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=served["url"], timeout=60) as c:
        yield c


def _get_when_done(http: httpx.Client, url: str, params: dict[str, Any], kind: str = "ibl") -> httpx.Response:
    first = http.get(url, params=params)
    if first.status_code == 202:
        assert first.headers["location"] == f"/jobs/{first.json()['id']}" and first.json()["kind"] == kind
        return wait_until(lambda: (r := http.get(url, params=params)).status_code == 200 and r, 300, "the ibl job")
    return first


def test_ktx2_resource_equals_the_core(http: httpx.Client, served: dict[str, Any]) -> None:
    params = {"target": "filament", "size": 8, "sun": "clamp=2"}
    r = _get_when_done(http, f"/envmaps/{served['env']}/ibl", params)
    assert r.headers["content-type"] == "image/ktx2"
    local = chain_export(read_envmap(served["path"]).pixels, {}, target="filament", size=8, levels=None,
                         epsilon=2.5e-5, sun_spec="clamp=2")
    assert r.content == local.data  # the same bytes as relight export
    job = r.headers["x-relight-job"]
    manifest = http.get(f"/jobs/{job}/result").json()["manifest"]
    assert without_seconds({**manifest, "source": {}}) == without_seconds({**local.manifest, "source": {}})
    assert manifest["source"] == {"envmap": served["env"], "height": 32, "width": 64}
    assert len(read_ktx2(r.content).levels) == 4
    # cached: the same parameters answer at once from the same job; the ETag revalidates
    again = http.get(f"/envmaps/{served['env']}/ibl", params=params)
    assert again.status_code == 200 and again.headers["x-relight-job"] == job
    assert http.get(f"/envmaps/{served['env']}/ibl", params=params,
                    headers={"If-None-Match": again.headers["etag"]}).status_code == 304


def test_packed_pixel_format_equals_the_core(http: httpx.Client, served: dict[str, Any]) -> None:
    r = _get_when_done(http, f"/envmaps/{served['env']}/ibl", {"size": 4, "pixel_format": "e5b9g9r9"})
    local = chain_export(read_envmap(served["path"]).pixels, {}, target="three", size=4, levels=None,
                         epsilon=2.5e-5, sun_spec="keep", pixel_format="e5b9g9r9")
    assert r.content == local.data and read_ktx2(r.content).vk_format == 123
    # the default is left out of the canonical request: naming it is the same job as not naming it
    a = _get_when_done(http, f"/envmaps/{served['env']}/ibl", {"size": 4})
    b = http.get(f"/envmaps/{served['env']}/ibl", params={"size": 4, "pixel_format": "rgba16f"})
    assert b.status_code == 200 and a.headers["x-relight-job"] == b.headers["x-relight-job"]


def test_sh_resource_ignores_chain_parameters(http: httpx.Client, served: dict[str, Any]) -> None:
    r = _get_when_done(http, f"/envmaps/{served['env']}/ibl", {"format": "sh", "size": 16})
    local = sh_export(read_envmap(served["path"]).pixels, {"envmap": served["env"], "height": 32, "width": 64},
                      sun_spec="keep")
    assert json.loads(r.content) == json.loads(local.data)
    other = http.get(f"/envmaps/{served['env']}/ibl", params={"format": "sh", "size": 64, "target": "babylon"})
    assert other.status_code == 200 and other.headers["x-relight-job"] == r.headers["x-relight-job"]


METAL = "gltf-pbr:base=0.9/0.6/0.2,metallic=1"


def test_brdf_chain_equals_the_core(http: httpx.Client, served: dict[str, Any]) -> None:
    """``brdf`` is ``relight export --brdf SPEC``: the same bytes as the core's chain of that lobe family, a job of
    its own; the default lobe's request stays without the key (its job id is the one it always had)."""
    url = f"/envmaps/{served['env']}/ibl"
    r = _get_when_done(http, url, {"size": 4, "brdf": METAL})
    local = chain_export(read_envmap(served["path"]).pixels, {}, target="three", size=4, levels=None,
                         epsilon=2.5e-5, sun_spec="keep", brdf=METAL)
    assert r.content == local.data and read_ktx2(r.content).metadata["brdf"] == METAL
    plain = _get_when_done(http, url, {"size": 4})
    assert plain.content != r.content and plain.headers["x-relight-job"] != r.headers["x-relight-job"]
    request = http.get(f"/jobs/{plain.headers['x-relight-job']}").json()["request"]
    assert "brdf" not in request and http.get(f"/jobs/{r.headers['x-relight-job']}").json()["request"]["brdf"] == METAL
    # SH9 is the lighting's alone: a brdf does not make another SH job
    sh = _get_when_done(http, url, {"format": "sh"})
    assert http.get(url, params={"format": "sh", "brdf": METAL}).headers["x-relight-job"] == sh.headers["x-relight-job"]


def test_gltf_resource_equals_the_core(http: httpx.Client, served: dict[str, Any]) -> None:
    r = _get_when_done(http, f"/envmaps/{served['env']}/ibl", {"format": "gltf", "target": "gltf", "size": 4})
    assert r.headers["content-type"] == "model/gltf-binary" and r.content[:4] == b"glTF"
    local = gltf_export(read_envmap(served["path"]).pixels, {}, size=4, levels=None, epsilon=2.5e-5, sun_spec="keep")
    assert r.content == local.data  # relight export --format gltf's bytes
    manifest = http.get(f"/jobs/{r.headers['x-relight-job']}/result").json()["manifest"]
    assert without_seconds({**manifest, "source": {}}) == without_seconds({**local.manifest, "source": {}})


@pytest.mark.parametrize(("fmt", "multiscatter"), [("exr", False), ("png", True), ("ktx2", False)])
def test_dfg_resource_equals_the_cli(http: httpx.Client, tmp_path: Path, fmt: str, multiscatter: bool) -> None:
    params = {"size": 16, "format": fmt, "multiscatter": str(multiscatter).lower()}
    r = _get_when_done(http, "/dfg", params, kind="dfg")
    assert r.headers["content-type"] == {"exr": "image/x-exr", "png": "image/png", "ktx2": "image/ktx2"}[fmt]
    out = tmp_path / f"dfg.{fmt}"
    cmd = [sys.executable, "-m", "relight.cli", "dfg", "--size", "16", "--out", str(out)]
    subprocess.run(cmd + (["--multiscatter"] if multiscatter else []), check=True, capture_output=True, timeout=600)
    assert r.content == out.read_bytes()
    again = http.get("/dfg", params=params)  # cached: the same job
    assert again.status_code == 200 and again.headers["x-relight-job"] == r.headers["x-relight-job"]


@pytest.mark.parametrize(("params", "field"), [({"size": 1}, "size"), ({"size": 4096}, "size"),
                                               ({"format": "tiff"}, "format"), ({"multiscatter": "perhaps"},
                                                                                "multiscatter")])
def test_bad_dfg_parameters_name_themselves(http: httpx.Client, params: dict[str, Any], field: str) -> None:
    body = assert_problem(http.get("/dfg", params=params), 422)
    assert field in json.dumps(body), body


@pytest.mark.parametrize(("params", "field"), [
    ({"size": 48}, "power of two"), ({"size": 2048}, "size"), ({"sun": "clamp=0"}, "sun"),
    ({"sun": "blind"}, "sun"), ({"target": "unity"}, "target"), ({"size": 4, "levels": 4}, "levels"),
    ({"brdf": "nope:x=1"}, "brdf"), ({"brdf": "kajiya-kay:s=8"}, "tangent"), ({"brdf": ""}, "brdf"),
    ({"format": "gltf", "target": "three"}, "target gltf"),
    ({"format": "gltf", "target": "gltf", "pixel_format": "e5b9g9r9"}, "pixel_format"),
])
def test_bad_parameters_name_themselves(http: httpx.Client, served: dict[str, Any], params: dict[str, Any],
                                        field: str) -> None:
    body = assert_problem(http.get(f"/envmaps/{served['env']}/ibl", params=params), 422)
    assert field in json.dumps(body), body


def test_a_failed_export_names_its_reason(http: httpx.Client, served: dict[str, Any]) -> None:
    """The synthetic map has no sun (its peak is ~50 x the mean, relight.sun needs 100 x): the job fails for good
    and the resource answers 422 with the core's reason, also to the SDK."""
    url = f"/envmaps/{served['env']}/ibl"
    wait_until(lambda: http.get(url, params={"sun": "extract", "size": 4}).status_code == 422, 300, "the failure")
    assert_problem(http.get(url, params={"sun": "extract", "size": 4}), 422, "no sun to extract")
    with RelightClient(served["url"]) as c, pytest.raises(Exception, match="no sun to extract"):
        c.ibl(served["env"], size=4, sun="extract")


def test_unknown_map_is_404(http: httpx.Client) -> None:
    assert_problem(http.get(f"/envmaps/{'b' * 64}/ibl"), 404, "b" * 64)


def test_sdk_and_cli_server_equal_local(served: dict[str, Any], tmp_path: Path) -> None:
    with RelightClient(served["url"]) as c:
        got = c.ibl(served["env"], target="gltf", size=4, sun="clamp=3")
    local = chain_export(read_envmap(served["path"]).pixels, {}, target="gltf", size=4, levels=None, epsilon=2.5e-5,
                         sun_spec="clamp=3")
    assert got.data == local.data and got.manifest["sun"] == local.manifest["sun"]
    # relight export --server writes the same file as relight export
    cli = [sys.executable, "-m", "relight.cli", "export", str(served["path"]), "--target", "three", "--size", "4"]
    subprocess.run([*cli, "--out", str(tmp_path / "local.ktx2")], check=True, capture_output=True, timeout=600)
    proc = subprocess.run([*cli, "--out", str(tmp_path / "served.ktx2"), "--server", served["url"]],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "served.ktx2").read_bytes() == (tmp_path / "local.ktx2").read_bytes()
    # --brdf and --format gltf through the service too
    gl = [sys.executable, "-m", "relight.cli", "export", str(served["path"]), "--target", "gltf", "--size", "4",
          "--format", "gltf", "--brdf", METAL]
    subprocess.run([*gl, "--out", str(tmp_path / "local.glb")], check=True, capture_output=True, timeout=600)
    proc = subprocess.run([*gl, "--out", str(tmp_path / "served.glb"), "--server", served["url"]],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "served.glb").read_bytes() == (tmp_path / "local.glb").read_bytes()


def test_bake_server_equals_local(served: dict[str, Any], tmp_path: Path) -> None:
    """Issue 17's ``--local`` = ``--server`` case: two maps, KTX2 and SH, -j 2 on the service side; every file
    byte-identical but the sidecars' seconds."""
    second = tmp_path / "second.exr"
    second.write_bytes(exr_bytes(make_envmap(16, seed=12), tmp_path))
    maps = [str(served["path"]), str(second)]
    bake = [sys.executable, "-m", "relight.cli", "bake", *maps, "--target", "babylon", "--size", "4", "--json"]
    loc = subprocess.run([*bake, "--out", str(tmp_path / "local"), "--local"], capture_output=True, text=True,
                         timeout=600)
    srv = subprocess.run([*bake, "--out", str(tmp_path / "server"), "--server", served["url"], "-j", "2"],
                         capture_output=True, text=True, timeout=600)
    assert loc.returncode == 0 and srv.returncode == 0, (loc.stderr, srv.stderr)
    assert [r["status"] for r in json.loads(srv.stdout)["items"]] == ["done"] * 4
    names = sorted(p.name for p in (tmp_path / "local").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "server").iterdir()) and len(names) == 6
    for name in names:
        a, b = (tmp_path / "local" / name).read_bytes(), (tmp_path / "server" / name).read_bytes()
        if name.endswith(".ktx2.json"):
            assert without_seconds(json.loads(a)) == without_seconds(json.loads(b)), name
        else:
            assert a == b, name
    # the served bake's items are skipped by a local rerun (one key, whoever computed it)
    rerun = subprocess.run([*bake, "--out", str(tmp_path / "server")], capture_output=True, text=True, timeout=600)
    assert [r["status"] for r in json.loads(rerun.stdout)["items"]] == ["skipped"] * 4


def test_bake_materials_server_equals_local(served: dict[str, Any], tmp_path: Path) -> None:
    """The same case with two materials (``--brdf`` twice) and the glTF format: one chain and one GLB per map x
    material, every file byte-identical between ``--local`` and ``--server`` but the sidecars' seconds."""
    bake = [sys.executable, "-m", "relight.cli", "bake", str(served["path"]), "--target", "gltf", "--size", "4",
            "--format", "ktx2,gltf,sh", "--brdf", METAL, "--brdf", "phong:s=32", "--json"]
    loc = subprocess.run([*bake, "--out", str(tmp_path / "local"), "--local"], capture_output=True, text=True,
                         timeout=600)
    srv = subprocess.run([*bake, "--out", str(tmp_path / "server"), "--server", served["url"], "-j", "2"],
                         capture_output=True, text=True, timeout=600)
    assert loc.returncode == 0 and srv.returncode == 0, (loc.stderr, srv.stderr)
    assert [r["status"] for r in json.loads(srv.stdout)["items"]] == ["done"] * 5
    names = sorted(p.name for p in (tmp_path / "local").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "server").iterdir()) and len(names) == 9
    assert sum(n.endswith(".glb") for n in names) == 2 and sum(n.endswith(".ktx2") for n in names) == 2
    for name in names:
        a, b = (tmp_path / "local" / name).read_bytes(), (tmp_path / "server" / name).read_bytes()
        if name.endswith((".ktx2.json", ".glb.json")):
            assert without_seconds(json.loads(a)) == without_seconds(json.loads(b)), name
        else:
            assert a == b, name


def test_submit_with_sun_prefilters_the_clamped_map(served: dict[str, Any]) -> None:
    """``relight submit --sun`` / ``ShrmCreate.sun``: the job prefilters the map after the sun step (the same floats
    as the core on ``relight.sun.clamp_map`` of the map), records it in the manifest's input, and is a different
    job from the same request without it."""
    import numpy as np

    from relight.brdf.models import Phong
    from relight.prefilter import prefilter_radial
    from relight.sun import clamp_map

    from ..support import read_exr

    with RelightClient(served["url"]) as c:
        job = c.submit(served["env"], "phong:s=16", epsilon=0.01, sun="clamp=2")
        assert job.params is not None and job.params.sun == "clamp=2"
        c.wait(job.id, timeout=300)
        got = read_exr(c.download(job.id, "coefficients.exr"))[""]
        manifest = c.get_shrm(job.id).model_dump()
        plain = c.submit(served["env"], "phong:s=16", epsilon=0.01)
    px = read_envmap(served["path"]).pixels
    clamped = clamp_map(px, 2.0)
    expected = prefilter_radial(clamped.pixels, Phong(16), epsilon=0.01).map.astype(np.float32)
    np.testing.assert_array_equal(got, expected)
    assert manifest["input"]["sun"] == json.loads(json.dumps(clamped.report))
    assert clamped.report["removed_energy_fraction"] > 0.01  # the clamp changed the map: the test can fail
    assert plain.id != job.id
