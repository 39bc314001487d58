"""Seed 002's job kinds: Gaussian lobes fitted to a BRDF and the Gaussian-prefiltered chain of a map.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from relight.contract.base import Digest, Strict
from relight.contract.resources import BrdfRef


class GaussianFitCreate(Strict):
    """Gaussian lobes fitted to an isotropic BRDF at view elevations (seed 002 §4, ``relight.sgfit``)."""

    brdf: BrdfRef
    lobes: int = Field(3, ge=1, le=8, description="Gaussians K per elevation")
    max_lobes: int | None = Field(None, ge=1, le=8, description="add lobes up to this many where the error exceeds "
                                  "5 % (default: lobes + 2, at most 8; equal to lobes: the paper's fixed K)")
    elevations: int = Field(15, ge=2, le=64, description="view elevations N, equally spaced from 0")
    theta_max_deg: float = Field(87.0, gt=0.0, lt=90.0, description="largest elevation in degrees")

    @model_validator(mode="after")
    def _max_lobes(self) -> GaussianFitCreate:
        if self.max_lobes is not None and self.max_lobes < self.lobes:
            raise ValueError(f"max_lobes ({self.max_lobes}) must be >= lobes ({self.lobes})")
        return self


class GaussianChainCreate(Strict):
    """The Gaussian-prefiltered chain of an environment map (seed 002 §5.1, ``relight.gaussian_chain``)."""

    envmap: Digest
    ratio: Literal["2", "sqrt2"] = Field("2", description="sigma ratio between levels")
    levels: int | None = Field(None, ge=1, le=32, description="number of levels (default: up to 90 degrees)")
    epsilon: float = Field(0.01, gt=0.0, lt=1.0,
                           description="tolerance for every level's SH order (relight chain's default)")
    sigma0: float | None = Field(None, gt=0.0, le=math.pi, description="sharpest sigma in radians (default pi / H)")
    uniform_size: bool = Field(False, description="every level at the input's size (one GPU texture array)")
