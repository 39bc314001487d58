"""CPU shading with Gaussian lobes and a Gaussian chain (Green, Kautz & Durand 2007, §5, eqs. 5 and 7).

Per surface point: theta_o = angle(n, v) clamped to the material's elevations, ``r = 2 (n.v) n - v``, the lobe
parameters interpolated at theta_o (``GaussianLobes.params_at``), and for each lobe k the chain looked up at the
lobe centre ``c_k = r rotated by mu_k toward n`` (``relight.brdf.gaussian_lobes.lobe_centres``) in the level of
sigma_k, blended between the two nearest levels as a mip lookup does (``relight.gaussian_chain.sample_chain``):

    L_o = sum_k w_k (G_{sigma_k} * L)(c_k)                                                        (eq. 5)

:func:`render_mesh_gaussian` draws a mesh with ``relight.mesh_render``'s camera (Mitsuba's), unshadowed or with
eq. 7's glossy shadows from per-vertex SH visibility (``relight.sg_shadow``). :func:`render_sphere_gaussian` draws
the unit sphere with the camera of ``relight.shrm.sphere_geometry`` (the one
``relight.shrm.render_sphere`` and the Mitsuba twin use), so the three images compare pixel for pixel.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from relight import validate
from relight.brdf.gaussian_lobes import GaussianLobes, lobe_centres
from relight.errors import InputError
from relight.gaussian_chain import GaussianChain, sample_chain
from relight.mesh.model import TriangleMesh
from relight.raycast import RayCaster
from relight.reports import OMIT_NONE, Report

FloatArray = NDArray[np.float64]


def shade_gaussian(material: GaussianLobes, chain: GaussianChain, normals: NDArray[np.floating],
                   view: NDArray[np.floating]) -> FloatArray:
    """Outgoing radiance (n, 3) at unit normals (n, 3) toward the unit view V ((3,) or (n, 3)), eq. 5."""
    lobes = lobe_terms(material, chain, normals, view)
    return np.asarray(np.einsum("pkc,pkc->pc", lobes.weight, lobes.radiance), dtype=np.float64)


@dataclass(frozen=True)
class LobeTerms:
    """Per point and lobe: centre c_k (P, K, 3), width sigma_k (P, K), weight w_k (P, K, 3) and the chain's
    radiance ``(G_{sigma_k} * L)(c_k)`` (P, K, 3); eq. 5 is ``sum_k w_k radiance_k``, eq. 7 weights each term."""

    centres: FloatArray
    sigma: FloatArray
    weight: FloatArray
    radiance: FloatArray


def lobe_terms(material: GaussianLobes, chain: GaussianChain, normals: NDArray[np.floating],
               view: NDArray[np.floating]) -> LobeTerms:
    """The terms of eqs. 5 and 7 at unit normals (n, 3) toward the unit view V ((3,) or (n, 3))."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    v = np.broadcast_to(np.asarray(view, dtype=np.float64), n.shape)
    ndv = np.clip(np.einsum("ij,ij->i", n, v), 0.0, 1.0)  # interpolated normals may face away: theta_o <= 90 deg
    theta_o = np.arccos(ndv)
    r = 2.0 * ndv[:, None] * n - v
    r /= np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-300)
    mu, sigma, w = material.params_at(theta_o)
    c = lobe_centres(n, r, mu)  # (n, K, 3)
    maps = [lv.map for lv in chain.levels]
    rad = np.zeros(w.shape)
    for k in range(material.n_lobes):
        live = np.any(w[:, k] > 0.0, axis=1)
        if np.any(live):
            rad[live, k] = sample_chain(maps, chain.sigmas, c[live, k], sigma[live, k])
    return LobeTerms(centres=c, sigma=sigma, weight=w, radiance=rad)


def render_sphere_gaussian(material: GaussianLobes, chain: GaussianChain,
                           view: NDArray[np.floating] | Sequence[float], size: int, *,
                           supersample: int = 1) -> FloatArray:
    """The unit sphere (size, size, 3) seen along -V, like ``relight.shrm.render_sphere``; each pixel the mean of
    ``supersample^2`` sub-pixels (Mitsuba's box filter). Off the sphere: 0."""
    from relight.mitsuba_compare import block_mean
    from relight.shrm import sphere_geometry, unit_view

    validate.at_least("size", size, 1)
    validate.at_least("supersample", supersample, 1)
    v = unit_view(view)
    nrm, mask = sphere_geometry(v, size * supersample)
    img = np.zeros(mask.shape + (3,))
    img[mask] = shade_gaussian(material, chain, nrm[mask], v)
    return block_mean(img, supersample)


@dataclass(frozen=True, kw_only=True)
class GaussianRenderReport(Report):
    """What a Gaussian-lobe render drew: the object (``sphere`` or ``mesh``, with the mesh's vertex count), the
    visibility mode and the surface points shaded; with visibility, the range of the per-lobe values before the clamp
    to [0, 1] and the fraction of lobe lookups clamped. Optional keys are left out of the JSON form while None."""

    object: str = "mesh"
    mode: str = "none"
    vertices: int | None = field(default=None, metadata=OMIT_NONE)
    points: int | None = field(default=None, metadata=OMIT_NONE)
    unclamped_min: float | None = field(default=None, metadata=OMIT_NONE)
    unclamped_max: float | None = field(default=None, metadata=OMIT_NONE)
    clamped_fraction: float | None = field(default=None, metadata=OMIT_NONE)


def render_mesh_gaussian(material: GaussianLobes, chain: GaussianChain, mesh: TriangleMesh,
                         view: NDArray[np.floating] | Sequence[float], size: int, *, supersample: int = 2,
                         visibility: NDArray[np.floating] | None = None, mode: str = "none",
                         order: int | None = None, caster: RayCaster | None = None
                         ) -> tuple[FloatArray, GaussianRenderReport]:
    """A mesh (already in the unit ball) with the camera of ``relight.mesh_render`` (Mitsuba's), eq. 5 or, with
    per-vertex SH ``visibility`` (V, (F+1)^2) and ``mode`` in ``relight.sg_shadow.MODES``, eq. 7: the coefficients
    interpolated with each hit's barycentrics, evaluated per lobe, clamped to [0, 1]. Returns the (size, size, 3)
    image and a report with the unclamped visibility range."""
    from relight.mesh_render import interpolate, surface_samples
    from relight.sg_shadow import lobe_visibility

    validate.at_least("size", size, 1)
    validate.at_least("supersample", supersample, 1)
    v = np.asarray(view, dtype=np.float64)
    v = v / np.linalg.norm(v)
    samples = surface_samples(mesh, v, size, supersample, caster)
    terms = lobe_terms(material, chain, samples.normals, v)
    report = GaussianRenderReport(mode=mode, points=int(samples.normals.shape[0]))
    if mode == "none":
        vis = np.ones(terms.sigma.shape)
    else:
        if visibility is None:
            raise InputError(f"visibility mode {mode!r} needs per-vertex SH visibility")
        coeffs = interpolate(samples, mesh, np.asarray(visibility, dtype=np.float64))
        vis, raw = lobe_visibility(coeffs, terms.centres, terms.sigma, mode, order)
        live = terms.weight.sum(axis=2) > 0.0
        report = dataclasses.replace(
            report, unclamped_min=float(raw[live].min(initial=np.inf)),
            unclamped_max=float(raw[live].max(initial=-np.inf)),
            clamped_fraction=float(np.mean((raw[live] < 0.0) | (raw[live] > 1.0))) if live.any() else 0.0)
    rgb = np.einsum("pk,pkc,pkc->pc", vis, terms.weight, terms.radiance)
    return samples.image(rgb), report
