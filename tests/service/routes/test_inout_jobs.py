"""The ``inout_prt`` job kind through ``POST /jobs`` against the shared server (relight.server.services.inout): the
transport of the preloaded bunny for Phong s = 8 computed by a worker equals ``relight.inout_prt.mesh_transport``
run here on the served geometry (same seeded rays and factors: to binary16 rounding, 2^-11 relative, plus float32
sums of 512 rays, 1e-5 absolute), its factor texture equals ``relight.gl.inout.factor_texture`` exactly; an unknown
mesh is 404 and an anisotropic BRDF fails the job with the reason."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from relight.brdf.spec import parse_brdf
from relight.gl.inout import factor_texture
from relight.inout_factors import build_factors
from relight.inout_prt import mesh_transport
from relight.mesh import geometry
from relight.vertex_texture import unpack_float16

from ..support import assert_problem, wait_done
from .test_visibility import sample_id

pytestmark = pytest.mark.timeout(300)


def test_inout_job_equals_the_core(http: httpx.Client) -> None:
    mesh_id = sample_id(http, "bunny")
    body = {"mesh": mesh_id, "brdf": "phong:s=8", "energy": 0.95, "order": 3, "rays": 512}
    r = http.post("/jobs", json={"kind": "inout_prt", "request": body})
    assert r.status_code == 202, r.text
    job = wait_done(http, r.headers["location"])
    assert job["state"] == "succeeded", job
    res = http.get(f"/jobs/{job['id']}/result").json()
    info = http.get(f"/meshes/{mesh_id}").json()
    mesh = geometry.from_bytes(http.get(f"/meshes/{mesh_id}/geometry.bin").content, info["vertices"], info["faces"])
    f = build_factors(parse_brdf("phong:s=8"), energy=0.95)
    assert res["terms"] == f.terms and res["order"] == 3 and res["vertices"] == mesh.n_vertices
    assert res["predicted_error"] == pytest.approx(np.sqrt(1.0 - f.captured))
    want = mesh_transport(mesh, f, 3, rays=512)["transport"]
    lay = res["transport_texture"]
    raw = np.frombuffer(http.get(f"/jobs/{job['id']}/files/transport.bin").content, dtype="<f2")
    got = unpack_float16(raw.reshape(lay["height"], lay["width"], 4), lay)
    assert got.shape == want.shape
    assert np.all(np.abs(got - want) <= 2.0**-11 * np.abs(want) + 1e-5)
    fac = np.frombuffer(http.get(f"/jobs/{job['id']}/files/factors.bin").content, dtype="<f4")
    assert np.array_equal(fac.reshape(f.terms, -1), factor_texture(f))


def test_inout_bad_requests(http: httpx.Client) -> None:
    r = http.post("/jobs", json={"kind": "inout_prt", "request": {"mesh": "0" * 64, "brdf": "phong:s=8"}})
    assert_problem(r, 404)
    mesh_id = sample_id(http, "bunny")
    r = http.post("/jobs", json={"kind": "inout_prt", "request": {"mesh": mesh_id, "brdf": "phong:s=8", "order": 9}})
    assert_problem(r, 422)
    assert "order" in r.text
