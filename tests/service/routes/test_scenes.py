"""``/scenes``: store a scene, run its plan as a job, read the plan, the result and the files."""

from __future__ import annotations

import tempfile
from typing import Any

import httpx
import numpy as np
import pytest

from relight.client.sdk import RelightClient

from ..support import assert_healthy, assert_problem, read_exr, wait_done

pytestmark = pytest.mark.timeout(240)
UNKNOWN = "f" * 64


def scene(env_id: str, **kw: Any) -> dict[str, Any]:
    return {"environment": env_id, "epsilon": 0.05, "size": 16, "preview_size": 16, "objects": [
        {"name": "chalk", "size": 1, "distance": 10, "material": "lambert:albedo=0.7"},
        {"name": "metal", "shape": "teapot", "size": 1, "distance": 2, "material": {"kind": "microfacet",
                                                                                  "sigma": 0.4},
         "view": [0, 0.5, 1], "shadows": "none"},
    ], **kw}


def test_scene_job_plan_result_and_files(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    r = http.post("/scenes", json=scene(env.id))
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    assert r.headers["location"] == f"/scenes/{sid}"
    done = wait_done(http, f"/scenes/{sid}")
    assert done["state"] == "succeeded", done
    objs = {o["name"]: o for o in done["plan"]["objects"]}
    assert objs["chalk"]["viewer"] == "distant" and objs["metal"]["viewer"] == "near"
    kinds = [(c["kind"], c["representation"]) for c in done["plan"]["computations"]]
    assert kinds == [("lambert", "irradiance"), ("microfacet", "shrm")]
    # a glossy lobe on a mesh with shadows: none keeps its SHRM; its shadows are listed as not simulated
    assert any(e["effect"].startswith("shadowing (glossy") and not e["simulated"] for e in objs["metal"]["effects"])
    assert [r["representation"] for r in objs["metal"]["representations"]] == ["shrm"]
    assert done["result"]["lighting_projections"] == 1
    assert {"chalk.view.exr", "metal.shrm.exr", "metal.sphere.png"} <= set(done["files"])
    f = http.get(f"/scenes/{sid}/files/chalk.view.exr")
    assert f.status_code == 200 and f.headers["etag"] == f'"{done["files"]["chalk.view.exr"]["sha256"]}"'
    assert read_exr(f.content)[""].shape == (16, 32, 3)
    assert http.get(f"/scenes/{sid}/files/chalk.view.exr", headers={"If-None-Match": f.headers["etag"]}
                    ).status_code == 304
    assert_problem(http.get(f"/scenes/{sid}/files/nothing.exr"), 404, "nothing.exr")
    for name in ("chalk", "metal"):
        check_texture(http, sid, done, name)
    # the same scene again: 200 with the stored result
    again = http.post("/scenes", json=scene(env.id))
    assert again.status_code == 200 and again.json()["id"] == sid and again.json()["state"] == "succeeded"
    assert_healthy(http)


def check_texture(http: httpx.Client, sid: str, done: dict[str, Any], name: str) -> None:
    """The object's viewer texture holds its SHRM's layers as float16 (the same numbers as ``{name}.shrm.exr`` to
    half precision: relative 2^-11), and its manifest describes them in the form ``/shrms`` manifests have
    (``relight.gl.layout.from_manifest`` reads it, as ``web/src/layout.js`` does)."""
    from relight.gl import layout as gl_layout
    from relight.shrm_io import read_shrm
    from relight.worker.shrm_adapter import shrm_layers

    files = next(o for o in done["result"]["objects"] if o["name"] == name)["files"]
    assert files["texture"] == f"{name}.texture.json" and files["coefficients_bin"] == f"{name}.coefficients.bin"
    manifest = http.get(f"/scenes/{sid}/files/{files['texture']}").raise_for_status().json()
    data = http.get(f"/scenes/{sid}/files/{files['coefficients_bin']}").raise_for_status().content
    exr = http.get(f"/scenes/{sid}/files/{files['shrm']}").raise_for_status().content
    lay = gl_layout.from_manifest(manifest)
    shape = manifest["files"]["coefficients.bin"]["shape"]
    assert shape == [lay.num_layers, 16, 32, 3] and len(data) == 2 * np.prod(shape)
    assert manifest["files"]["coefficients.bin"]["sha256"] == done["files"][files["coefficients_bin"]]["sha256"]
    texture = np.frombuffer(data, dtype="<f2").astype(np.float64).reshape(shape)
    with tempfile.NamedTemporaryFile(suffix=".exr") as f:
        f.write(exr)
        f.flush()
        want = np.stack([layer.pixels for layer in shrm_layers(read_shrm(f.name))])
    assert texture.shape == want.shape
    np.testing.assert_allclose(texture, want, rtol=2.0**-11, atol=1e-7)


@pytest.mark.parametrize(("patch", "status", "fragment"), [
    ({"epsilon": None}, 422, "exactly one"),
    ({"time_budget_s": 1.0}, 422, "exactly one"),
    ({"objects": []}, 422, "objects"),
    ({"environment": UNKNOWN}, 404, UNKNOWN),
    ({"size": 4}, 422, "size"),
])
def test_invalid_scenes(client: RelightClient, http: httpx.Client, sample_exr: bytes, patch: dict[str, Any],
                        status: int, fragment: str) -> None:
    env = client.upload_envmap(sample_exr)
    assert_problem(http.post("/scenes", json=scene(env.id, **patch)), status, fragment)


def test_scene_checks_of_the_core(client: RelightClient, http: httpx.Client, sample_exr: bytes) -> None:
    env = client.upload_envmap(sample_exr)
    body = scene(env.id)
    body["objects"][0]["distance"] = 0.5  # the viewer inside the object
    assert_problem(http.post("/scenes", json=body), 422, "outside the object")
    body = scene(env.id)
    body["objects"][1]["name"] = "chalk"
    assert_problem(http.post("/scenes", json=body), 422, "duplicate name")
    body = scene(env.id)
    body["objects"][0]["material"] = "phong:s=-1"
    assert_problem(http.post("/scenes", json=body), 422, "brdf")
    assert_problem(http.get(f"/scenes/{UNKNOWN}"), 404, UNKNOWN)
    assert_problem(http.get(f"/scenes/{UNKNOWN}/files/x.exr"), 404, UNKNOWN)


def test_scene_on_an_uploaded_mesh_is_planned_and_shadowed(client: RelightClient, http: httpx.Client,
                                                            sample_exr: bytes) -> None:
    """Planner v2's inputs through the API: an uploaded mesh (``POST /meshes``) with a Lambertian material gets its
    shadowed transfer computed on exactly the uploaded vertices; an anisotropic material (not a registry BRDF) is
    planned as an SH table; unknown meshes are 404."""
    from relight.mesh import sample_file

    env = client.upload_envmap(sample_exr)
    name, data = sample_file("teapot")
    mesh = http.post(f"/meshes?name={name}", content=data)
    assert mesh.status_code in (200, 201), mesh.text
    mesh_id = mesh.json()["id"]
    body = {"environment": env.id, "epsilon": 0.05, "size": 16, "lighting": "rotating", "objects": [
        {"name": "chalk", "mesh": mesh_id, "size": 1, "distance": 10, "material": "lambert:albedo=0.7"},
        {"name": "brushed", "size": 1, "distance": 10, "material": "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0",
         "tangent": {"kind": "project", "direction": [1, 0, 0]}, "shadows": "none"}]}
    r = http.post("/scenes", json=body)
    assert r.status_code == 202, r.text
    done = wait_done(http, f"/scenes/{r.json()['id']}")
    assert done["state"] == "succeeded", done
    objs = {o["name"]: o for o in done["plan"]["objects"]}
    assert objs["chalk"]["mesh"] == mesh_id and objs["chalk"]["shadows"]["vertices"] == mesh.json()["vertices"]
    assert objs["chalk"]["representations"][0]["representation"] == "diffuse_transfer"
    assert objs["brushed"]["representations"][0]["representation"] == "sh_table"
    assert done["plan"]["lighting_mode"] == "rotating" and done["plan"]["frame"]["predicted_ms"] > 0
    assert "chalk.transfer.npz" in done["files"]
    entry = {o["name"]: o for o in done["result"]["objects"]}["chalk"]
    assert entry["shadows"]["vertices"] == mesh.json()["vertices"]
    body["objects"][0]["mesh"] = UNKNOWN
    assert_problem(http.post("/scenes", json=body), 404, UNKNOWN)
