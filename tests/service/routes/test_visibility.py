"""``/visibility``: per-vertex visibility and transfer of a stored mesh as a job of the one job system, fanned out
over the server's two workers by vertex blocks; its files against the core computed in this process."""

from __future__ import annotations

import io
import time
from typing import Any

import httpx
import numpy as np
import pytest

from relight.mesh import geometry
from relight.vertex_texture import unpack_float16
from relight.visibility import TransferSettings, compute_transfer

from ..support import assert_healthy, assert_problem, wait_done, wait_until

pytestmark = pytest.mark.timeout(300)


def sample_id(http: httpx.Client, name: str) -> str:
    def find() -> str | None:
        ids = [m["id"] for m in http.get("/meshes").json()["items"] if m["name"] == name]
        return ids[0] if ids else None

    found: str = wait_until(find, 120, f"the sample mesh {name} to be preloaded", interval=0.5)
    return found


def result(http: httpx.Client, job_id: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    manifest = http.get(f"/visibility/{job_id}").json()
    npz = np.load(io.BytesIO(http.get(f"/visibility/{job_id}/files/visibility.npz").content))
    return manifest, {k: npz[k] for k in npz.files}


def test_diffuse_transfer_job_fans_out_and_equals_the_core(http: httpx.Client) -> None:
    """Bunny (1839 vertices) in blocks of 512 (4 blocks over 2 workers) equals one serial ``compute_transfer`` on
    the served geometry: the blocks share the seeded directions. Tolerance 1e-5 absolute: float32 sums of 256
    terms in either process (BLAS blocking may differ), values |T| <= 1."""
    mesh_id = sample_id(http, "bunny")
    body = {"mesh": mesh_id, "order": 3, "rays": 256, "kind": "diffuse_transfer", "block": 512}
    r = http.post("/visibility", json=body)
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["kind"] == "visibility" and job["request"]["geometry"]["vertices"] == 1839
    done = wait_done(http, f"/jobs/{job['id']}")
    assert done["state"] == "succeeded", done
    assert done["measured"]["rms_error"] > 0
    # the blocks ran as Dask tasks of their own; on two idle workers both usually take some (not asserted: the
    # scheduler decides), the count is reported
    assert done["measured"]["processes"] in (1, 2), done["measured"]
    manifest, arrays = result(http, job["id"])
    assert manifest["blocks"] == 4 and manifest["coefficients"] == 16 and manifest["mesh"] == mesh_id
    info = http.get(f"/meshes/{mesh_id}").json()
    mesh = geometry.from_bytes(http.get(f"/meshes/{mesh_id}/geometry.bin").content, info["vertices"], info["faces"])
    ref = compute_transfer(mesh, TransferSettings(order=3, rays=256, kind="diffuse_transfer", block=512))
    assert set(arrays) == set(ref.arrays)
    for key, value in ref.arrays.items():
        np.testing.assert_allclose(arrays[key], value, rtol=0, atol=1e-5, err_msg=key)
    assert manifest["monte_carlo_error_rms"] == pytest.approx(ref.manifest["monte_carlo_error_rms"], rel=1e-4)
    # the float16 textures hold the float32 values rounded to half precision (relative 2^-11)
    for name in ("transfer", "visibility", "ao"):
        f = manifest["files"][f"{name}.bin"]
        raw = http.get(f"/visibility/{job['id']}/files/{name}.bin")
        assert raw.status_code == 200 and raw.headers["etag"] == f'"{f["sha256"]}"'
        tex = np.frombuffer(raw.content, dtype="<f2").reshape(f["texture"]["height"], f["texture"]["width"], 4)
        np.testing.assert_array_equal(unpack_float16(tex, f["texture"]), arrays[name].astype(np.float16))
    # the same request again: the finished job, 200
    again = http.post("/visibility", json=body)
    assert again.status_code == 200 and again.json()["id"] == job["id"] and again.json()["cached"] is True
    assert done["links"]["transfer.bin"] == f"/visibility/{job['id']}/files/transfer.bin"
    # the predicted Monte Carlo error is the i.i.d. bound (relight.visibility.predict): the stratified set stays below
    assert done["measured"]["rms_error"] <= done["predicted"]["rms_error"], (done["measured"], done["predicted"])
    # the generic route takes the same request: the same job, its files through /jobs/{id}/files
    generic = http.post("/jobs", json={"kind": "visibility", "request": body})
    assert generic.status_code == 200 and generic.json()["id"] == job["id"], generic.text
    raw = http.get(f"/jobs/{job['id']}/files/ao.bin")
    assert raw.status_code == 200 and raw.headers["etag"] == f'"{manifest["files"]["ao.bin"]["sha256"]}"'


def test_shadow_matrix_job_is_symmetric_and_contracts_visibility(http: httpx.Client) -> None:
    """Teapot, F = 2: a shadow-only transfer matrix is symmetric, and its trace-free part agrees with the
    visibility it was computed with: M_00 = v_0 / sqrt(4 pi) exactly (Y_00 is constant)."""
    mesh_id = sample_id(http, "teapot")
    r = http.post("/visibility", json={"mesh": mesh_id, "order": 2, "rays": 64, "kind": "shadow_matrix"})
    done = wait_done(http, f"/jobs/{r.json()['id']}")
    assert done["state"] == "succeeded", done
    _, arrays = result(http, r.json()["id"])
    m = arrays["shadow_matrix"]
    assert m.shape == (529, 9, 9)
    np.testing.assert_allclose(m, np.swapaxes(m, 1, 2), atol=1e-6)
    np.testing.assert_allclose(m[:, 0, 0], arrays["visibility"][:, 0] / np.sqrt(4 * np.pi), atol=1e-5)


def test_bad_visibility_requests(http: httpx.Client) -> None:
    mesh_id = sample_id(http, "teapot")
    assert_problem(http.post("/visibility", json={"mesh": "f" * 64}), 404, "no mesh")
    assert_problem(http.post("/visibility", json={"mesh": mesh_id, "order": 9}), 422, "order")
    assert_problem(http.post("/visibility", json={"mesh": mesh_id, "bounces": 1}), 422, "diffuse_transfer")
    assert_problem(http.post("/visibility", json={"mesh": mesh_id, "rays": 4}), 422, "rays")
    assert_problem(http.get("/visibility/" + "f" * 64), 404, "no visibility")
    assert_healthy(http)


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of every process under the server (its Dask workers, the planning sandboxes)."""
    import psutil

    total = 0.0
    for p in psutil.Process(pid).children(recursive=True):
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            continue
    return total


def test_cancelling_a_fanned_out_job_stops_its_blocks(server: Any, http: httpx.Client) -> None:
    """A job fanned out in 29 blocks over the two workers (bunny, 65536 rays per vertex, 64 vertices per block:
    4.2 M rays a block), cancelled once its first block is in: it ends ``cancelled`` with no result, its progress
    stops, and the blocks stop too: the workers' CPU time goes flat (a 2 s window with at most 0.3 CPU s, for
    heartbeats). The allowance for the blocks in flight is scaled by the first block's own duration T, so the
    check holds on a loaded machine: quiet within 3 T + 4 s of the cancel, while the uncancelled remainder (28
    blocks over 2 workers, about 14 T) would keep both workers busy far longer. CPU time is what is asserted."""
    mesh_id = sample_id(http, "bunny")
    body = {"mesh": mesh_id, "order": 3, "rays": 65536, "kind": "diffuse_transfer", "block": 64, "seed": 77}
    r = http.post("/visibility", json=body)
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    wait_until(lambda: http.get(f"/jobs/{job_id}").json()["state"] == "running", 240, "the job to run",
               interval=0.05)
    t_start = time.monotonic()
    running = wait_until(lambda: (j := http.get(f"/jobs/{job_id}").json())["progress"] > 0.06 and j, 600,
                         "the first block to finish", interval=0.05)
    block_s = time.monotonic() - t_start
    assert running["state"] == "running" and running["stage"] == "tracing", running
    r = http.delete(f"/jobs/{job_id}")
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    progress = http.get(f"/jobs/{job_id}").json()["progress"]

    used: list[float] = []

    def quiet() -> bool:
        before = _cpu_seconds(server.pid)
        time.sleep(2.0)
        used.append(_cpu_seconds(server.pid) - before)
        return used[-1] < 0.3

    try:
        wait_until(quiet, 3 * block_s + 4, f"the workers to stop computing cancelled blocks (T = {block_s:.1f} s)",
                   interval=0.0)
    except AssertionError as exc:
        raise AssertionError(f"{exc}; CPU seconds per 2 s window: {used}") from None
    job = http.get(f"/jobs/{job_id}").json()
    assert job["state"] == "cancelled" and job["progress"] == progress, job
    assert http.get(f"/visibility/{job_id}").status_code in (404, 409)
    assert_healthy(http)
