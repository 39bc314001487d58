"""The split-sum DFG table (the BRDF half of Karis 2013, "Real Shading in Unreal Engine 4", eq. 4-8) by
deterministic quadrature (issue 17, item 5).

For a view at ``NoV = n . v`` and perceptual roughness r (GGX, alpha = r^2), with the height-correlated Smith
visibility ``V = 0.5 / (NoL sqrt(NoV^2 (1 - a^2) + a^2) + NoV sqrt(NoL^2 (1 - a^2) + a^2))`` (Heitz 2014, eq. 99;
Filament's ``V_SmithGGXCorrelated``) and ``Fc = (1 - v . h)^5`` (Schlick):

    A = int D(h) V (n.l) (1 - Fc) dl,      B = int D(h) V (n.l) Fc dl,

so a Schlick specular integrates to ``F0 A + F90 B``; ``--multiscatter`` gives Filament's layout
``(B, A + B)`` (``E_spec = mix(x, y, F0)``, Kulla & Conty 2017 energy compensation ``1 + F0 (1 / y - 1)``).

Quadrature: with ``dl = 4 (v.h) dh`` and GGX's own inverse CDF ``tan^2(theta_h) = alpha^2 u / (1 - u)``,
``D(h) (n.h) dh = du dphi / (2 pi)``, so both integrals are ``(1/2pi) int_0^1 int_0^2pi 4 V NoL VoH / NoH w du dphi``
— the integrand cmgen and every engine average over random u; here Gauss–Legendre in u (``NODES_U``) and in phi
(``NODES_PHI``; the integrand is even in phi about the plane of incidence). The ``NoL > 0`` cut is, for each u, the
range ``phi < phi_max(u)`` (closed form below), so phi's nodes span exactly it; tests/relight/test_dfg.py measures
the table against adaptive 2-D quadrature over l.

Layout (docs/conventions.md, "DFG"): an N x N table, row i (file order) at ``r = (i + 0.5) / N``, column j at
``NoV = (j + 0.5) / N``; uploaded as is to a GL texture, ``texture(lut, vec2(NoV, r))`` reads it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError

FloatArray = NDArray[np.float64]
#: Gauss–Legendre nodes in the GGX CDF variable u and in phi (per half circle).
NODES_U = 96
NODES_PHI = 48
MAX_SIZE = 1024


def v_smith_ggx_correlated(nov: FloatArray, nol: FloatArray, alpha: FloatArray) -> FloatArray:
    """Height-correlated Smith visibility ``G2 / (4 NoV NoL)`` for GGX (module docstring)."""
    a2 = alpha * alpha
    gv = nol * np.sqrt(nov * nov * (1.0 - a2) + a2)
    gl = nov * np.sqrt(nol * nol * (1.0 - a2) + a2)
    return np.asarray(0.5 / (gv + gl), dtype=np.float64)


def dfg_terms(nov: FloatArray, roughness: FloatArray, *, nodes_u: int = NODES_U,
              nodes_phi: int = NODES_PHI) -> FloatArray:
    """``(A, B)`` of the module docstring for arrays of NoV in (0, 1] and perceptual roughness in (0, 1], shape
    ``(..., 2)``."""
    nov = np.asarray(nov, dtype=np.float64)
    r = np.asarray(roughness, dtype=np.float64)
    nov, r = np.broadcast_arrays(nov, r)
    if np.any(~(nov > 0.0)) or np.any(nov > 1.0) or np.any(~(r > 0.0)) or np.any(r > 1.0):
        raise InputError("NoV and roughness must lie in (0, 1]")
    alpha = (r * r)[..., None, None]
    xu, wu = np.polynomial.legendre.leggauss(nodes_u)
    xp, wp = np.polynomial.legendre.leggauss(nodes_phi)
    nv = nov[..., None, None]
    sv = np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
    # Beyond theta_h = (pi/2 + theta_v) / 2 every l is below the horizon (l's angle in the plane of incidence is
    # 2 theta_h - theta_v): u stops at that u_c, and u = u_c (1 - s^2) smooths phi_max ~ sqrt(u_c - u) there.
    tan_c = np.tan(0.5 * (0.5 * math.pi + np.arccos(np.clip(nv, -1.0, 1.0))))
    u_c = np.where(np.isfinite(tan_c), tan_c**2 / (alpha * alpha + tan_c**2), 1.0)
    sq = 0.5 * (xu + 1.0)[:, None]  # (Nu, 1)
    u = u_c * (1.0 - sq * sq)
    du = 2.0 * u_c * sq  # du/ds
    cos2 = 1.0 / (1.0 + alpha * alpha * u / (1.0 - u))  # (..., Nu, 1): GGX inverse CDF
    cth = np.sqrt(cos2)
    sth = np.sqrt(np.maximum(1.0 - cos2, 0.0))
    # NoL = 2 VoH NoH - NoV > 0  <=>  cos(phi) > (NoV / (2 NoH) - NoV NoH) / (sin(theta_v) sin(theta_h)): the cut
    # is a phi range per u, so phi's nodes span [0, phi_max(u)] and the integrand has no kink in phi
    with np.errstate(divide="ignore", invalid="ignore"):
        c_star = (nv / (2.0 * cth) - nv * cth) / (sv * sth)
    c_star = np.where(sv * sth > 0.0, c_star, np.where(nv / (2.0 * cth) - nv * cth < 0.0, -1.0, 1.0))
    phi_max = np.arccos(np.clip(c_star, -1.0, 1.0))  # (..., Nu, 1)
    phi = 0.5 * phi_max * (xp + 1.0)  # (..., Nu, Np)
    # (1/2pi) int_0^1 du 2 int_0^phi_max dphi: both halves of phi
    w = (0.5 * wu)[:, None] * du * (0.5 * phi_max * wp) / math.pi
    voh = sv * sth * np.cos(phi) + nv * cth
    nol = 2.0 * voh * cth - nv
    ok = nol > 0.0
    nol_c = np.where(ok, nol, 1.0)
    vis = v_smith_ggx_correlated(nv, nol_c, alpha)
    g = np.where(ok, 4.0 * vis * nol_c * voh / cth, 0.0)
    fc = (1.0 - np.clip(voh, 0.0, 1.0)) ** 5
    a = np.sum(g * (1.0 - fc) * w, axis=(-2, -1))
    b = np.sum(g * fc * w, axis=(-2, -1))
    return np.asarray(np.stack([a, b], axis=-1), dtype=np.float64)


def dfg_table(size: int = 128, *, multiscatter: bool = False) -> FloatArray:
    """The (size, size, 2) table of the module docstring's layout: ``(A, B)`` or, multiscatter, ``(B, A + B)``."""
    size = validate.int_in_range("DFG size", size, 2, MAX_SIZE)
    c = (np.arange(size) + 0.5) / size
    out = np.empty((size, size, 2))
    for i in range(size):  # one roughness row at a time bounds memory to size x NODES_U x NODES_PHI
        out[i] = dfg_terms(c, np.full(size, c[i]))
    if multiscatter:
        out = np.stack([out[..., 1], out[..., 0] + out[..., 1]], axis=-1)
    return out


#: File formats of :func:`dfg_file` (``relight dfg --out FILE.<format>``, ``GET /dfg?format=``).
DFG_FORMATS = ("exr", "png", "ktx2")


def dfg_file(size: int = 128, *, multiscatter: bool = False, fmt: str = "exr") -> bytes:
    """The table as a file's bytes (what ``relight dfg`` writes and ``GET /dfg`` serves): R, G = the table, B = 0;
    ``exr`` float32, ``png`` 16-bit linear (values x 65535), ``ktx2`` a 2-D RGBA16F (B 0, A 1) with the layout
    under ``relight.dfg`` (docs/conventions.md "DFG")."""
    import os
    import tempfile

    if fmt not in DFG_FORMATS:
        raise InputError(f"DFG format must be one of {', '.join(DFG_FORMATS)}, got {fmt!r}")
    table = dfg_table(size, multiscatter=multiscatter)
    rgb = np.concatenate([table, np.zeros(table.shape[:2] + (1,))], axis=-1)
    if fmt == "ktx2":
        from relight import __version__
        from relight.ktx2 import write_ktx2

        layout = "(B, A + B)" if multiscatter else "(A, B)"
        meta = {"dfg": {"channels": layout, "rows": "r = (i + 0.5) / N", "columns": "NoV = (j + 0.5) / N",
                        "size": size}}
        return write_ktx2([rgb[None]], meta, writer=f"relight {__version__}")
    if fmt == "png":
        import imagecodecs  # 16-bit PNG (libpng), as relight.envmap.ldr reads them

        return bytes(imagecodecs.png_encode(np.round(np.clip(rgb, 0.0, 1.0) * 65535).astype(np.uint16)))
    from relight.envmap.exr import write_exr

    fd, tmp = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    try:
        write_exr(tmp, rgb.astype(np.float32))
        with open(tmp, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(tmp)
