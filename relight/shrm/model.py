"""The SHRM data types: one component per lobe (local maps ``Br_pq`` on a lat-long grid of the lobe's centre)
and a material's SHRM (components sharing one grid, with the report); eq. 12 per component (:meth:`view_map`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.conventions import (
    dirs_to_angles,
    latlong_dirs,
    ring_thetas,
)
from relight.errors import InputError
from relight.indexing import full_index
from relight.reports import ShrmReport
from relight.shrm.basis import (
    Y00,
    FloatArray,
    Structure,
    real_harmonics,
)
from relight.shrm.geometry import (
    unit_view,
)
from relight.shrm.rotation import local_to_global


# ------------------------------------------------------------------------------------------- data classes
@dataclass
class SHRMComponent:
    """One lobe's SHRM: local maps ``Br_pq`` on a lat-long grid indexed by the lobe's centre direction.

    ``maps[k]`` (rows, 2 rows, 3) holds the term ``terms[k] = (p, q)`` (module docstring: local frame, real basis).
    ``report`` carries orders, predicted errors and the reason for the structure
    (``relight.reports.ShrmComponentReport`` from ``create_shrm`` and ``read_shrm``; a plain mapping elsewhere).
    The global maps (eq. 8) are cached on first use: replace ``maps`` only before evaluating.
    """

    center: str
    structure: Structure
    F: int
    P: int
    terms: list[tuple[int, int]]
    maps: FloatArray
    lobe: dict[str, Any]
    report: Mapping[str, Any] = field(default_factory=dict)
    _global: FloatArray | None = field(default=None, repr=False)

    @property
    def height(self) -> int:
        return int(self.maps.shape[1])

    def global_maps(self) -> FloatArray:
        """``B~r_pq`` for all (P+1)^2 terms (eq. 8), cached; for P = 0 the local map itself."""
        if self._global is None:
            if self.P == 0:
                self._global = self.maps
            else:
                self._global = local_to_global(self.maps, self.terms, ring_thetas(self.height))
        return self._global

    def view_map(self, view: NDArray[np.floating]) -> FloatArray:
        """The eq. 12 map ``B~(alpha, beta)`` for the distant view V, on this component's grid, (rows, 2 rows, 3).

        Radial: ``Br_00 Y_00``. Azimuthal (q = 0 only): ``sum_p Br_p0(C) Yr_p0(theta_o)`` with ``cos theta_o =
        C . V`` at every pixel centre — eq. 6 evaluated exactly, which equals eq. 12. General: eq. 12 with the
        global maps of eq. 8.
        """
        v = unit_view(view)
        if self.structure == "radial":
            return np.asarray(self.maps[0] * Y00, dtype=np.float64)
        if self.structure == "azimuthal":
            dirs = latlong_dirs(self.height, 2 * self.height)
            theta_o = np.arccos(np.clip(dirs @ v, -1.0, 1.0))
            y = real_harmonics(self.P, theta_o, np.zeros_like(theta_o))
            cols = [full_index(p, 0) for p, _ in self.terms]
            return np.asarray(np.einsum("khwc,hwk->hwc", self.maps, y[..., cols]), dtype=np.float64)
        theta_v, phi_v = dirs_to_angles(v)
        y = real_harmonics(self.P, theta_v, phi_v)
        return np.asarray(np.tensordot(y, self.global_maps(), axes=(0, 0)), dtype=np.float64)


@dataclass
class SHRM:
    """A material's SHRM: a list of components (one per lobe) sharing one output grid, with the report."""

    components: list[SHRMComponent]
    brdf: dict[str, Any] | None = None
    report: Mapping[str, Any] = field(default_factory=dict)

    @property
    def typed_report(self) -> ShrmReport:
        """The report as :class:`relight.reports.ShrmReport` (what ``create_shrm`` and ``read_shrm`` give);
        InputError for an SHRM built by hand whose report is a plain mapping."""
        if not isinstance(self.report, ShrmReport):
            raise InputError("this SHRM's report is a plain mapping, not create_shrm's ShrmReport")
        return self.report

    @property
    def height(self) -> int:
        return self.components[0].height

    @property
    def width(self) -> int:
        return 2 * self.height

