"""Per-view SH tables of the BRDF product function (Kautz, Sloan & Snyder 2002, §3 "Calculating BRDF Coefficients").

For every local view v of the upper hemisphere, ``c_i(v) = int Yr_i(s) f*(s, v) ds`` with ``f* = f(s, v) max(0,
s_z)`` (the BRDF's ``fcos_local``, ``relight.brdf.frame``), for ``i`` over relight's real basis to order F (l <= F,
(F + 1)^2 coefficients; the paper's "fifth order projection", n = 25, is F = 4), in the local frame x = tangent,
y = bitangent, z = normal. The table is stored over a 2-D map of views (``relight.view_maps``: parabolic as in the
paper, or hemi-octahedral); shading is then ``Q = sum_i L_i c_i(v)`` (eq. 1) with the lighting in the same frame
(``relight.sh_render``).

Quadrature adapted to the lobe (design notes §3.4 item 7; the paper used 1000 random samples per integral): a
polar grid about the mirror direction ``r = (-v_x, -v_y, v_z)`` (about the normal for lobes centred on it, with
the horizon as a panel edge; a sum is integrated term by term), composite Gauss–Legendre in the angle from r on
panels ``[0, w/2], [w/2, w], [w, 2w], ...`` up to pi (w the BRDF's ``lobe_width``), ``N_GL`` nodes per panel, times
a ``N_PHI``-point trapezoid rule in the azimuth about r. The same nodes ``x_k`` about +z serve every view: with
``R_v`` the rotation taking +z to r (``R_z(phi_r) R_y(theta_r)``), ``c(v) = M(R_v) g(v)`` where ``g_j(v) = sum_k
w_k Yr_j(x_k) f*(R_v x_k, v)`` (one matrix product for all views) and ``M`` the real band rotation
(``relight.sh_rotation``). ``refine=2`` doubles both node counts (the "2x finer rule" the tests and
``bench/shtable.py`` compare against).

Isotropic BRDFs (``brdf.isotropic``) need only views in the x-z plane: a 1-D table over ``theta_v`` (``R`` samples
from 0 to the rim), expanded to any azimuth exactly by a rotation about z, ``c(theta, phi) = M(R_z(phi)) c(theta,
0)`` (2 x 2 rotations of each (m, -m) pair). Energy: ``sqrt(4 pi) c_0(v) = int f* ds`` is the directional albedo.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.brdf.frame import FrameBRDF, FrameSum, as_frame_brdf, mirror_local
from relight.errors import InputError
from relight.sh_rotation import band_rotations, rotate_coefficients, rotation_about_z
from relight.shrm import real_harmonics
from relight.view_maps import RIM_Z, Layout, bilinear, check_layout, clamp_to_hemisphere, map_views, view_to_texel

FloatArray = NDArray[np.float64]

#: Gauss–Legendre nodes per angular panel and trapezoid nodes in the azimuth about r (refine=1); with these the
#: tables agree with refine=2 to ~1e-4 of the largest coefficient for the models tested (bench/shtable.py).
N_GL = 8
N_PHI = 48
#: Default order F (the paper's n = 25) and map.
DEFAULT_ORDER = 4
DEFAULT_RESOLUTION = 128
#: Default map, chosen by measured interpolation error at equal bytes (R x R texels either way): the parabolic
#: map's RMS error against direct projection at 400 random views is 0.55-0.9x the hemi-octahedral one's at R = 32
#: and 64 for AS (12, 4), AS (48, 16) and GGX (0.2, 0.5) — it spends 2x the linear resolution at the rim, where
#: tables vary fastest, which outweighs the 21.5 % of texels outside the disk (tests/relight/test_sh_table.py).
DEFAULT_LAYOUT: Layout = "parabolic"
#: Largest order accepted (n = 225, the paper's offline Fig. 6 column).
MAX_ORDER = 14
#: Views evaluated per block (bounds memory at ~views x nodes x channels doubles).
VIEW_CHUNK = 32


def lobe_quadrature(width: float, refine: int = 1, *, horizon: bool = False) -> tuple[FloatArray, FloatArray]:
    """Nodes (K, 3) about +z and weights (K,) (module docstring); weights sum to 4 pi. ``horizon``: add pi/2 to the
    panel edges (for grids about the normal, where the horizon's kink of ``max(0, s_z)`` then falls on an edge)."""
    validate.at_least("refine", refine, 1)
    w = float(np.clip(width, 1e-3, np.pi / 2))
    edges = [0.0, w / 2]
    while edges[-1] * 2 < np.pi:
        edges.append(edges[-1] * 2)
    edges.append(np.pi)
    if horizon:
        edges = sorted({*edges, np.pi / 2})
    x, wx = np.polynomial.legendre.leggauss(N_GL * refine)
    th, wt = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        t = 0.5 * (b - a) * x + 0.5 * (a + b)
        th.append(t)
        wt.append(0.5 * (b - a) * wx * np.sin(t))
    theta, wtheta = np.concatenate(th), np.concatenate(wt)
    n_phi = N_PHI * refine
    phi = (np.arange(n_phi) + 0.5) * 2.0 * np.pi / n_phi
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    nodes = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
    weights = (wtheta[:, None] * np.full(n_phi, 2.0 * np.pi / n_phi)[None, :]).reshape(-1)
    return np.asarray(nodes), np.asarray(weights)


def mirror_rotations(views: FloatArray) -> FloatArray:
    """Rotations (V, 3, 3) ``R_z(phi_r) R_y(theta_r)`` taking +z to the mirror direction r of each local view."""
    r = mirror_local(views)
    th = np.arctan2(np.hypot(r[:, 0], r[:, 1]), r[:, 2])
    ph = np.arctan2(r[:, 1], r[:, 0])
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    zero = np.zeros_like(th)
    return np.stack([np.stack([cp * ct, -sp, cp * st], -1), np.stack([sp * ct, cp, sp * st], -1),
                     np.stack([-st, zero, ct], -1)], axis=-2)


def _fold_channels(val: FloatArray, channels: int) -> FloatArray:
    return np.broadcast_to(val, val.shape[:-1] + (channels,)) if val.shape[-1] != channels else val


def mirror_signs(order: int, flip_x: ArrayLike, flip_y: ArrayLike) -> FloatArray:
    """Signs (..., (F+1)^2) taking the coefficients of ``g`` to those of ``g(S s)``, S = diag(+-1, +-1, 1).

    y -> -y is phi -> -phi: ``Yr_{l,m<0}`` (sin-like) change sign. x -> -x is phi -> pi - phi: ``Yr_{l,m>=0}`` get
    ``(-1)^m`` and ``Yr_{l,m<0}`` get ``(-1)^(|m|+1)``.
    """
    l = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    m = np.arange(l.size) - l * l - l
    fx = np.asarray(flip_x, dtype=bool)[..., None]
    fy = np.asarray(flip_y, dtype=bool)[..., None]
    sx = np.where(m >= 0, (-1.0) ** np.abs(m), (-1.0) ** (np.abs(m) + 1))
    sy = np.where(m < 0, -1.0, 1.0)
    return np.asarray(np.where(fx, sx, 1.0) * np.where(fy, sy, 1.0), dtype=np.float64)


def project_views(brdf: FrameBRDF, views: ArrayLike, order: int, *, refine: int = 1) -> FloatArray:
    """``c_i(v)`` (V, (F+1)^2, C) for local unit views (V, 3) by the lobe quadrature (module docstring).

    For a ``mirror_symmetric`` BRDF only the distinct views ``(|v_x|, |v_y|, v_z)`` are integrated; the others
    follow from ``f*_v(s) = f*_{Sv}(S s)`` by :func:`mirror_signs` (a quarter of the work on a symmetric map).
    """
    v_all = clamp_to_hemisphere(np.asarray(views, dtype=np.float64).reshape(-1, 3))
    if isinstance(brdf, FrameSum):  # linear: each term with its own quadrature (centre, width, symmetry)
        return np.asarray(sum(np.broadcast_to(project_views(t, v_all, order, refine=refine),
                                              (v_all.shape[0], (order + 1) ** 2, brdf.channels))
                              for t in brdf.terms))
    if brdf.mirror_symmetric and v_all.shape[0] > 1:
        canon = np.abs(v_all)  # v_z >= 0 after the clamp
        found = np.unique(np.round(canon, 12), axis=0, return_inverse=True)
        uniq: FloatArray = np.asarray(found[0], dtype=np.float64)
        c = _project(brdf, uniq, order, refine)[np.asarray(found[1]).reshape(-1)]
        return np.asarray(c * mirror_signs(order, v_all[:, 0] < 0.0, v_all[:, 1] < 0.0)[..., None])
    return _project(brdf, v_all, order, refine)


def _project(brdf: FrameBRDF, v_all: FloatArray, order: int, refine: int) -> FloatArray:
    about_n = brdf.lobe_center == "N"
    nodes, weights = lobe_quadrature(brdf.lobe_width, refine, horizon=about_n)
    th = np.arccos(np.clip(nodes[:, 2], -1.0, 1.0))
    basis = real_harmonics(order, th, np.arctan2(nodes[:, 1], nodes[:, 0])) * weights[:, None]  # (K, n)
    ch = int(brdf.channels)
    out = np.empty((v_all.shape[0], (order + 1) ** 2, ch))
    for v0 in range(0, v_all.shape[0], VIEW_CHUNK):
        v = v_all[v0 : v0 + VIEW_CHUNK]
        rot = np.broadcast_to(np.eye(3), (v.shape[0], 3, 3)) if about_n else mirror_rotations(v)
        s = np.matmul(nodes[None], np.swapaxes(rot, 1, 2))  # (V, K, 3): R_v x_k
        f = _fold_channels(np.asarray(brdf.fcos_local(s, v[:, None, :]), dtype=np.float64), ch)
        g = np.swapaxes(np.matmul(np.swapaxes(f, 1, 2), basis), 1, 2)  # (V, n, C)
        out[v0 : v0 + VIEW_CHUNK] = rotate_coefficients(band_rotations(rot, order), g)
    return out


def check_order(order: int) -> int:
    return validate.int_in_range("the table order F", order, 0, MAX_ORDER)
    return int(order)


@dataclass
class SHTable:
    """A per-view SH table (module docstring): ``coefficients`` (R, R, n, C) over the map's texels, ``views`` (R, R,
    3), ``valid`` (R, R); for isotropic BRDFs also the 1-D table ``theta_coefficients`` (N, n, C) at
    ``thetas`` (N,) with views ``(sin theta, 0, cos theta)``."""

    coefficients: FloatArray
    views: FloatArray
    valid: NDArray[np.bool_]
    order: int
    layout: Layout
    brdf: dict[str, Any]
    thetas: FloatArray | None = None
    theta_coefficients: FloatArray | None = None
    report: dict[str, Any] = field(default_factory=dict)

    @property
    def resolution(self) -> int:
        return int(self.coefficients.shape[0])

    def lookup(self, views: ArrayLike, *, exact_azimuth: bool = True) -> FloatArray:
        """Coefficients (..., n, C) at local views (..., 3): the 1-D table rotated about z for isotropic tables
        (``exact_azimuth``), else bilinear on the map (what a GPU does)."""
        v = clamp_to_hemisphere(views)
        if exact_azimuth and self.thetas is not None and self.theta_coefficients is not None:
            return expand_isotropic(self.thetas, self.theta_coefficients, v)
        x, y = view_to_texel(self.layout, self.resolution, v)
        return bilinear(self.coefficients, x, y)

    def albedo(self) -> FloatArray:
        """``sqrt(4 pi) c_0(v)`` per texel (R, R, C): the directional albedo of the texel's view."""
        return np.asarray(np.sqrt(4.0 * np.pi) * self.coefficients[:, :, 0, :])

    def band_energy(self) -> FloatArray:
        """Energy per band ``sum_m c_lm^2`` per texel (R, R, F+1, C) (the paper's Fig. 2 bottom row)."""
        l = np.repeat(np.arange(self.order + 1), 2 * np.arange(self.order + 1) + 1)
        sq = self.coefficients**2
        return np.stack([sq[:, :, l == k].sum(axis=2) for k in range(self.order + 1)], axis=2)


def expand_isotropic(thetas: FloatArray, coeffs: FloatArray, views: FloatArray) -> FloatArray:
    """``c(theta, phi) = M(R_z(phi)) c(theta, 0)`` with c(theta, 0) linear in theta between samples."""
    v = np.asarray(views, dtype=np.float64)
    th = np.arctan2(np.hypot(v[..., 0], v[..., 1]), v[..., 2])
    ph = np.arctan2(v[..., 1], v[..., 0])
    pos = np.interp(th, thetas, np.arange(thetas.size))
    k0 = np.minimum(np.floor(pos).astype(np.intp), thetas.size - 2)
    t = (pos - k0)[..., None, None]
    c0 = coeffs[k0] * (1.0 - t) + coeffs[k0 + 1] * t
    order = int(round(np.sqrt(coeffs.shape[1]))) - 1
    return rotate_coefficients(rotation_about_z(ph, order), c0)


def build_table(brdf: Any, *, order: int = DEFAULT_ORDER, resolution: int = DEFAULT_RESOLUTION,
                layout: str = DEFAULT_LAYOUT, refine: int = 1) -> SHTable:
    """The SH table of any BRDF (a spec object, a lobe, a sum or a ``FrameBRDF``) (module docstring)."""
    t0 = time.perf_counter()
    f = as_frame_brdf(brdf)
    order = check_order(order)
    lay = check_layout(layout)
    views, valid = map_views(lay, resolution)
    thetas = theta_c = None
    if f.isotropic:
        thetas = np.linspace(0.0, float(np.arccos(RIM_Z)), int(resolution))
        v1 = np.stack([np.sin(thetas), np.zeros_like(thetas), np.cos(thetas)], axis=-1)
        theta_c = project_views(f, v1, order, refine=refine)
        coeffs = expand_isotropic(thetas, theta_c, views)
    else:
        flat = project_views(f, views.reshape(-1, 3), order, refine=refine)
        coeffs = flat.reshape(views.shape[:2] + flat.shape[1:])
    report = {"seconds": time.perf_counter() - t0, "isotropic": bool(f.isotropic), "refine": refine,
              "quadrature_nodes": int(lobe_quadrature(f.lobe_width, refine)[1].size), "lobe_width": f.lobe_width}
    return SHTable(coefficients=coeffs, views=views, valid=valid, order=order, layout=lay, brdf=f.spec(),
                   thetas=thetas, theta_coefficients=theta_c, report=report)


def manifest(table: SHTable) -> dict[str, Any]:
    """JSON description of a table file (``docs/conventions.md``, "SH tables")."""
    return {"format": "relight.sh-table", "version": 1, "order": table.order,
            "coefficients": (table.order + 1) ** 2, "resolution": table.resolution, "layout": table.layout,
            "channels": int(table.coefficients.shape[-1]), "basis": "relight real SH, l^2 + l + m",
            "frame": "local: x = tangent, y = bitangent, z = normal", "brdf": table.brdf, "report": table.report}


def write_table(path: str | os.PathLike[str], table: SHTable) -> dict[str, Any]:
    """Write ``.npz`` (float32 ``coefficients`` R x R x n x C, ``views``, ``valid``, ``manifest`` JSON) or ``.exr``
    (one RGB layer ``c{i}`` per coefficient as float16, values beyond 65504 clamped and counted in the manifest's
    ``float16_clamped``; layers ``views`` (x, y, z) and ``valid``). The file is deterministic: its manifest leaves
    out the report's ``seconds`` and the ``.npz`` is written by :func:`relight.npz.write_npz` (fixed member
    timestamps). Returns the manifest, with the seconds."""
    from relight.envmap.exr import to_half_safe, write_exr_layers
    from relight.npz import without_timings, write_npz

    p = Path(path)
    man = manifest(table)
    half, clamped = to_half_safe(table.coefficients)
    man["float16_clamped"] = clamped
    stored = json.dumps(without_timings(man), sort_keys=True)  # no seconds: the same table gives the same bytes
    if p.suffix.lower() == ".npz":
        write_npz(p, {"coefficients": table.coefficients.astype(np.float32), "views": table.views,
                      "valid": table.valid, "manifest": np.array(stored)})
    elif p.suffix.lower() == ".exr":
        rgb = np.broadcast_to(half, half.shape[:-1] + (3,)) if half.shape[-1] == 1 else half
        layers: dict[str, NDArray[np.floating]] = {f"c{i}": np.asarray(rgb[:, :, i], np.float32)
                                                     for i in range(rgb.shape[2])}
        layers["views"] = table.views
        layers["valid"] = np.repeat(table.valid[..., None], 3, axis=-1).astype(np.float32)
        write_exr_layers(p, layers, half=True, attributes={"relight.shtable": stored})
    else:
        raise InputError(f"the table file must end in .npz or .exr, got {p.name!r}")
    return man


def product_energy(brdf: Any, view: ArrayLike, order: int, *, refine: int = 2) -> tuple[FloatArray, FloatArray]:
    """For one local view: the energy per band captured by the order-F projection, (F+1, C), and the total energy
    ``int f*^2 ds`` (C,), both by the lobe quadrature (the missing fraction is ``1 - sum / total``)."""
    f = as_frame_brdf(brdf)
    v = clamp_to_hemisphere(np.asarray(view, dtype=np.float64).reshape(1, 3))
    c = project_views(f, v, order, refine=refine)[0]
    about_n = f.lobe_center == "N"
    nodes, weights = lobe_quadrature(f.lobe_width, refine, horizon=about_n)
    s = nodes if about_n else nodes @ mirror_rotations(v)[0].T
    vals = _fold_channels(np.asarray(f.fcos_local(s, v), dtype=np.float64), f.channels)
    total = np.einsum("k,kc->c", weights, vals**2)
    l = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    bands = np.stack([(c[l == k] ** 2).sum(axis=0) for k in range(order + 1)])
    return bands, total


def read_table(path: str | os.PathLike[str]) -> SHTable:
    """A table written by :func:`write_table` (``.npz`` float32 or ``.exr`` float16 layers), with its manifest in
    ``brdf`` / ``report``; the 1-D isotropic table is not stored, so lookups are bilinear on the map."""
    from relight.envmap.exr import read_exr_layers

    p = Path(path)
    if p.suffix.lower() == ".npz":
        with np.load(p, allow_pickle=False) as z:
            if not {"coefficients", "views", "valid", "manifest"} <= set(z.files):
                raise InputError(f"{p.name}: not an SH table (needs coefficients, views, valid, manifest)")
            man = json.loads(str(z["manifest"]))
            coeffs, views, valid = (np.asarray(z["coefficients"], np.float64), np.asarray(z["views"], np.float64),
                                    np.asarray(z["valid"], bool))
    elif p.suffix.lower() == ".exr":
        layers, attrs = read_exr_layers(p)
        if "relight.shtable" not in attrs:
            raise InputError(f"{p.name}: not an SH table (no relight.shtable attribute)")
        man = json.loads(attrs["relight.shtable"])
        n = int(man["coefficients"])
        coeffs = np.stack([layers[f"c{i}"] for i in range(n)], axis=2).astype(np.float64)
        if int(man["channels"]) == 1:
            coeffs = coeffs[..., :1]
        views, valid = layers["views"].astype(np.float64), layers["valid"][..., 0] > 0.5
    else:
        raise InputError(f"the table file must end in .npz or .exr, got {p.name!r}")
    if man.get("format") != "relight.sh-table":
        raise InputError(f"{p.name}: manifest format is {man.get('format')!r}, expected 'relight.sh-table'")
    return SHTable(coefficients=coeffs, views=views, valid=valid, order=int(man["order"]),
                   layout=check_layout(man["layout"]), brdf=man["brdf"], report=man.get("report", {}))
