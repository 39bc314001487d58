"""Radially symmetric (1-D) lobes: ``rho_hat = u(C . L)`` about a central direction C (seed 000 §3.1, §6.3).

* ``Phong(s)`` — the normalised Phong lobe reparameterised by the reflection vector,
  ``u(t) = (s + 1) / (2 pi) max(t, 0)^s`` (seed 000 §6.3); it reflects a uniform environment exactly.
* ``Lambert(albedo)`` — ``u(t) = albedo / pi max(t, 0)`` about the normal N (seed 000 §3.1); with albedo 1 the
  output is the irradiance over pi, E(N) / pi. (Phong with s = 1 is the same lobe, about R instead of N.)
* ``Lobe1D(table)`` — any lobe ``u(cos theta)`` given as a table of samples (linear interpolation, 0 outside the
  table's range) or, for local use only, a Python callable (not serialisable, so never cached).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.base import Center, FloatArray, RadialLobe
from relight.errors import InputError

#: Largest accepted Phong exponent (the stability suite covers up to 1e4; orders grow as sqrt(s)).
PHONG_MAX_EXPONENT = 1.0e5


def _finite(name: str, value: Any, lo: float, hi: float, *, lo_open: bool = False) -> float:
    return validate.in_range(name, value, lo, hi, lo_open=lo_open)


class Phong(RadialLobe):
    """Normalised Phong lobe about R: ``(s + 1)/(2 pi) max(t, 0)^s`` (seed 000 §6.3)."""

    kind: ClassVar[str] = "phong"

    def __init__(self, s: float) -> None:
        self.s = _finite("s", s, 0.0, PHONG_MAX_EXPONENT, lo_open=True)
        self.center: Center = "R"
        self.channels = 1

    def u(self, t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        with np.errstate(under="ignore"):
            val = (self.s + 1.0) / (2.0 * np.pi) * np.clip(t, 0.0, 1.0) ** self.s
        return np.asarray(val[..., None], dtype=np.float64)

    def params(self) -> dict[str, Any]:
        return {"s": self.s}


class Lambert(RadialLobe):
    """Lambertian lobe about N: ``albedo / pi max(t, 0)`` (seed 000 §3.1); albedo grey or RGB in [0, 1]."""

    kind: ClassVar[str] = "lambert"

    def __init__(self, albedo: float | Sequence[float] = 1.0) -> None:
        if isinstance(albedo, int | float):
            self.albedo: tuple[float, ...] = (_finite("albedo", albedo, 0.0, 1.0),)
        else:
            vals = list(albedo)
            if len(vals) != 3:
                raise InputError(f"albedo must be one number or three (RGB), got {len(vals)} values")
            self.albedo = tuple(_finite(f"albedo[{i}]", v, 0.0, 1.0) for i, v in enumerate(vals))
        self.center = "N"
        self.channels = len(self.albedo)

    def u(self, t: FloatArray) -> FloatArray:
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
        return np.asarray(t[..., None] * (np.array(self.albedo) / np.pi), dtype=np.float64)

    def params(self) -> dict[str, Any]:
        return {"albedo": self.albedo[0] if len(self.albedo) == 1 else list(self.albedo)}


class Lobe1D(RadialLobe):
    """A tabulated (or callable) lobe ``u(cos theta)`` about R or N (seed 000 §3.1, "any 1-D lobe").

    ``table``: samples ``(t_k, u_k)`` with strictly increasing ``t_k`` in [-1, 1] and finite ``u_k`` (grey) or
    ``u_k`` rows of 3 (RGB); linear interpolation, 0 outside ``[t_0, t_last]``. The spec form
    ``{"t": [...], "u": [...], "center": "R" | "N"}`` (``u`` of shape (n,) or (n, 3)) or ``{"table": rows}`` is
    accepted too.
    """

    kind: ClassVar[str] = "lobe1d"

    def __init__(
        self,
        table: Mapping[str, Any] | Sequence[Sequence[float]] | NDArray[np.floating] | Callable[[FloatArray], FloatArray]
        | None = None,
        *,
        func: Callable[[FloatArray], FloatArray] | None = None,
        center: str = "R",
    ) -> None:
        if isinstance(table, Mapping):
            table, center = _lobe1d_rows(table, center)
        elif callable(table):  # Lobe1D(callable)
            if func is not None:
                raise InputError("lobe1d needs exactly one of a table of (t, u) samples or a callable")
            table, func = None, table
        if (table is None) == (func is None):
            raise InputError("lobe1d needs exactly one of a table of (t, u) samples or a callable")
        if center not in ("R", "N"):
            raise InputError(f"lobe1d center must be 'R' or 'N', got {center!r}")
        self.center = "R" if center == "R" else "N"
        self.func = func
        self.t = np.zeros(0)
        self.values = np.zeros((0, 1))
        if table is not None:
            arr = np.asarray(table, dtype=np.float64)
            if arr.ndim != 2 or arr.shape[1] not in (2, 4) or arr.shape[0] < 2:
                raise InputError(f"lobe1d table must be rows of (t, u) or (t, r, g, b), got shape {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise InputError("lobe1d table contains non-finite values")
            t = arr[:, 0]
            if np.any(np.diff(t) <= 0) or t[0] < -1.0 or t[-1] > 1.0:
                raise InputError("lobe1d table t values must increase strictly within [-1, 1]")
            self.t, self.values = t, arr[:, 1:]
            self.channels = self.values.shape[1]
        else:
            self.channels = 1

    def u(self, t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        if self.func is not None:
            v = np.asarray(self.func(t), dtype=np.float64)
            return v[..., None] if v.shape == t.shape else v
        cols = [np.interp(t, self.t, self.values[:, c], left=0.0, right=0.0) for c in range(self.channels)]
        return np.asarray(np.stack(cols, axis=-1), dtype=np.float64)

    def params(self) -> dict[str, Any]:
        if self.func is not None:
            raise InputError("a lobe1d given as a Python callable cannot be serialised or cached; give a table")
        table = np.concatenate([self.t[:, None], self.values], axis=1)
        return {"center": self.center, "table": table.tolist()}


def _lobe1d_rows(spec: Mapping[str, Any], center: str) -> tuple[FloatArray, str]:
    """Rows ``(t, u...)`` from ``{"t", "u"}`` or ``{"table"}`` (optionally ``"center"``)."""
    valid = {"t", "u", "table", "center"}
    if set(spec) - valid:
        raise InputError(f"lobe1d: unknown key {sorted(set(spec) - valid)[0]!r}; valid keys are {sorted(valid)}")
    center = str(spec.get("center", center))
    if "table" in spec:
        if "t" in spec or "u" in spec:
            raise InputError("lobe1d: give either table or t and u, not both")
        try:
            return np.asarray(spec["table"], dtype=np.float64), center
        except (TypeError, ValueError):
            raise InputError("lobe1d table must be rows of numbers (t, u) or (t, r, g, b)") from None
    if "t" not in spec or "u" not in spec:
        raise InputError("lobe1d: needs both t and u (or a table)")
    try:
        t = np.asarray(spec["t"], dtype=np.float64)
        u = np.asarray(spec["u"], dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("lobe1d: t and u must be arrays of numbers") from None
    if t.ndim != 1 or u.ndim not in (1, 2) or u.shape[0] != t.size:
        raise InputError(f"lobe1d: t must be 1-D and u have one row per t, got shapes {t.shape} and {u.shape}")
    return np.column_stack([t, u]), center
