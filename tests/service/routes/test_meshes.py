"""``/meshes``: uploads of OBJ, glTF and GLB, the canonical geometry served back, the preloaded samples, and every
way an upload can be bad (a 4xx problem, nothing stored, the server healthy after each)."""

from __future__ import annotations

import base64
import hashlib
import json
import struct

import httpx
import numpy as np
import pytest

from relight.mesh import geometry, sample_mesh
from relight.mesh.gltf import write_glb
from relight.resources import mesh_dir
from relight.worker.blobs import BlobStore

from ..support import Server, assert_healthy, assert_problem, wait_until

pytestmark = pytest.mark.timeout(180)

#: A unit cube: 8 corners, 6 quads (fanned into 12 triangles), counter-clockwise seen from outside.
CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
CUBE_Q = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]]


def cube_obj(order: list[int] | None = None) -> bytes:
    """The cube as OBJ with its vertices listed in ``order`` (a permutation; faces renumbered to match)."""
    order = order or list(range(8))
    where = {old: new for new, old in enumerate(order)}
    lines = [f"v {x:g} {y:g} {z:g}" for x, y, z in CUBE_V[order]]
    lines += ["f " + " ".join(str(where[i] + 1) for i in q) for q in CUBE_Q]
    return ("\n".join(lines) + "\n").encode()


def blobs(server: Server) -> BlobStore:
    return BlobStore(server.log.parent / "blobs")


def mesh_of(http: httpx.Client, mesh_id: str) -> tuple[dict, object]:
    info = http.get(f"/meshes/{mesh_id}").json()
    r = http.get(f"/meshes/{mesh_id}/geometry.bin")
    assert r.status_code == 200 and r.headers["etag"] == f'"{info["geometry"]["sha256"]}"', r.headers
    assert len(r.content) == info["geometry"]["bytes"]
    return info, geometry.from_bytes(r.content, info["vertices"], info["faces"])


def test_samples_are_preloaded_as_meshes(http: httpx.Client) -> None:
    """The sample bunny and teapot are meshes like any upload: id = SHA-256 of the file, geometry = the core's
    canonical mesh (float32 of it: the positions' float32 rounding, 6e-8 relative, bounds the difference)."""

    def names() -> dict[str, dict] | None:
        items = {m["name"]: m for m in http.get("/meshes").json()["items"]}
        return items if {"bunny", "teapot"} <= set(items) else None

    items = wait_until(names, 120, "the sample meshes to be preloaded", interval=0.5)
    for name in ("bunny", "teapot"):
        data = (mesh_dir() / f"{name}.obj").read_bytes()
        assert items[name]["id"] == hashlib.sha256(data).hexdigest()
        core = sample_mesh(name)
        info, geo = mesh_of(http, items[name]["id"])
        assert (info["vertices"], info["faces"], info["format"]) == (core.n_vertices, core.n_faces, "obj")
        np.testing.assert_array_equal(geo.faces, core.faces)
        np.testing.assert_allclose(geo.positions, core.positions, rtol=0, atol=1e-6 * core.radius)
        np.testing.assert_allclose(geo.normals, core.normals, rtol=0, atol=1e-6)
        assert info["defects"]["merged_vertices"] == core.defects["merged_vertices"]


def test_obj_upload_is_welded_into_canonical_order(http: httpx.Client) -> None:
    first = http.post("/meshes?name=cube.obj", content=cube_obj())
    assert first.status_code == 201, first.text
    body = first.json()
    assert (body["vertices"], body["faces"], body["watertight"]) == (8, 12, True)
    assert first.headers["location"] == f"/meshes/{body['id']}"
    again = http.post("/meshes", content=cube_obj())
    assert again.status_code == 200 and again.json()["id"] == body["id"]
    # the same cube listed in another vertex order is another file (another id) but the same canonical geometry
    shuffled = http.post("/meshes", content=cube_obj([5, 2, 7, 0, 3, 6, 1, 4]))
    assert shuffled.status_code == 201 and shuffled.json()["id"] != body["id"]
    _, a = mesh_of(http, body["id"])
    _, b = mesh_of(http, shuffled.json()["id"])
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.faces, b.faces)
    # unit normals, each inside the corner's octant (area weights of the fanned quads are unequal: not the diagonal)
    np.testing.assert_allclose(np.linalg.norm(a.normals, axis=1), 1.0, atol=1e-6)
    assert np.all(np.sign(a.normals) == np.sign(a.positions - 0.5))
    r = http.get(f"/meshes/{body['id']}/geometry.bin", headers={"If-None-Match": f'"{body["geometry"]["sha256"]}"'})
    assert r.status_code == 304


def test_gltf_and_glb_uploads_match_the_obj(http: httpx.Client) -> None:
    """The cube as GLB and as glTF JSON (base64 buffer): the same canonical geometry as the OBJ."""
    tris = np.array([[q[0], q[k], q[k + 1]] for q in CUBE_Q for k in (1, 2)])
    glb = write_glb(CUBE_V, tris)
    r = http.post("/meshes?name=cube.glb", content=glb)
    assert r.status_code == 201 and r.json()["format"] == "glb", r.text
    obj_id = http.post("/meshes", content=cube_obj()).json()["id"]
    _, ref = mesh_of(http, obj_id)
    _, got = mesh_of(http, r.json()["id"])
    np.testing.assert_array_equal(got.faces, ref.faces)
    np.testing.assert_array_equal(got.positions, ref.positions)
    doc, binary = gltf_parts(glb)
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
    g = http.post("/meshes?name=cube.gltf", content=json.dumps(doc).encode())
    assert g.status_code == 201 and g.json()["format"] == "gltf", g.text
    np.testing.assert_array_equal(mesh_of(http, g.json()["id"])[1].faces, ref.faces)


def gltf_parts(glb: bytes) -> tuple[dict, bytes]:
    jlen = struct.unpack_from("<I", glb, 12)[0]
    doc = json.loads(glb[20:20 + jlen])
    blen = struct.unpack_from("<I", glb, 20 + jlen)[0]
    return doc, glb[28 + jlen:28 + jlen + blen]


def bad_meshes() -> dict[str, tuple[bytes, int, str]]:
    """name -> (bytes, status, a fragment of the problem's detail)."""
    tris = np.array([[q[0], q[k], q[k + 1]] for q in CUBE_Q for k in (1, 2)])
    glb = write_glb(CUBE_V, tris)
    lying = glb[:8] + struct.pack("<I", len(glb) + 4096) + glb[12:]  # header says 4 KiB more than the file has
    doc, binary = gltf_parts(glb)
    doc["accessors"][1]["count"] = 3 * 10**8  # 10^8 triangles declared, 36 indices present
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
    full = cube_obj()
    return {
        "truncated OBJ": (full[: full.rindex(b"f ") + 5], 422, "truncated"),
        "index out of range": (cube_obj().replace(b"f 1 4 3 2", b"f 1 4 3 99"), 422, "out of range"),
        "NaN coordinate": (cube_obj().replace(b"v 1 1 1", b"v 1 nan 1"), 422, "non-finite"),
        "10^8 declared faces": (json.dumps(doc).encode(), 422, "100000000 triangles"),
        "GLB with a lying header": (lying, 422, "header declares"),
        "no triangles": (b"v 0 0 0\nv 1 0 0\n", 422, "no triangles"),
        "binary garbage": (bytes(range(256)) * 4, 415, "unrecognised mesh"),
        "too large": (b"v 0 0 0\n" * 140_000, 413, "limit"),  # 1.1 MB > the test server's 1 MiB
        "empty": (b"", 422, "empty"),
    }


@pytest.mark.parametrize("case", list(bad_meshes()))
def test_bad_meshes_are_refused_and_nothing_is_stored(case: str, http: httpx.Client, server: Server) -> None:
    data, status, fragment = bad_meshes()[case]
    before = {m["id"] for m in http.get("/meshes?limit=1000").json()["items"]}
    r = http.post("/meshes", content=data)
    assert_problem(r, status, fragment)
    digest = hashlib.sha256(data).hexdigest()
    assert not blobs(server).has(digest), f"{case}: the rejected upload was stored"
    assert http.get(f"/meshes/{digest}").status_code == 404
    assert {m["id"] for m in http.get("/meshes?limit=1000").json()["items"]} == before
    assert_healthy(http)


def test_unknown_mesh_is_404(http: httpx.Client) -> None:
    assert_problem(http.get("/meshes/" + "f" * 64), 404, "no mesh")
    assert_problem(http.get("/meshes/" + "f" * 64 + "/geometry.bin"), 404, "no mesh")
