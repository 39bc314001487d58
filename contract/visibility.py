"""Per-vertex visibility jobs over a stored mesh (``POST /visibility``, ``relight.visibility``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from relight.contract.base import Digest, Strict

VisibilityKind = Literal["visibility", "diffuse_transfer", "shadow_matrix"]


class VisibilityCreate(Strict):
    """Per-vertex SH visibility / diffuse transfer / shadow matrix of a mesh by ray casting (``relight.visibility``;
    order F means l <= F, (F+1)^2 coefficients)."""

    mesh: Digest = Field(description="a mesh id from POST /meshes")
    order: int = Field(3, ge=0, le=8, description="SH order F")
    rays: int = Field(1024, ge=16, le=65536, description="rays per vertex (spherical Fibonacci, randomly rotated)")
    kind: VisibilityKind = "visibility"
    bounces: int = Field(0, ge=0, le=8, description="interreflection bounces (diffuse_transfer only)")
    albedo: float = Field(0.8, ge=0.0, le=1.0, description="albedo of the interreflections")
    seed: int = Field(0, ge=0, lt=2**31, description="rotation of the direction set")
    block: int = Field(1024, ge=64, le=65536, description="vertices per block (the unit fanned out over workers)")

    @model_validator(mode="after")
    def _bounces(self) -> VisibilityCreate:
        if self.bounces and self.kind != "diffuse_transfer":
            raise ValueError(f"bounces ({self.bounces}) need kind 'diffuse_transfer', got {self.kind!r}")
        return self
