"""The stored resources' models: environment maps, meshes and BRDFs (``POST``/``GET /envmaps``, ``/meshes``,
``/brdfs``), and :data:`BrdfRef`, how a request names a BRDF.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from pydantic import Field

from relight.contract.base import Digest, Public
from relight.contract.brdfs import BrdfSpec


# -------------------------------------------------------------------------------------------------- envmaps
class EnvmapPublic(Public):
    id: Digest = Field(description="SHA-256 of the uploaded bytes")
    name: str | None = None
    format: str = Field(description="exr, hdr, png or jpeg")
    layout: str = Field(description="latlong, or the cube-map layout that was resampled")
    width: int = Field(description="width of the stored map (what jobs use)")
    height: int
    source_width: int | None = Field(None, description="width of the uploaded file; larger than width when a "
                                     "lat-long EXR above the server's max_pixels was streamed and downsampled")
    source_height: int | None = None
    stored_sha256: str | None = Field(None, description="blob of the stored map: the upload itself, or its "
                                      "area-exact downsample (float32 EXR) when it was streamed")
    bytes: int
    min: list[float] = Field(description="per-channel minimum (after clamping negatives)")
    max: list[float]
    mean: list[float]
    negatives_clamped: int = Field(description="channel values below 0 that were set to 0")
    min_negative: float
    non_finite: int = Field(0, description="NaN/Inf values (always 0: such maps are rejected)")
    spectrum_lmax: int
    sh_power_spectrum: list[float] = Field(description="luminance energy per band l = 0..spectrum_lmax")
    total_energy: float = Field(description="integral of luminance^2 over the sphere")
    created_at: datetime
    links: dict[str, str] = {}


class EnvmapList(Public):
    items: list[EnvmapPublic]


# -------------------------------------------------------------------------------------------------- meshes
class MeshPublic(Public):
    """A mesh welded into relight's canonical vertex order (``docs/conventions.md``, "Meshes")."""

    id: Digest = Field(description="SHA-256 of the uploaded bytes")
    name: str | None = None
    format: str | None = Field(None, description="obj, gltf or glb")
    bytes: int
    vertices: int = Field(description="welded vertices, in the order every per-vertex result uses")
    faces: int
    bounds: dict[str, list[float]]
    bounding_radius: float
    surface_area: float
    watertight: bool
    tangent_source: str = Field(description="file (glTF TANGENT), uv (texture coordinates) or field")
    normal_weighting: str
    defects: dict[str, Any] = Field(description="boundary / non-manifold / inconsistently oriented edges, "
                                    "degenerate and collapsed faces, welded and unreferenced vertices (reported, "
                                    "not refused)")
    geometry: dict[str, Any] = Field(description="geometry.bin: sha256, byte size and the offset, dtype and shape "
                                     "of positions, normals, tangents and indices")
    created_at: datetime
    links: dict[str, str] = {}


class MeshList(Public):
    items: list[MeshPublic]



# -------------------------------------------------------------------------------------------------- brdfs
class BrdfPublic(Public):
    id: Digest = Field(description="SHA-256 of the canonical spec (or of the measured file)")
    kind: str
    spec: dict[str, Any] = Field(description="canonical parameters, as accepted by POST /brdfs")
    radially_symmetric: bool
    center: str | None = Field(None, description="R (reflection vector), N (normal) or T (tangent)")
    measured: bool = False
    created_at: datetime
    links: dict[str, str] = {}


BrdfRef = Annotated[
    Digest | BrdfSpec | str,
    Field(description="a BRDF id from POST /brdfs, a spec object, or a spec string such as 'phong:s=32'"),
]
