"""Measured isotropic BRDFs: the MERL ``.binary`` format and a documented ``.npz`` table format.

MERL (Matusik, Pfister, Brand & McMillan 2003, "A data-driven reflectance model"; reader ``BRDFRead.cpp``)
---------------------------------------------------------------------------------------------------------
A file is three little-endian int32 dims that must equal ``(90, 90, 180)``, then ``3 * 90 * 90 * 180`` little-endian
float64 values: all red, then all green, then all blue, each ``[theta_h][theta_d][phi_d]`` with phi_d fastest;
``12 + 3 * 1,458,000 * 8 = 34,992,012`` bytes in all, checked before anything else is read (as ``docs/facts.md``
says). Stored values times ``1/1500``, ``1.15/1500``, ``1.66/1500`` (R, G, B;
``BRDFRead.cpp`` RED_SCALE, GREEN_SCALE, BLUE_SCALE) give f_r in 1/sr; negative values mark
missing samples (below the horizon) and read as 0. The angles are Rusinkiewicz's (1998) half/difference angles:
``theta_h`` = angle(n, h), ``theta_d`` = angle(wi, h), ``phi_d`` = azimuth of wi about h measured from the plane of
n and h, folded to [0, pi) by reciprocity. ``BRDFRead.cpp`` indexes::

    i_h = floor(90 sqrt(theta_h / (pi/2)))     (clamped to 0..89; the square-root mapping)
    i_d = floor(90 theta_d / (pi/2))           (clamped to 0..89)
    i_p = floor(180 phi_d / pi)                (clamped to 0..179)

so sample (i_h, i_d, i_p) sits at ``theta_h = (i_h/90)^2 pi/2``, ``theta_d = i_d pi/180``, ``phi_d = i_p pi/180``
(the lower edges of the bins). :class:`MERLBRDF` offers ``lookup="merl"`` (exactly that floor indexing, bit-for-bit
the reference reader) and ``lookup="trilinear"`` (default: linear interpolation between those sample positions,
clamped at the grid ends in theta and periodic in phi_d with period pi).

``.npz`` tabulated format (:class:`TabulatedBRDF`), for any measured isotropic BRDF
------------------------------------------------------------------------------------
``numpy.savez`` archive with exactly these arrays:

* ``theta_h`` (n_th,), ``theta_d`` (n_td,): strictly increasing, within [0, pi/2] (radians);
* ``phi_d`` (n_pd,): strictly increasing, within [0, pi) (reciprocity folds phi_d to [0, pi));
* ``values`` (n_th, n_td, n_pd, channels), channels 1 or 3: f_r (no cosine), finite and >= 0;
* ``units``: the string ``"1/sr"``; ``description``: free text (source, material, licence).

Lookup is trilinear on the grids (clamped in theta, periodic in phi_d with period pi), in the same half/difference
angles as MERL. No pickled objects are read (``allow_pickle=False``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight.brdf.base import FloatArray, IsotropicBRDF, dot
from relight.errors import InputError

#: MERL table resolution (BRDFRead.cpp: BRDF_SAMPLING_RES_THETA_H, _THETA_D, _PHI_D / 2).
MERL_DIMS = (90, 90, 180)
#: Per-channel factors from stored values to f_r (BRDFRead.cpp RED_SCALE, GREEN_SCALE, BLUE_SCALE).
MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
#: Exact size of a MERL file: 3 int32 + 3 * 90 * 90 * 180 float64.
MERL_FILE_BYTES = 3 * 4 + 3 * 90 * 90 * 180 * 8  # = 34,992,012

HALF_PI = 0.5 * np.pi


def half_diff_angles(wi: ArrayLike, wo: ArrayLike, n: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Rusinkiewicz (1998) ``(theta_h, theta_d, phi_d)`` of unit ``wi``, ``wo`` about ``n`` (..., 3), frame-free.

    Notes
    -----
    MERL's ``std_coords_to_half_diff_coords`` rotates wi by ``-phi_h`` about n and by ``-theta_h`` about the
    binormal, which maps h to +z. The images of the x and y axes are ``e1 = (cos(theta_h) h - n) / sin(theta_h)``
    and ``e2 = (n x h) / sin(theta_h)``, so ``phi_d = atan2(wi.e2, wi.e1)``, returned folded to [0, pi) (reciprocity,
    as ``phi_diff_index``). At theta_h = 0 any tangent is used (phi_d is then arbitrary in MERL too).
    """
    a, b, nn = np.broadcast_arrays(
        np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64), np.asarray(n, dtype=np.float64)
    )
    h = a + b
    hn = np.linalg.norm(h, axis=-1, keepdims=True)
    h = h / np.where(hn > 0.0, hn, 1.0)
    cos_h = np.clip(dot(nn, h), -1.0, 1.0)
    theta_h = np.arccos(cos_h)
    theta_d = np.arccos(np.clip(dot(a, h), -1.0, 1.0))
    n_x_h = np.cross(nn, h)
    sin_h = np.linalg.norm(n_x_h, axis=-1)
    small = sin_h < 1e-12
    # fallback tangent frame about n where h ~ n: any unit vector orthogonal to n
    helper = np.where(np.abs(nn[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    t = np.cross(helper, nn)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    safe = np.where(small, 1.0, sin_h)[..., None]
    e1 = np.where(small[..., None], t, (cos_h[..., None] * h - nn) / safe)
    e2 = np.where(small[..., None], np.cross(nn, t), n_x_h / safe)
    phi_d = np.arctan2(dot(a, e2), dot(a, e1))
    phi_d = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)
    phi_d = np.where(phi_d >= np.pi, phi_d - np.pi, phi_d)
    return theta_h, theta_d, phi_d


def half_diff_to_dirs(
    theta_h: ArrayLike, theta_d: ArrayLike, phi_d: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`half_diff_angles` in the frame n = +z (phi_h = 0): ``(wi, wo)`` of shape (..., 3).

    ``wi = R_y(theta_h) d`` with ``d = (sin td cos pd, sin td sin pd, cos td)``; ``wo = 2 (wi.h) h - wi``.
    """
    th, td, pd = (np.asarray(x, dtype=np.float64) for x in np.broadcast_arrays(theta_h, theta_d, phi_d))
    dx, dy, dz = np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)
    ch, sh = np.cos(th), np.sin(th)
    wi = np.stack([dx * ch + dz * sh, dy, -dx * sh + dz * ch], axis=-1)
    h = np.stack([sh, np.zeros_like(sh), ch], axis=-1)
    wo = 2.0 * dot(wi, h)[..., None] * h - wi
    return wi, wo


def merl_sample_angles() -> tuple[FloatArray, FloatArray, FloatArray]:
    """Angles of the MERL samples (lower bin edges of ``BRDFRead.cpp``'s indexing): theta_h, theta_d, phi_d grids."""
    ih = np.arange(MERL_DIMS[0])
    theta_h = (ih / MERL_DIMS[0]) ** 2 * HALF_PI
    theta_d = np.arange(MERL_DIMS[1]) * HALF_PI / MERL_DIMS[1]
    phi_d = np.arange(MERL_DIMS[2]) * np.pi / MERL_DIMS[2]
    return theta_h, theta_d, phi_d


def merl_indices(theta_h: FloatArray, theta_d: FloatArray, phi_d: FloatArray) -> tuple[NDArray[np.intp], ...]:
    """``BRDFRead.cpp``'s ``theta_half_index``, ``theta_diff_index``, ``phi_diff_index``, vectorised."""
    nh, nd, npd = MERL_DIMS
    th_deg = np.where(theta_h <= 0.0, 0.0, theta_h / HALF_PI * nh)
    ih = np.clip(np.sqrt(th_deg * nh).astype(np.intp), 0, nh - 1)
    idd = np.clip((theta_d / HALF_PI * nd).astype(np.intp), 0, nd - 1)
    pd = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)
    ip = np.clip((pd / np.pi * npd).astype(np.intp), 0, npd - 1)
    return ih, idd, ip


def _interp_axis(
    x: FloatArray, grid: FloatArray, periodic: float | None
) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]:
    """Indices (i0, i1) and weight w of linear interpolation of x on a strictly increasing grid.

    Clamped to the ends unless ``periodic`` (a period): then x is wrapped and the last cell joins the first.
    """
    n = grid.size
    if periodic is not None:
        xw = np.mod(x - grid[0], periodic) + grid[0]
        ext = np.append(grid, grid[0] + periodic)
        i0 = np.clip(np.searchsorted(ext, xw, side="right") - 1, 0, n - 1)
        lo, hi = ext[i0], ext[i0 + 1]
        w = np.clip((xw - lo) / (hi - lo), 0.0, 1.0)
        return i0, (i0 + 1) % n, w
    if n == 1:
        zero = np.zeros(np.shape(x), dtype=np.intp)
        return zero, zero, np.zeros(np.shape(x))
    xc = np.clip(x, grid[0], grid[-1])
    i0 = np.clip(np.searchsorted(grid, xc, side="right") - 1, 0, n - 2)
    w = (xc - grid[i0]) / (grid[i0 + 1] - grid[i0])
    return i0, i0 + 1, np.clip(w, 0.0, 1.0)


def trilinear(
    table: FloatArray, grids: tuple[FloatArray, FloatArray, FloatArray], th: FloatArray, td: FloatArray, pd: FloatArray
) -> FloatArray:
    """Trilinear lookup in ``table[i_h, i_d, i_p, c]`` (clamped in theta, periodic with period pi in phi_d)."""
    a0, a1, wa = _interp_axis(th, grids[0], None)
    b0, b1, wb = _interp_axis(td, grids[1], None)
    c0, c1, wc = _interp_axis(pd, grids[2], np.pi)
    out = np.zeros(th.shape + (table.shape[-1],))
    for ia, fa in ((a0, 1.0 - wa), (a1, wa)):
        for ib, fb in ((b0, 1.0 - wb), (b1, wb)):
            for ic, fc in ((c0, 1.0 - wc), (c1, wc)):
                out += (fa * fb * fc)[..., None] * table[ia, ib, ic]
    return out


class MERLBRDF(IsotropicBRDF):
    """A MERL ``.binary`` BRDF (module docstring), RGB, f_r in 1/sr.

    ``MERLBRDF(path, lookup="trilinear" | "merl")``: trilinear interpolation between the sample angles, or the
    exact floor indexing of MERL's ``BRDFRead.cpp``. ``f(wi, wo, n)`` converts to half/difference angles
    (:func:`half_diff_angles`). The file is validated strictly (size, dims, finite values) before use.
    """

    kind: ClassVar[str] = "merl"
    channels: int = 3

    def __init__(self, path: str | os.PathLike[str], lookup: str = "trilinear") -> None:
        if lookup not in ("trilinear", "merl"):
            raise InputError(f"merl: lookup must be 'trilinear' or 'merl', got {lookup!r}")
        self.path = os.fspath(path)
        self.lookup = lookup
        self.table = read_merl(self.path)  # (90, 90, 180, 3) f_r, missing samples as 0
        self.grids = merl_sample_angles()

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        th, td, pd = half_diff_angles(wi, wo, n)
        if self.lookup == "merl":
            ih, idd, ip = merl_indices(th, td, pd)
            return np.asarray(self.table[ih, idd, ip], dtype=np.float64)
        return trilinear(self.table, self.grids, th, td, pd)

    def to_tabulated(self, description: str = "") -> TabulatedBRDF:
        """The same samples as a :class:`TabulatedBRDF` (non-uniform theta_h grid)."""
        return TabulatedBRDF(*self.grids, self.table, description=description or f"MERL file {self.path}")

    def params(self) -> dict[str, Any]:
        return {"lookup": self.lookup, "path": self.path}


def read_merl(path: str | os.PathLike[str]) -> FloatArray:
    """Read and validate a MERL ``.binary`` file: f_r table (90, 90, 180, 3), missing (negative) samples as 0."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"merl: no such file: {os.fspath(path)!r}")
    size = p.stat().st_size
    if size != MERL_FILE_BYTES:
        raise InputError(
            f"merl: {p.name} has {size} bytes; a MERL .binary file has exactly {MERL_FILE_BYTES} "
            "(3 int32 dims 90 90 180, then 3*90*90*180 float64)"
        )
    with p.open("rb") as fh:
        dims = np.frombuffer(fh.read(12), dtype="<i4")
        if tuple(int(d) for d in dims) != MERL_DIMS:
            raise InputError(f"merl: {p.name} has dims {tuple(int(d) for d in dims)}; expected {MERL_DIMS}")
        raw = np.frombuffer(fh.read(), dtype="<f8")
    if not np.all(np.isfinite(raw)):
        raise InputError(f"merl: {p.name} contains non-finite values")
    vals = raw.reshape((3,) + MERL_DIMS).transpose(1, 2, 3, 0) * MERL_SCALE
    return np.asarray(np.where(vals < 0.0, 0.0, vals), dtype=np.float64)


def write_merl(path: str | os.PathLike[str], values: ArrayLike) -> None:
    """Write f_r samples ``values`` (90, 90, 180, 3) at :func:`merl_sample_angles` as a MERL ``.binary`` file.

    Values are divided by :data:`MERL_SCALE`; negative values (missing samples) are written as -1 (below the
    horizon in MERL's data). Inverse of :func:`read_merl`.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.shape != MERL_DIMS + (3,):
        raise InputError(f"merl: values must have shape {MERL_DIMS + (3,)}, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError("merl: values must be finite")
    stored = np.where(v < 0.0, -1.0, v / MERL_SCALE).transpose(3, 0, 1, 2)
    with Path(path).open("wb") as fh:
        fh.write(np.asarray(MERL_DIMS, dtype="<i4").tobytes())
        fh.write(np.ascontiguousarray(stored, dtype="<f8").tobytes())


def tabulate_merl(brdf: IsotropicBRDF) -> FloatArray:
    """Sample an isotropic BRDF at the MERL sample angles: (90, 90, 180, 3) f_r, -1 where wi or wo is below n.

    Grey BRDFs are replicated to RGB. Used to make synthetic MERL files (tests, conversions).
    """
    grids = merl_sample_angles()
    th, td, pd = np.meshgrid(*grids, indexing="ij")
    wi, wo = half_diff_to_dirs(th, td, pd)
    n = np.array([0.0, 0.0, 1.0])
    val = np.asarray(brdf.f(wi, wo, np.broadcast_to(n, wi.shape)), dtype=np.float64)
    val = np.broadcast_to(val, th.shape + (3,))
    below = (wi[..., 2] <= 0.0) | (wo[..., 2] <= 0.0)
    return np.where(below[..., None], -1.0, val)


def _grid(name: str, arr: ArrayLike, hi: float, hi_open: bool) -> FloatArray:
    a = np.asarray(arr, dtype=np.float64)
    if a.ndim != 1 or a.size < 1:
        raise InputError(f"measured: {name} must be a non-empty 1-D array, got shape {a.shape}")
    if not np.all(np.isfinite(a)) or a[0] < 0.0 or a[-1] > hi or (hi_open and a[-1] >= hi):
        raise InputError(f"measured: {name} must lie in [0, {'pi' if hi == np.pi else 'pi/2'}{')' if hi_open else ']'}")
    if np.any(np.diff(a) <= 0.0):
        raise InputError(f"measured: {name} must be strictly increasing")
    return a


class TabulatedBRDF(IsotropicBRDF):
    """A tabulated isotropic BRDF on a (theta_h, theta_d, phi_d) grid, the ``.npz`` format of the module docstring.

    Trilinear lookup (clamped in theta, periodic in phi_d with period pi). ``params()`` needs the file it was
    loaded from or saved to (``{"path": ...}``); an unsaved table raises ``InputError`` (not serialisable).
    """

    kind: ClassVar[str] = "measured"

    def __init__(
        self,
        theta_h: ArrayLike,
        theta_d: ArrayLike,
        phi_d: ArrayLike,
        values: ArrayLike,
        *,
        units: str = "1/sr",
        description: str = "",
    ) -> None:
        th = _grid("theta_h", theta_h, HALF_PI, False)
        td = _grid("theta_d", theta_d, HALF_PI, False)
        pd = _grid("phi_d", phi_d, np.pi, True)
        v = np.asarray(values, dtype=np.float64)
        if v.ndim != 4 or v.shape[:3] != (th.size, td.size, pd.size) or v.shape[3] not in (1, 3):
            raise InputError(
                f"measured: values must have shape ({th.size}, {td.size}, {pd.size}, 1|3), got {v.shape}"
            )
        if not np.all(np.isfinite(v)) or np.any(v < 0.0):
            raise InputError("measured: values must be finite and >= 0 (f_r in 1/sr)")
        if units != "1/sr":
            raise InputError(f"measured: units must be '1/sr' (values are f_r), got {units!r}")
        self.grids = (th, td, pd)
        self.values = v
        self.units = units
        self.description = str(description)
        self.channels = v.shape[3]
        self.path: str | None = None

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        th, td, pd = half_diff_angles(wi, wo, n)
        return trilinear(self.values, self.grids, th, td, pd)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the ``.npz`` file (module docstring); afterwards ``params()`` refers to it."""
        with Path(path).open("wb") as fh:
            np.savez(
                fh,
                theta_h=self.grids[0],
                theta_d=self.grids[1],
                phi_d=self.grids[2],
                values=self.values,
                units=np.array(self.units),
                description=np.array(self.description),
            )
        self.path = os.fspath(path)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> TabulatedBRDF:
        """Read and validate a ``.npz`` table (module docstring)."""
        p = Path(path)
        if not p.is_file():
            raise InputError(f"measured: no such file: {os.fspath(path)!r}")
        try:
            with np.load(p, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise InputError(f"measured: {p.name} is not a valid .npz archive ({exc})") from None
        need = {"theta_h", "theta_d", "phi_d", "values", "units", "description"}
        missing = need - set(data)
        extra = set(data) - need
        if missing or extra:
            raise InputError(
                f"measured: {p.name} must hold exactly {sorted(need)}; "
                f"missing {sorted(missing)}, unexpected {sorted(extra)}"
            )
        for key in ("units", "description"):
            if data[key].dtype.kind != "U" or data[key].ndim != 0:
                raise InputError(f"measured: {p.name}: {key} must be a string")
        out = cls(
            data["theta_h"],
            data["theta_d"],
            data["phi_d"],
            data["values"],
            units=str(data["units"]),
            description=str(data["description"]),
        )
        out.path = os.fspath(path)
        return out

    def params(self) -> dict[str, Any]:
        if self.path is None:
            raise InputError("measured: this table has no file; call save(path) before serialising or caching it")
        return {"path": self.path}
