"""The ``factorization`` job kind through ``POST /jobs`` against a real server (relight.server.services.
factorizations): the analysis computed by a worker equals ``relight.factor_analysis.analyse`` run in the test
process (same code, same grid: the SVD is deterministic, so K and the singular values agree to rounding, 1e-9
relative), its float16 factor file equals the core's factors to binary16 rounding (2^-11 relative), its PNG decodes
to the core's image exactly; two spellings of one BRDF share one job; bad requests are 422 naming the field."""

from __future__ import annotations

import io
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
from PIL import Image

from relight.brdf.spec import parse_brdf
from relight.factor_analysis import analyse, factor_image

from ..postgres import Backend
from ..support import assert_problem, start_server, wait_done

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def http(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Iterator[httpx.Client]:
    server = start_server(tmp_path_factory.mktemp("factorization"), database=database)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as c:
            yield c
    finally:
        server.stop()


def test_factorization_job_equals_the_core(http: httpx.Client) -> None:
    assert "factorization" in http.get("/jobs/kinds").json()["items"]
    body = {"brdf": "phong:s=30", "resolution": 40, "factors": 4}
    r = http.post("/jobs", json={"kind": "factorization", "request": body})
    assert r.status_code == 202, r.text
    job = wait_done(http, r.headers["location"])
    assert job["state"] == "succeeded", job
    same = http.post("/jobs", json={"kind": "factorization", "request": {**body, "brdf": {"kind": "phong", "s": 30}}})
    assert same.status_code == 200 and same.json()["id"] == job["id"]  # canonical BRDF: one job
    doc = http.get(f"/jobs/{job['id']}/result").json()["analysis"]
    want, res = analyse(parse_brdf("phong:s=30"), resolution=40, factors=4)
    assert doc["terms"] == want["terms"] and doc["terms"]["0.99"] == 75  # the paper's Fig. 6 on the paper's grid
    np.testing.assert_allclose(doc["singular_values"], want["singular_values"], rtol=1e-9)
    assert doc["predicted_terms"] == want["predicted_terms"] and doc["convergence"]["converged"]
    assert doc["quantity"] == "f_r cos(theta_i)" and doc["domain"] == "hemisphere"
    shape = tuple(doc["factors"]["shape"])
    assert shape == (4, 2, 40, 40) and len(doc["grid_nodes"]["theta"]) == 40
    got = np.frombuffer(http.get(f"/jobs/{job['id']}/files/factors.bin").content, dtype="<f2").reshape(shape)
    ref = np.stack([np.stack([f.g, f.h]) for f in res.factors])
    assert np.all(np.abs(got - ref) <= 2.0**-11 * np.abs(ref) + 1e-7)
    png = Image.open(io.BytesIO(http.get(f"/jobs/{job['id']}/files/factors.png").content))
    assert np.array_equal(np.asarray(png.convert("RGB")), factor_image(res))


@pytest.mark.parametrize(("request_body", "field"), [
    ({"brdf": "phong:s=-3"}, "brdf"),
    ({"brdf": "phong:s=8", "resolution": 2}, "resolution"),
    ({"brdf": "phong:s=8", "resolution": 400}, "phi"),
    ({"brdf": "phong:s=8", "domain": "disk"}, "domain"),
    ({"brdf": "phong:s=8", "factors": 99}, "factors"),
])
def test_bad_requests_are_422(http: httpx.Client, request_body: dict[str, object], field: str) -> None:
    r = http.post("/jobs", json={"kind": "factorization", "request": request_body})
    assert_problem(r, 422)
    assert field in r.text, r.text
