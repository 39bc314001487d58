"""CPU shading with Gaussian lobes and a Gaussian chain (Green, Kautz & Durand 2007, §5, eq. 5; unshadowed).

Per surface point: theta_o = angle(n, v) clamped to the material's elevations, ``r = 2 (n.v) n - v``, the lobe
parameters interpolated at theta_o (``GaussianLobes.params_at``), and for each lobe k the chain looked up at the
lobe centre ``c_k = r rotated by mu_k toward n`` (``relight.brdf.gaussian_lobes.lobe_centres``) in the level of
sigma_k, blended between the two nearest levels as a mip lookup does (``relight.gaussian_chain.sample_chain``):

    L_o = sum_k w_k (G_{sigma_k} * L)(c_k)                                                        (eq. 5)

:func:`render_sphere_gaussian` draws the unit sphere with the camera of ``relight.shrm.sphere_geometry`` (the one
``relight.shrm.render_sphere`` and the Mitsuba twin use), so the three images compare pixel for pixel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from relight.brdf.gaussian_lobes import GaussianLobes, lobe_centres
from relight.errors import InputError
from relight.gaussian_chain import GaussianChain, sample_chain

FloatArray = NDArray[np.float64]


def shade_gaussian(material: GaussianLobes, chain: GaussianChain, normals: NDArray[np.floating],
                   view: NDArray[np.floating]) -> FloatArray:
    """Outgoing radiance (n, 3) at unit normals (n, 3) toward the unit view V ((3,) or (n, 3)), eq. 5."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    v = np.broadcast_to(np.asarray(view, dtype=np.float64), n.shape)
    ndv = np.clip(np.einsum("ij,ij->i", n, v), 0.0, 1.0)  # interpolated normals may face away: theta_o <= 90 deg
    theta_o = np.arccos(ndv)
    r = 2.0 * ndv[:, None] * n - v
    r /= np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-300)
    mu, sigma, w = material.params_at(theta_o)
    c = lobe_centres(n, r, mu)  # (n, K, 3)
    maps = [lv.map for lv in chain.levels]
    out = np.zeros((n.shape[0], 3))
    for k in range(material.n_lobes):
        live = np.any(w[:, k] > 0.0, axis=1)
        if np.any(live):
            out[live] += w[live, k] * sample_chain(maps, chain.sigmas, c[live, k], sigma[live, k])
    return out


def render_sphere_gaussian(material: GaussianLobes, chain: GaussianChain,
                           view: NDArray[np.floating] | Sequence[float], size: int, *,
                           supersample: int = 1) -> FloatArray:
    """The unit sphere (size, size, 3) seen along -V, like ``relight.shrm.render_sphere``; each pixel the mean of
    ``supersample^2`` sub-pixels (Mitsuba's box filter). Off the sphere: 0."""
    from relight.mitsuba_twin import block_mean
    from relight.shrm import sphere_geometry, unit_view

    if size < 1 or supersample < 1:
        raise InputError(f"size and supersample must be >= 1, got {size} and {supersample}")
    v = unit_view(view)
    nrm, mask = sphere_geometry(v, size * supersample)
    img = np.zeros(mask.shape + (3,))
    img[mask] = shade_gaussian(material, chain, nrm[mask], v)
    return block_mean(img, supersample)
