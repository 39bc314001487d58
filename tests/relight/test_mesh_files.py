"""relight.mesh's file side: format sniffing, the GLB writer, ``geometry.bin`` (``relight.mesh.geometry``) and the
samples as files (``relight.mesh.sample_file``)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import trimesh

from relight.errors import InputError
from relight.mesh import build, decode, geometry, sample_file, sample_mesh, sniff
from relight.mesh.gltf import read_gltf_bytes, write_glb
from relight.mesh.load import MESH_DIR


@pytest.mark.parametrize(("head", "expected"), [
    (b"glTF\x02\x00\x00\x00", "glb"), (b'  \n{"asset": {}}', "gltf"), (b"# cube\nv 0 0 0\n", "obj"),
    ("v 0 0 0 # caf\u00e9".encode(), "obj"), ("# \u00e9".encode()[:-1], "obj"),  # a character cut at the end
    (b"\x89PNG\r\n\x1a\n\x00\x00", None), (b"v 0 0 0\n\xff\xfe\xfd more text after", None)])
def test_sniff(head: bytes, expected: str | None) -> None:
    assert sniff(head) == expected


def test_write_glb_round_trips_and_trimesh_reads_it() -> None:
    """An independent reader (trimesh) sees the same triangles; relight's own decoder the same float32 values."""
    mesh = sample_mesh("teapot")
    glb = write_glb(mesh.positions, mesh.faces)
    raw = read_gltf_bytes(glb)
    np.testing.assert_array_equal(raw.positions, mesh.positions.astype(np.float32))
    np.testing.assert_array_equal(raw.faces, mesh.faces)
    tm = trimesh.load(trimesh.util.wrap_as_stream(glb), file_type="glb", force="mesh", process=False)
    np.testing.assert_allclose(np.asarray(tm.vertices), mesh.positions, rtol=1e-6, atol=1e-6 * mesh.radius)
    np.testing.assert_array_equal(np.asarray(tm.faces), mesh.faces)


def test_geometry_bin_round_trips_and_refuses_a_wrong_size() -> None:
    mesh = sample_mesh("bunny")
    blob, lay = geometry.to_bytes(mesh)
    assert lay["bytes"] == len(blob) == mesh.n_vertices * 40 + mesh.n_faces * 12
    sec = lay["sections"]
    assert [sec[k]["offset"] for k in ("positions", "normals", "tangents", "indices")] == [
        0, 12 * mesh.n_vertices, 24 * mesh.n_vertices, 40 * mesh.n_vertices]
    back = geometry.from_bytes(blob, mesh.n_vertices, mesh.n_faces)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    for a, b in ((back.positions, mesh.positions), (back.normals, mesh.normals), (back.tangents, mesh.tangents)):
        np.testing.assert_array_equal(a, b.astype(np.float32))
    with pytest.raises(InputError, match="bytes"):
        geometry.from_bytes(blob[:-4], mesh.n_vertices, mesh.n_faces)
    bad = bytearray(blob)
    bad[sec["indices"]["offset"]:sec["indices"]["offset"] + 4] = np.uint32(mesh.n_vertices).tobytes()
    with pytest.raises(InputError, match="out of range"):
        geometry.from_bytes(bytes(bad), mesh.n_vertices, mesh.n_faces)


def test_sample_files() -> None:
    """The OBJ samples are their files; bunny-100k is a GLB generated deterministically (the same bytes twice)
    that decodes to the subdivided bunny's counts and surface."""
    name, data = sample_file("bunny")
    assert name == "bunny.obj" and data == (MESH_DIR / "bunny.obj").read_bytes()
    name, data = sample_file("bunny-100k")
    assert name == "bunny-100k.glb" and sniff(data[:16]) == "glb"
    assert hashlib.sha256(data).digest() == hashlib.sha256(sample_file("bunny-100k")[1]).digest()
    mesh = build(decode(data, name))
    ref = sample_mesh("bunny-100k")
    assert (mesh.n_vertices, mesh.n_faces) == (ref.n_vertices, ref.n_faces)
    assert 100_000 <= mesh.n_vertices <= 152_000  # the papers' scale (seed 002: 100K, seed 003: up to 152K)
    assert mesh.defects["surface_area"] == pytest.approx(ref.defects["surface_area"], rel=1e-6)
    with pytest.raises(InputError, match="unknown sample"):
        sample_file("dragon")
