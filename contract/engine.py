"""Engine-ready exports (issue 17): the ``ibl`` and ``dfg`` job kinds' requests and the sun step's spelling."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from relight.contract.base import Digest, Strict

#: ``--sun``: extract, keep, or clamp=V with V a positive number (``relight.sun.parse_sun`` is the authority).
SUN_PATTERN = r"^(extract|keep|clamp=([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?)$"


class IblCreate(Strict):
    """An engine-ready export of an environment map (``relight export`` through the service, ``relight.engine_export``):
    ``ktx2`` the target engine's prefiltered GGX cube chain, ``sh`` its SH9 in every engine convention, ``gltf`` a
    GLB with the ``gltf`` target's chain as EXT_lights_image_based and KHR_lights_environment (``--format gltf``)."""

    envmap: Digest
    target: Literal["three", "filament", "gltf", "babylon"] = Field(
        "three", description="engine whose roughness-to-mip mapping and split-sum lobe the chain follows")
    format: Literal["ktx2", "sh", "gltf"] = "ktx2"
    size: int = Field(256, ge=1, le=1024, description="face size of level 0, a power of two (service limit 1024)")
    levels: int | None = Field(None, ge=1, le=11, description="mip levels (default: down to 1 x 1)")
    epsilon: float = Field(2.5e-5, ge=1e-8, lt=1.0, description="uncaptured lobe energy per level (seed 000 §5.1)")
    sun: str = Field("keep", max_length=40, pattern=SUN_PATTERN,
                     description="extract (directional light + residual), clamp=V or keep")
    pixel_format: Literal["rgba16f", "b10g11r11", "e5b9g9r9"] = Field(
        "rgba16f", description="KTX2 texels: RGBA16F or a 4-byte packed unsigned float (relight.packed_float)")
    brdf: str | None = Field(None, min_length=1, max_length=400, description=(
        "another lobe family per level (relight export --brdf SPEC): the BRDF's lobe at view = normal; a ggx-ld or "
        "gltf-pbr term without roughness takes each level's (docs/conventions.md); default the target's split-sum "
        "GGX lobe; ignored by format=sh"))

    @model_validator(mode="after")
    def _power_of_two(self) -> IblCreate:
        if self.format == "gltf" and self.target != "gltf":
            raise ValueError(f"format gltf (EXT_lights_image_based) needs target gltf, got {self.target!r}")
        if self.format == "gltf" and self.pixel_format != "rgba16f":
            raise ValueError("format gltf writes RGBD PNGs and an RGBA16F KTX2: pixel_format must be rgba16f")
        if self.size & (self.size - 1):
            raise ValueError(f"size must be a power of two, got {self.size}")
        if self.levels is not None and self.levels > self.size.bit_length():
            raise ValueError(f"levels ({self.levels}) must be at most {self.size.bit_length()} for size {self.size}")
        return self


class DfgCreate(Strict):
    """The split-sum DFG table (``relight dfg``, ``relight.dfg``): the same file as the CLI writes."""

    size: int = Field(128, ge=2, le=1024, description="table size N (N x N; relight.dfg.MAX_SIZE)")
    multiscatter: bool = Field(False, description="Filament's (B, A + B) layout instead of (A, B)")
    format: Literal["exr", "png", "ktx2"] = Field(
        "exr", description="exr (float32), png (16-bit linear) or ktx2 (2-D RGBA16F): relight dfg --out FILE.<format>")
