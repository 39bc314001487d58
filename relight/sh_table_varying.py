"""Spatially varying SH tables: one more table dimension ``c_i(v, q)`` for a BRDF parameter q varied over the surface
(Kautz, Sloan & Snyder 2002, §3 "To vary the BRDF's parameters across the object, we just need a higher-dimensional
c_i(v, q) table"; Fig. 4: the Ashikhmin–Shirley exponent or its anisotropy driven by noise, a 3-D texture).

The table holds Q ordinary tables (``relight.sh_table.build_table``) at parameter samples ``q_0 < ... < q_{Q-1}``;
a lookup interpolates linearly between the two neighbouring samples — in q (``spacing="linear"``) or in log q
(``"log"``, for exponents and roughnesses, whose lobes change by ratios). The BRDF is nonlinear in q, so the
interpolation has an error at mid samples (design notes §3.4 item 9): :func:`mid_sample_error` measures it against
direct projection at the mid points, which is how the spacing and Q are chosen (tests/relight/test_sh_table_varying.py:
log spacing of the AS exponent beats linear spacing at equal Q). Outside ``[q_0, q_{Q-1}]`` q is clamped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.brdf.spec import parse_frame_brdf
from relight.errors import InputError
from relight.sh_table import DEFAULT_ORDER, SHTable, build_table, project_views

FloatArray = NDArray[np.float64]
Spacing = Literal["linear", "log"]


@dataclass
class VaryingTable:
    """Q tables at ``values`` of the spec parameter ``parameter`` (module docstring)."""

    parameter: str
    values: FloatArray
    spacing: Spacing
    tables: list[SHTable]

    def _axis(self, q: ArrayLike) -> FloatArray:
        a = np.asarray(q, dtype=np.float64)
        return np.log(a) if self.spacing == "log" else a

    def positions(self, q: ArrayLike) -> FloatArray:
        """Fractional positions among the tables of parameter values q (...): ``k + t`` between samples k and k + 1
        (linear in q or log q), clamped to ``[0, Q - 1]`` (the GPU's per-vertex ``a_table``)."""
        qq = np.asarray(q, dtype=np.float64)
        if np.any(~np.isfinite(qq)) or (self.spacing == "log" and np.any(qq <= 0.0)):
            raise InputError(f"{self.parameter} values must be finite (and > 0 for log spacing)")
        grid = self._axis(self.values)
        return np.asarray(np.interp(self._axis(qq), grid, np.arange(grid.size)), dtype=np.float64)

    def lookup(self, views: ArrayLike, q: ArrayLike, *, exact_azimuth: bool = True) -> FloatArray:
        """Coefficients (N, n, C) at local views (N, 3) and parameter values (N,) (or one value)."""
        v = np.asarray(views, dtype=np.float64).reshape(-1, 3)
        pos = self.positions(np.broadcast_to(np.asarray(q, dtype=np.float64), v.shape[:1]))
        grid = self.values
        k0 = np.minimum(np.floor(pos).astype(np.intp), grid.size - 2)
        t = (pos - k0)[:, None, None]
        per = np.stack([tab.lookup(v, exact_azimuth=exact_azimuth) for tab in self.tables])  # (Q, N, n, C)
        rows = np.arange(v.shape[0])
        return np.asarray(per[k0, rows] * (1.0 - t) + per[k0 + 1, rows] * t, dtype=np.float64)


def _spec_at(spec: dict[str, Any], parameter: str, value: float) -> dict[str, Any]:
    return {**spec, parameter: float(value)}


def build_varying_table(spec: dict[str, Any], parameter: str, values: ArrayLike, *, spacing: Spacing = "log",
                        order: int = DEFAULT_ORDER, resolution: int = 64, layout: str = "parabolic") -> VaryingTable:
    """Tables of the BRDF ``spec`` (a dict, as ``parse_frame_brdf`` takes) with ``parameter`` set to each of
    ``values`` (at least 2, strictly increasing; > 0 for log spacing)."""
    vals = np.asarray(values, dtype=np.float64)
    if spacing not in ("linear", "log"):
        raise InputError(f"spacing must be 'linear' or 'log', got {spacing!r}")
    if vals.ndim != 1 or vals.size < 2 or not np.all(np.isfinite(vals)) or np.any(np.diff(vals) <= 0.0):
        raise InputError(f"{parameter} values must be at least 2 finite, strictly increasing numbers, got "
                         f"{np.asarray(values).tolist()}")
    if spacing == "log" and vals[0] <= 0.0:
        raise InputError(f"log spacing needs {parameter} values > 0, got {vals[0]}")
    if parameter not in parse_frame_brdf(spec).spec():
        raise InputError(f"{spec.get('kind')!r} has no parameter {parameter!r}")
    tables = [build_table(parse_frame_brdf(_spec_at(spec, parameter, q)), order=order, resolution=resolution,
                          layout=layout) for q in vals]
    return VaryingTable(parameter, vals, spacing, tables)


def mid_sample_error(table: VaryingTable, spec: dict[str, Any], views: ArrayLike) -> float:
    """RMS over the mid points between samples (geometric means for log spacing) and the given views of the
    interpolated coefficients minus direct projection at the mid value, relative to the RMS of the direct ones."""
    v = np.asarray(views, dtype=np.float64).reshape(-1, 3)
    lo, hi = table.values[:-1], table.values[1:]
    mids = np.sqrt(lo * hi) if table.spacing == "log" else 0.5 * (lo + hi)
    order = table.tables[0].order
    err = ref = 0.0
    for q in mids:
        direct = project_views(parse_frame_brdf(_spec_at(spec, table.parameter, q)), v, order)
        got = table.lookup(v, q)
        err += float(np.sum((got - direct) ** 2))
        ref += float(np.sum(direct**2))
    return float(np.sqrt(err / ref))
