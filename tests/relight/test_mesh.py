"""relight.mesh: decoding under caps, welding into the canonical order, normals, tangents, defects, bad files."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from relight.errors import InputError
from relight.mesh import Caps, RawMesh, build, decode, load_mesh, sample_mesh
from relight.mesh.gltf import read_gltf_bytes
from relight.mesh.load import MESH_DIR
from relight.mesh.obj import read_obj_bytes


def _obj_text(v: np.ndarray, f: np.ndarray) -> str:
    verts = "".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in v)
    return verts + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)


def _glb(doc: dict, binary: bytes, declared_length: int | None = None) -> bytes:
    """A GLB file (glTF 2.0 §4.4) from a JSON document and a BIN chunk, with an optionally lying total length."""
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(binary), 0x004E4942) + binary
    total = 12 + len(body)
    return struct.pack("<III", 0x46546C67, 2, declared_length if declared_length is not None else total) + body


def _triangle_glb(n_index: int | None = None, extra: dict | None = None, positions: np.ndarray | None = None) -> bytes:
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4") if positions is None else positions.astype("<f4")
    idx = np.array([0, 1, 2], dtype="<u4")
    binary = pos.tobytes() + idx.tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
                        {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5125, "count": n_index or 3, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
    }
    doc.update(extra or {})
    return _glb(doc, binary)


# ------------------------------------------------------------------------------------------------ samples
def test_samples_load_with_their_counts_and_defects() -> None:
    bunny = sample_mesh("bunny")
    assert (bunny.n_vertices, bunny.n_faces) == (1839, 3674)
    assert bunny.defects["watertight"] and bunny.defects["euler_characteristic"] == 2  # a closed genus-0 surface
    teapot = sample_mesh("teapot")
    # the teapot's 792 file vertices hold 263 duplicates along its patch seams; its lid and body are open
    assert teapot.defects["input_vertices"] == 792 and teapot.n_vertices == 792 - 263
    assert teapot.defects["boundary_edges"] > 0 and not teapot.defects["watertight"]
    for m in (bunny, teapot):
        assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0)
        assert np.allclose(np.linalg.norm(m.tangents[:, :3], axis=1), 1.0)
        assert np.abs(np.einsum("ij,ij->i", m.normals, m.tangents[:, :3])).max() < 1e-12


def test_subdivided_bunny_has_paper_scale_and_the_same_surface() -> None:
    big, small = sample_mesh("bunny-100k"), sample_mesh("bunny")
    # three midpoint subdivisions: V' = V + E each time, 1839 -> 7350 -> 29394 -> 117570; the surface is unchanged
    assert big.n_vertices == 117570 and big.n_faces == 64 * small.n_faces
    assert big.defects["surface_area"] == pytest.approx(small.defects["surface_area"], rel=1e-12)
    assert big.defects["watertight"]


def test_canonical_order_ignores_the_file_order() -> None:
    raw = read_obj_bytes((MESH_DIR / "bunny.obj").read_bytes())
    ref = build(raw)
    rng = np.random.default_rng(42)
    perm = rng.permutation(raw.positions.shape[0])
    inv = np.empty_like(perm)
    inv[perm] = np.arange(perm.size)
    faces = inv[raw.faces][rng.permutation(raw.faces.shape[0])]
    faces = np.roll(faces, 1, axis=1)  # a cyclic rotation of every face keeps its orientation
    other = build(RawMesh(raw.positions[perm], faces))
    assert np.array_equal(other.positions, ref.positions)
    assert np.array_equal(other.faces, ref.faces)
    assert np.allclose(other.normals, ref.normals, atol=1e-14)


def test_welding_merges_a_triangle_soup_back_into_the_mesh() -> None:
    ref = sample_mesh("bunny")
    soup = RawMesh(ref.positions[ref.faces].reshape(-1, 3), np.arange(3 * ref.n_faces).reshape(-1, 3))
    welded = build(soup)
    assert welded.defects["merged_vertices"] == 3 * ref.n_faces - ref.n_vertices
    assert np.array_equal(welded.positions, ref.positions) and np.array_equal(welded.faces, ref.faces)


def test_angle_weighted_normals_of_a_cube_do_not_depend_on_the_triangulation() -> None:
    box = trimesh.creation.box()
    for flip in (False, True):
        f = np.asarray(box.faces)
        if flip:  # a different diagonal on every face changes area weights but not corner angles
            quads = f.reshape(-1, 2, 3)
            f = np.concatenate([quads[:, 0, [0, 1, 2]], quads[:, 1]]).reshape(-1, 3)
            f = np.asarray(trimesh.Trimesh(box.vertices, f, process=False).faces)
        m = build(RawMesh(np.asarray(box.vertices, dtype=float), f), weighting="angle")
        # each corner sees three faces, each over a right angle: the normal is the diagonal (+-1, +-1, +-1)/sqrt 3
        assert np.allclose(m.normals, np.sign(m.positions) / np.sqrt(3.0), atol=1e-12)


def test_vertex_normals_lie_in_the_cone_of_their_face_normals() -> None:
    s = trimesh.creation.icosphere(subdivisions=4)
    for weighting in ("area", "angle"):
        m = build(RawMesh(np.asarray(s.vertices), np.asarray(s.faces)), weighting=weighting)  # type: ignore[arg-type]
        radial = m.positions / np.linalg.norm(m.positions, axis=1, keepdims=True)
        fn = np.cross(m.positions[m.faces[:, 1]] - m.positions[m.faces[:, 0]],
                      m.positions[m.faces[:, 2]] - m.positions[m.faces[:, 0]])
        fn /= np.linalg.norm(fn, axis=1, keepdims=True)
        # a normalised positive combination of unit vectors stays in any cone holding them all: the vertex normal
        # is no farther from the radial direction than the farthest face normal around the vertex
        cone = np.zeros(m.n_vertices)
        for k in range(3):
            np.maximum.at(cone, m.faces[:, k], np.arccos(np.clip(np.einsum("ij,ij->i", fn, radial[m.faces[:, k]]),
                                                                 -1, 1)))
        err = np.arccos(np.clip(np.einsum("ij,ij->i", m.normals, radial), -1, 1))
        assert np.all(err <= cone + 1e-12) and err.max() < 0.5 * cone.max()


# ----------------------------------------------------------------------------------------------- tangents
def _quad_with_uvs(mirror: bool) -> RawMesh:
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, -1]], dtype=float)  # in the y = 0 plane, normal +Y
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    if mirror:
        uv[:, 0] = 1.0 - uv[:, 0]
    return RawMesh(pos, f, corner_uvs=uv[f])


def test_uv_tangents_follow_u_and_their_sign_follows_the_uv_handedness() -> None:
    m = build(_quad_with_uvs(False))
    assert m.tangent_source == "uv" and np.allclose(m.normals, [0, 1, 0])
    assert np.allclose(m.tangents, [1, 0, 0, 1])  # u grows along +X; v along -Z = N x T: w = +1
    mm = build(_quad_with_uvs(True))
    assert np.allclose(mm.tangents, [-1, 0, 0, -1])  # u mirrored: T = -X and B = (0,0,-1) = -(N x T): w = -1


def test_gltf_tangents_keep_their_sign() -> None:
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 0, -1]], dtype="<f4")
    tan = np.array([[1, 0, 0, -1]] * 3, dtype="<f4")
    idx = np.array([0, 1, 2], dtype="<u4")
    binary = pos.tobytes() + tan.tobytes() + idx.tobytes()
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(binary)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 48},
                           {"buffer": 0, "byteOffset": 84, "byteLength": 12}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC4"},
                         {"bufferView": 2, "componentType": 5125, "count": 3, "type": "SCALAR"}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TANGENT": 1}, "indices": 2}]}]}
    m = build(read_gltf_bytes(_glb(doc, binary)))
    assert m.tangent_source == "file" and np.allclose(m.tangents, [1, 0, 0, -1])


def test_field_tangents_without_uvs() -> None:
    m = sample_mesh("bunny")
    assert m.tangent_source == "field" and np.all(m.tangents[:, 3] == 1.0)
    assert np.abs(m.tangents[:, 1]).max() < 1e-12  # normalize(+Y x N) is horizontal


# ------------------------------------------------------------------------------------------------- glTF
def test_glb_written_by_trimesh_decodes_to_the_obj_mesh() -> None:
    ref = sample_mesh("bunny")
    tm = trimesh.Trimesh(ref.positions, ref.faces, process=False)
    scene = trimesh.Scene()
    shift = np.eye(4)
    shift[:3, 3] = [1.0, 2.0, 3.0]
    scene.add_geometry(tm, transform=shift)  # a node transform: applied by the decoder
    m = build(decode(trimesh.exchange.gltf.export_glb(scene), "bunny.glb"))
    assert m.n_vertices == ref.n_vertices and m.n_faces == ref.n_faces
    # float32 in the file: positions agree to float32 rounding of coordinates up to ~10
    assert np.abs(m.positions - (ref.positions + [1.0, 2.0, 3.0])).max() < 1e-5
    assert np.abs(m.normals - ref.normals).max() < 1e-4


# --------------------------------------------------------------------------------------------- bad files
@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 1 1", "needs 3 coordinates"),  # truncated mid-record
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2", "at least 3 corners"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "index 4 out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0 out of range"),
        ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 1 has a non-finite coordinate"),
        ("v 0 0 0\nv 1 0 0\nv 0 1e999 0\nf 1 2 3\n", "non-finite"),
        ("v 0 0 0\nv 1 x 0\n", "cannot parse"),
        ("# nothing\n", "no triangles"),
    ],
)
def test_bad_obj_files_are_refused_with_a_clear_error(text: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        build(read_obj_bytes(text.encode(), name="bad.obj"))


def test_truncated_bunny_obj_is_refused() -> None:
    data = (MESH_DIR / "bunny.obj").read_bytes()
    cut = data[: data.index(b"\nf ", len(data) // 2) + 4]  # ends inside a face record: "f 1"
    with pytest.raises(InputError, match="at least 3 corners"):
        read_obj_bytes(cut, name="cut.obj")


def test_caps_are_checked_before_decoding() -> None:
    with pytest.raises(InputError, match="size cap"):
        read_obj_bytes(b"v 0 0 0\n" * 100, Caps(max_bytes=100))
    with pytest.raises(InputError, match="4 vertices declared"):
        read_obj_bytes(b"v 0 0 0\n" * 4, Caps(max_vertices=3))
    # 10^8 declared triangles: refused from the accessor count, although the buffer holds 3 indices
    with pytest.raises(InputError, match="100000000 triangles declared"):
        read_gltf_bytes(_triangle_glb(n_index=300_000_000))


def test_glb_with_a_lying_header_is_refused() -> None:
    good = _triangle_glb()
    assert build(read_gltf_bytes(good)).n_faces == 1
    for declared in (len(good) + 4, len(good) - 4, 1 << 31):
        with pytest.raises(InputError, match="declares"):
            read_gltf_bytes(good[:8] + struct.pack("<I", declared) + good[12:])
    with pytest.raises(InputError, match="past the end"):  # the JSON chunk claims more bytes than the file has
        bad = bytearray(good)
        bad[12:16] = struct.pack("<I", 1 << 20)
        read_gltf_bytes(bytes(bad))
    with pytest.raises(InputError, match="does not fit its buffer view"):  # an accessor beyond its bytes
        read_gltf_bytes(_triangle_glb(n_index=6))
    with pytest.raises(InputError, match="extensions"):
        read_gltf_bytes(_triangle_glb(extra={"extensionsRequired": ["KHR_draco_mesh_compression"]}))


def test_gltf_nan_positions_are_refused() -> None:
    pos = np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]])
    with pytest.raises(InputError, match="non-finite"):
        read_gltf_bytes(_triangle_glb(positions=pos))


def test_defects_report_non_manifold_degenerate_and_collapsed_faces() -> None:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [2, 0, 0], [0, 0, 0]], dtype=float)
    # three faces on edge (0, 1); a zero-area face (0, 1, 5) on a line; a face collapsing once 6 welds onto 0
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [0, 5, 1], [0, 6, 2]])
    m = build(RawMesh(v, f))
    d = m.defects
    assert d["collapsed_faces"] == 1 and d["merged_vertices"] == 1 and d["faces"] == 4
    assert d["non_manifold_edges"] == 1 and d["degenerate_faces"] == 1 and not d["watertight"]
    # indices beyond the vertices of an in-memory mesh
    with pytest.raises(InputError, match="index 9 out of range"):
        build(RawMesh(v, np.array([[0, 1, 9]])))


def test_load_mesh_reads_files_and_refuses_missing_ones(tmp_path) -> None:  # type: ignore[no-untyped-def]
    s = trimesh.creation.icosphere(subdivisions=1)
    p = tmp_path / "ico.obj"
    p.write_text(_obj_text(np.asarray(s.vertices), np.asarray(s.faces)))
    m = load_mesh(p)
    assert m.n_vertices == 42 and m.defects["watertight"]
    with pytest.raises(InputError, match="cannot read mesh"):
        load_mesh(tmp_path / "missing.obj")
