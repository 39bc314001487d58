"""Seed 002's job kinds through ``POST /jobs`` against a real server (relight.server.services.gaussian): a fit and a
chain computed by the workers, their results and float16 files checked against the core run in the test process."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest

from relight.brdf.models import TorranceSparrow
from relight.envmap import read_envmap
from relight.gaussian_chain import RATIOS, build_chain
from relight.sgfit import FitSettings, fit_gaussian_lobes

from ..support import assert_problem, exr_bytes, make_envmap, start_server, wait_done

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    data = tmp_path_factory.mktemp("gaussian")
    server = start_server(data)
    exr = exr_bytes(make_envmap(32, seed=5), data)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            r = http.post("/envmaps", content=exr)
            assert r.status_code in (200, 201), r.text
            yield {"url": server.url, "env": r.json()["id"], "exr": exr, "data": data}
    finally:
        server.stop()


@pytest.fixture
def http(served: dict[str, Any]) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=served["url"], timeout=60) as c:
        yield c


def test_fit_job(http: httpx.Client) -> None:
    body = {"brdf": "torrance-sparrow:alpha=0.3,fresnel=none", "lobes": 2, "max_lobes": 2, "elevations": 4,
            "theta_max_deg": 60.0}
    r = http.post("/jobs", json={"kind": "gaussian_fit", "request": body})
    assert r.status_code == 202, r.text
    job = wait_done(http, r.headers["location"])
    assert job["state"] == "succeeded", job
    result = http.get(f"/jobs/{job['id']}/result").json()
    mat = result["material"]
    assert mat["kind"] == "gaussian-lobes" and len(mat["elevations"]) == 4 and result["lobes"] == 2
    # the same fit in this process (the fit is deterministic: same starts, same continuation)
    local = fit_gaussian_lobes(TorranceSparrow(0.3, fresnel="none"),
                               FitSettings(lobes=2, max_lobes=2, elevations=4, theta_max=math.radians(60.0)))
    np.testing.assert_allclose(result["errors"], local.errors, rtol=1e-9)
    assert max(result["errors"]) < 0.1  # K = 2, alpha 0.3: measured 4.8, 4.4, 4.7, 8.9 % at 0, 20, 40, 60 degrees
    # lobes.bin: the two K x N textures as float16 (N, K, 8)
    tex = np.frombuffer(http.get(f"/jobs/{job['id']}/files/lobes.bin").content, dtype="<f2").reshape(4, 2, 8)
    np.testing.assert_array_equal(tex[..., 0], local.mu.astype(np.float16))
    np.testing.assert_array_equal(tex[..., 1], local.sigma.astype(np.float16))
    np.testing.assert_array_equal(tex[..., 4:7], local.weight.astype(np.float16))
    again = http.post("/jobs", json={"kind": "gaussian_fit", "request": body})
    assert again.status_code == 200 and again.json()["id"] == job["id"]


def test_chain_job(http: httpx.Client, served: dict[str, Any]) -> None:
    body = {"envmap": served["env"], "levels": 3, "ratio": "sqrt2", "epsilon": 1e-3}
    r = http.post("/jobs", json={"kind": "gaussian_chain", "request": body})
    assert r.status_code == 202, r.text
    job = wait_done(http, r.headers["location"])
    assert job["state"] == "succeeded", job
    result = http.get(f"/jobs/{job['id']}/result").json()
    tmp = served["data"] / "env.exr"
    tmp.write_bytes(served["exr"])
    local = build_chain(read_envmap(tmp).pixels, ratio=RATIOS["sqrt2"], levels=3, epsilon=1e-3)
    assert [lv["sigma"] for lv in result["levels"]] == pytest.approx(list(local.sigmas), rel=1e-12)
    for entry, lv in zip(result["levels"], local.levels, strict=True):
        data = http.get(f"/jobs/{job['id']}/files/{entry['file']}").content
        got = np.frombuffer(data, dtype="<f2").reshape(entry["height"], entry["width"], 3)
        np.testing.assert_array_equal(got, lv.map.astype(np.float16))  # same core code, same float16 rounding


def test_bad_requests(http: httpx.Client) -> None:
    r = http.post("/jobs", json={"kind": "gaussian_fit", "request": {"brdf": "phong:s=10", "lobes": 3,
                                                                      "max_lobes": 2}})
    assert_problem(r, 422, "max_lobes")
    r = http.post("/jobs", json={"kind": "gaussian_chain", "request": {"envmap": "0" * 64}})
    assert r.status_code == 404, r.text
    r = http.post("/jobs", json={"kind": "gaussian_chain", "request": {"envmap": "0" * 64, "ratio": "3"}})
    assert_problem(r, 422, "ratio")
