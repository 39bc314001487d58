"""Evaluating an SHRM: reflection maps for a distant view (seed 000 eq. 12, §7.5), eq. 6 per point (near viewer),
and CPU renders of a sphere.

Negative radiance: a truncated expansion rings (Gibbs), most near grazing views and around point-like lamps, and
can go below 0 where the true radiance is small (issue 18). Radiance is therefore clamped at 0 (``clamp=True``,
the default; per colour). The cost is stated, not hidden: against any non-negative truth t,
``|max(x, 0) - t| <= |x - t|``, so the clamp never increases a texel's error (the predicted errors of
``relight.shrm.view_bands`` stay upper estimates); it adds energy, at most the error it removes. ``clamp=False``
returns the raw expansion (the tests of the expansion itself use it).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.conventions import (
    latlong_dirs,
    sample_latlong,
)
from relight.errors import InputError
from relight.indexing import full_index
from relight.shrm.basis import (
    FloatArray,
    real_harmonics,
)
from relight.shrm.geometry import (
    halfway_normals,
    lobe_centres,
    local_view_angles,
    reflect_dirs,
    unit_view,
)
from relight.shrm.model import SHRM, SHRMComponent


# --------------------------------------------------------------------------------------------- evaluation
def reflect(shrm: SHRM, view: NDArray[np.floating] | Sequence[float], *, size: int | None = None,
            clamp: bool = True) -> FloatArray:
    """The reflection map for a distant view V (seed 000 eq. 12, §7.5), indexed by R, shape (S, 2S, 3).

    Each pixel holds the radiance reflected toward V by a surface whose reflection vector is that pixel's
    direction R (``docs/conventions.md``); its normal is ``N = normalize(R + V)``. R-centred components give their
    eq. 12 map directly (no resampling when ``size`` is the SHRM's); N- and T-centred components are looked up
    bilinearly at N and T(N). The one direction R = -V (no normal) reads 0. ``clamp``: negative radiance reads 0
    (module docstring).
    """
    v = unit_view(view)
    s = shrm.height if size is None else validate.at_least("size", size, 1)
    r = latlong_dirs(s, 2 * s)
    n, ok = halfway_normals(r, v)
    out = np.zeros((s, 2 * s, 3))
    for comp in shrm.components:
        vm = comp.view_map(v)
        if comp.center == "R" and comp.height == s:
            out += vm
            continue
        c = lobe_centres(comp.center, n, r).reshape(-1, 3)
        out += sample_latlong(vm[None], c)[:, 0].reshape(s, 2 * s, 3)
    out = np.where(ok[..., None], out, 0.0)
    return np.maximum(out, 0.0) if clamp else out


def sphere_geometry(view: FloatArray, size: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Normals of a unit sphere seen by an orthographic camera looking along -V, +Y up, filling the frame.

    The camera matches Mitsuba's ``look_at(origin=3 V, target=0, up=+Y)`` (``docs/facts.md``): image right =
    ``normalize(up x V)`` (+X for V = +Z), image up = ``V x right``; pixel (i, j) sits at
    ``x = 2 (j + 1/2) / size - 1``, ``y = 1 - 2 (i + 1/2) / size``. Returns (size, size, 3) normals and the mask
    of pixels on the sphere. For V = +-Y the up vector is +Z instead.
    """
    up = np.array([0.0, 1.0, 0.0]) if abs(view[1]) < 1.0 - 1e-9 else np.array([0.0, 0.0, 1.0])
    right = np.cross(up, view)
    right /= np.linalg.norm(right)
    upv = np.cross(view, right)
    c = (np.arange(size) + 0.5) * 2.0 / size - 1.0
    x, y = np.meshgrid(c, -c)
    rr = x * x + y * y
    mask = rr < 1.0
    z = np.sqrt(np.clip(1.0 - rr, 0.0, None))
    n = x[..., None] * right + y[..., None] * upv + z[..., None] * view
    return np.asarray(n, dtype=np.float64), mask


def render_sphere(
    shrm: SHRM,
    view: NDArray[np.floating] | Sequence[float],
    size: int,
    *,
    local: bool = False,
    background: NDArray[np.floating] | float = 0.0,
    clamp: bool = True,
) -> FloatArray:
    """CPU render of a unit sphere with the SHRM (seed 000 §7.5), (size, size, 3).

    Orthographic camera of :func:`sphere_geometry`; per pixel N from the sphere, ``R = 2 (N.V) N - V``, and each
    component looked up by bilinear interpolation at its centre (R, N or T(N) of :func:`tangent_field`).
    ``local=False``: the distant-viewer global SHRM, i.e. one eq. 12 map per frame sampled at C.
    ``local=True``: the local SHRM, eq. 6 per pixel: the maps ``Br_pq`` sampled at C, weighted by
    ``Yr_pq(theta_o, phi_o)`` of V in C's local frame (identical to the global path up to interpolation).
    Pixels off the sphere get ``background``; ``clamp`` as in :func:`reflect`.
    """
    v = unit_view(view)
    validate.at_least("size", size, 1)
    n, mask = sphere_geometry(v, size)
    out = np.empty((size, size, 3))
    out[...] = np.asarray(background, dtype=np.float64)
    out[mask] = shade(shrm, n[mask], v, local=local, clamp=clamp)
    return out


def shade(
    shrm: SHRM, normals: NDArray[np.floating], view: NDArray[np.floating], *, local: bool = False,
    map_view: NDArray[np.floating] | None = None, clamp: bool = True,
) -> FloatArray:
    """Radiance (n, 3) leaving surface points with unit normals N (n, 3) toward V (unit; (3,) or per point
    (n, 3)), seed 000 §7.5: ``R = 2 (N.V) N - V`` and each component looked up bilinearly at its centre C.

    ``local=False`` (distant viewer): one eq. 12 map for ``map_view`` (default: ``view``, which must then be a
    single direction) sampled at C. ``local=True`` (near viewer): eq. 6 per point, the maps ``Br_pq`` sampled at C
    and weighted by ``Yr_pq`` of the point's own V in C's local frame. ``clamp`` as in :func:`reflect`.
    """
    nn = np.asarray(normals, dtype=np.float64)
    v = np.asarray(view, dtype=np.float64)
    r = reflect_dirs(nn, v)
    mv = v if map_view is None else unit_view(map_view)
    if not local and mv.shape != (3,):
        raise InputError("a distant viewer needs one view direction for its eq. 12 map (map_view)")
    acc = np.zeros((nn.shape[0], 3))
    for comp in shrm.components:
        c = lobe_centres(comp.center, nn, r)
        if not local:
            acc += sample_latlong(comp.view_map(mv)[None], c)[:, 0]
            continue
        coeffs = sample_latlong(comp.maps, c)  # (n, K, 3)
        theta_o, phi_o = local_view_angles(c, v)
        y = real_harmonics(comp.P, theta_o, phi_o)
        cols = [full_index(p, q) for p, q in comp.terms]
        acc += np.einsum("nkc,nk->nc", coeffs, y[:, cols])
    return np.maximum(acc, 0.0) if clamp else acc


def evaluate_local(comp: SHRMComponent, view: NDArray[np.floating] | Sequence[float]) -> FloatArray:
    """Eq. 6 at every pixel centre of the component's grid for a distant view V: ``sum Br_pq(C) Yr_pq(R_C^{-1} V)``.

    Equals :meth:`SHRMComponent.view_map` (eq. 8 + eq. 12) to rounding; used to check eq. 8.
    """
    v = unit_view(view)
    dirs = latlong_dirs(comp.height, 2 * comp.height)
    theta_o, phi_o = local_view_angles(dirs, v)
    y = real_harmonics(comp.P, theta_o, phi_o)
    cols = [full_index(p, q) for p, q in comp.terms]
    return np.asarray(np.einsum("khwc,hwk->hwc", comp.maps, y[..., cols]), dtype=np.float64)

