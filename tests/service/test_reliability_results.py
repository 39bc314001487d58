"""Issue 12, item 4: a missing or corrupt result file of *any* job kind is recomputed or answered 503, never served
and never reported "succeeded" for good; against a real server on loopback, one small job of every kind with files.

* **Deleted.** A scene whose file was deleted from the blob store was resubmitted and answered 200 "succeeded"
  without computing anything, and the file stayed gone. Now resubmitting a job whose stored files are missing
  answers 202 and computes it again; every file comes back byte-identical (same SHA-256: stored files carry no
  timings and no zip timestamps, the kinds are deterministic), the manifest of shrm and visibility results too.
* **Corrupted in place** (same inode and size, mtime put back): ``GET`` of the file answers 503 with ``Retry-After``
  (never the bytes), the job is queued again by itself, and the next ``GET`` after it finishes serves the file
  with the old digest.

``tradeoff`` is the one kind without files (its points live in the job row).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from relight.worker.blobs import BlobStore
from relight.worker.results import job_ref

from .postgres import Backend
from .routes.test_meshes import cube_obj
from .support import Server, exr_bytes, make_envmap, start_server, wait_until

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory, database: Backend) -> Path:
    return tmp_path_factory.mktemp(f"results-{database.name}")


@pytest.fixture(scope="module")
def server(data_dir: Path, database: Backend) -> Iterator[Server]:
    srv = start_server(data_dir, database=database)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def http(server: Server) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=server.url, timeout=120.0) as c:
        yield c


@pytest.fixture(scope="module")
def inputs(http: httpx.Client, data_dir: Path) -> dict[str, str]:
    env = http.post("/envmaps", content=exr_bytes(make_envmap(16, seed=21), data_dir))
    mesh = http.post("/meshes?name=cube.obj", content=cube_obj())
    assert env.status_code in (200, 201) and mesh.status_code in (200, 201), (env.text, mesh.text)
    return {"env": env.json()["id"], "mesh": mesh.json()["id"]}


#: kind -> (submission route, request from the uploaded inputs, route of a file by job id and name).
Case = tuple[str, Callable[[dict[str, str]], dict[str, Any]], str]
CASES: dict[str, Case] = {
    "scene": ("/scenes", lambda i: {"environment": i["env"], "epsilon": 0.05, "size": 8, "preview_size": 8,
                                    "objects": [{"name": "chalk", "size": 1, "distance": 10,
                                                 "material": "lambert:albedo=0.7"}]},
              "/scenes/{id}/files/{name}"),
    # planner v2's archives: the uploaded mesh's shadowed transfer (``chalk.transfer.npz``), the anisotropic
    # BRDF's SH table (``job<NN>-sh_table.npz``), each with a manifest inside, and the shadowed anisotropic mesh's
    # prt_matrix files for the viewer (``P.shadow_matrix.bin``, ``P.geometry.bin``, ``P.prt_matrix.json``)
    "scene_archives": ("/scenes", lambda i: {"environment": i["env"], "epsilon": 0.05, "size": 8, "objects": [
        {"name": "chalk", "mesh": i["mesh"], "size": 1, "distance": 10, "material": "lambert:albedo=0.7"},
        {"name": "brushed", "size": 1, "distance": 10, "material": "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0",
         "tangent": {"kind": "project", "direction": [1, 0, 0]}, "shadows": "none"},
        {"name": "brushed_shadowed", "mesh": i["mesh"], "size": 1, "distance": 10,
         "material": "ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0",
         "tangent": {"kind": "project", "direction": [1, 0, 0]}, "shadows": "exact"}]},
        "/scenes/{id}/files/{name}"),
    "shrm": ("/shrms", lambda i: {"envmap": i["env"], "brdf": "phong:s=8", "order": 4, "size": 8},
             "/shrms/{id}/{name}"),
    "visibility": ("/visibility", lambda i: {"mesh": i["mesh"], "order": 2, "rays": 64, "kind": "diffuse_transfer"},
                   "/visibility/{id}/files/{name}"),
    "factorization": ("/jobs", lambda i: {"brdf": "phong:s=30", "resolution": 16, "factors": 2},
                      "/jobs/{id}/files/{name}"),
    "gaussian_fit": ("/jobs", lambda i: {"brdf": "phong:s=10", "lobes": 1, "max_lobes": 1, "elevations": 2,
                                         "theta_max_deg": 60.0}, "/jobs/{id}/files/{name}"),
    "gaussian_chain": ("/jobs", lambda i: {"envmap": i["env"], "levels": 2, "ratio": "sqrt2", "epsilon": 1e-3},
                       "/jobs/{id}/files/{name}"),
    "ibl": ("/jobs", lambda i: {"envmap": i["env"], "target": "three", "format": "ktx2", "size": 8},
            "/jobs/{id}/files/{name}"),
    "dfg": ("/jobs", lambda i: {"size": 16, "format": "exr"}, "/jobs/{id}/files/{name}"),
    "inout_prt": ("/jobs", lambda i: {"mesh": i["mesh"], "brdf": "phong:s=8", "order": 2, "rays": 64},
                  "/jobs/{id}/files/{name}"),
    "sh_table": ("/jobs", lambda i: {"brdf": "phong:s=8", "order": 2, "resolution": 8}, "/jobs/{id}/files/{name}"),
    "sh_transfer": ("/jobs", lambda i: {"mesh": i["mesh"], "brdf": "phong:s=8", "order": 2, "resolution": 8,
                                        "rays": 64}, "/jobs/{id}/files/{name}"),
}


def submit(http: httpx.Client, kind: str, inputs: dict[str, str]) -> httpx.Response:
    route, request, _ = CASES[kind]
    body = request(inputs)
    return http.post(route, json={"kind": kind, "request": body} if route == "/jobs" else body)


def finished(http: httpx.Client, job_id: str) -> dict[str, Any]:
    def done() -> dict[str, Any] | None:
        job: dict[str, Any] = http.get(f"/jobs/{job_id}").json()
        return job if job["state"] in ("succeeded", "failed", "cancelled") else None

    job: dict[str, Any] = wait_until(done, 300, f"job {job_id}", interval=0.1)
    assert job["state"] == "succeeded", job
    return job


def files_of(http: httpx.Client, kind: str, job_id: str) -> dict[str, str]:
    """Name -> SHA-256 of every file the job's result lists (an SHRM's in its manifest)."""
    if kind == "shrm":
        files = http.get(f"/shrms/{job_id}").json()["files"]
    else:
        files = http.get(f"/jobs/{job_id}/result").json()["files"]
    out = {name: str(info["sha256"]) for name, info in files.items()}
    assert out, (kind, files)
    return out


def stored_of(http: httpx.Client, data_dir: Path, kind: str, job_id: str) -> dict[str, str]:
    """Every blob the job's result consists of: its files and, for the kinds whose result is a manifest named by
    the ref ``job-<id>`` (shrm, visibility), that manifest."""
    out = files_of(http, kind, job_id)
    manifest = BlobStore(data_dir / "blobs").get_ref(job_ref(job_id))
    if manifest is not None:
        out["(manifest ref)"] = manifest
    return out


def blob_path(data_dir: Path, digest: str) -> Path:
    return data_dir / "blobs" / "sha256" / digest[:2] / digest[2:4] / digest


def corrupt_in_place(path: Path) -> None:
    """Flip bytes in the middle of the file, keeping its inode, size and mtime."""
    st = path.stat()
    with open(path, "r+b") as fh:
        at = st.st_size // 2
        fh.seek(at)
        chunk = fh.read(min(16, st.st_size - at))
        fh.seek(at)
        fh.write(bytes(b ^ 0xFF for b in chunk))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (path.stat().st_size, path.stat().st_mtime_ns) == (st.st_size, st.st_mtime_ns)


@pytest.mark.parametrize("kind", sorted(CASES))
def test_a_lost_or_corrupt_result_file_is_recomputed_never_served(kind: str, http: httpx.Client, data_dir: Path,
                                                                  inputs: dict[str, str]) -> None:
    first = submit(http, kind, inputs)
    assert first.status_code in (200, 202), first.text
    job_id = first.json()["id"]
    measured = finished(http, job_id)["measured"]  # the timings are the job's record, not in its files
    assert measured is not None and measured["seconds"] > 0, measured
    if kind == "ibl":
        assert measured["stage_seconds"]["level_00"] > 0 and measured["task_seconds"] > 0, measured
    files = files_of(http, kind, job_id)
    if kind == "scene_archives":  # the case covers the viewer's prt_matrix files
        assert {"shadow_matrix.bin", "geometry.bin", "prt_matrix.json"} <= {n.split(".", 1)[-1] for n in files}, files
    stored = stored_of(http, data_dir, kind, job_id)
    url = CASES[kind][2]
    names = sorted(files)
    for name in names:  # all served, each verified against its name
        r = http.get(url.format(id=job_id, name=name))
        assert r.status_code == 200, (name, r.text)
        assert hashlib.sha256(r.content).hexdigest() == files[name]

    # 1. every blob of the result deleted: resubmitting computes the job again (202), never "succeeded" from the
    # cache (200), and the recomputed result is byte-identical, every file and manifest of it (no timings or zip
    # timestamps in stored files: relight.npz, the ibl manifest without seconds)
    for digest in set(stored.values()):
        blob_path(data_dir, digest).unlink()
    again = submit(http, kind, inputs)
    assert again.status_code == 202, (again.status_code, again.text)
    assert again.json()["id"] == job_id
    finished(http, job_id)
    assert stored_of(http, data_dir, kind, job_id) == stored  # the same bytes, every file
    for name in names:
        r = http.get(url.format(id=job_id, name=name))
        assert r.status_code == 200 and hashlib.sha256(r.content).hexdigest() == files[name], name

    # 2. a file corrupted in place: 503 with Retry-After on GET (the job queued again), then the file again
    bad = names[-1]
    corrupt_in_place(blob_path(data_dir, files[bad]))
    r = http.get(url.format(id=job_id, name=bad))
    assert r.status_code == 503, (r.status_code, r.headers.get("etag"))
    assert "retry-after" in r.headers and r.json()["job"] == f"/jobs/{job_id}"
    assert http.get(f"/jobs/{job_id}").json()["state"] in ("queued", "running", "succeeded")

    def served() -> httpx.Response | None:
        resp = http.get(url.format(id=job_id, name=bad))
        return resp if resp.status_code == 200 else None

    back = wait_until(served, 300, f"the {kind} file {bad} to be recomputed", interval=0.25)
    assert hashlib.sha256(back.content).hexdigest() == back.headers["etag"].strip('"') == files[bad]
    assert submit(http, kind, inputs).status_code == 200  # intact again: served from the store


def test_a_render_from_a_lost_result_is_503_then_drawn(http: httpx.Client, data_dir: Path,
                                                       inputs: dict[str, str]) -> None:
    """``GET /gaussian/render.png`` reads a fit's and a chain's files in a worker: with a chain level deleted it
    answered 422 ("cannot render": the worker's missing blob is a KeyError); now 503 with the chain queued again,
    then the image."""
    ids = {}
    for kind in ("gaussian_fit", "gaussian_chain"):
        r = submit(http, kind, inputs)
        assert r.status_code in (200, 202), r.text
        ids[kind] = r.json()["id"]
        finished(http, ids[kind])
    chain_files = files_of(http, "gaussian_chain", ids["gaussian_chain"])
    blob_path(data_dir, chain_files[sorted(chain_files)[0]]).unlink()
    params = {"fit": ids["gaussian_fit"], "chain": ids["gaussian_chain"], "size": 8, "view": "0,0.3,1"}
    r = http.get("/gaussian/render.png", params=params)
    assert r.status_code == 503 and "retry-after" in r.headers, (r.status_code, r.text)

    def drawn() -> httpx.Response | None:
        resp = http.get("/gaussian/render.png", params=params)
        return resp if resp.status_code == 200 else None

    png = wait_until(drawn, 300, "the render after the chain is recomputed", interval=0.25)
    assert png.content.startswith(b"\x89PNG") and png.headers["content-type"] == "image/png"
