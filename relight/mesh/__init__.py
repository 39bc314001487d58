"""Triangle meshes for per-vertex precomputation (issue 13): decoding under caps, welding into one canonical vertex
order, normals, tangents and a defects report. ``relight.gl.mesh`` keeps the renderer's minimal OBJ reader."""

from relight.mesh.load import SAMPLES, build, decode, load_mesh, sample_file, sample_mesh, sniff
from relight.mesh.model import Caps, RawMesh, TriangleMesh, vertex_normals, weld

__all__ = ["SAMPLES", "Caps", "RawMesh", "TriangleMesh", "build", "decode", "load_mesh", "sample_file",
           "sample_mesh", "sniff", "vertex_normals", "weld"]
