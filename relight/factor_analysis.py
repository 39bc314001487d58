"""One factorization analysis of a BRDF (Mahajan, Tseng & Ramamoorthi 2008, §§3–4) as a JSON document plus
factor images: what ``relight factorize`` writes and what the ``factorization`` job returns.

:func:`analyse` runs the SVD (``relight.factorization.factorize``: block-diagonal in the azimuthal frequency for
isotropic BRDFs, dense otherwise), the SVD-free predictions (``relight.factor_predict``), the resolution
convergence check (K at a 1.5x finer grid) and collects the leading factors. :func:`factor_image` draws the
factors as the paper's Figs. 2 and 4 do (red positive, blue negative, white 0; each factor scaled by its largest
magnitude) on the hemisphere seen from above the normal (orthographic disk; over the sphere a second disk for the
lower hemisphere), g_k (incident) in the top row and h_k (outgoing) below, leading factor first.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.errors import InputError
from relight.factorization import Factorization

#: Singular values written to the document (at least every one counted in K is listed).
MAX_VALUES = 400
#: Largest number of leading factors returned as images.
MAX_FACTORS = 32
#: Pixels of one factor disk in :func:`factor_image`.
DISK = 64


def _keys(d: dict[float, int]) -> dict[str, int]:
    return {f"{t:g}": int(k) for t, k in d.items()}


def analyse(brdf: Any, *, domain: str = "hemisphere", resolution: int = 40, phi: int | None = None,
            grid: str = "gauss", include_cosine: bool = True, method: str = "auto", factors: int = 8,
            check_convergence: bool = True) -> tuple[dict[str, Any], Factorization]:
    """The analysis document (``terms``, ``terms_whole_groups``, ``singular_values``, ``frequencies``,
    ``predicted_terms``, ``prediction``, ``convergence``, grid, quantity and seconds; ``radial_transfer``: |F_l|
    for lobes about R, else None) and the factorization (with
    ``factors`` leading factor images)."""
    from relight.brdf.frame import FrameBRDF
    from relight.brdf.spec import brdf_to_spec
    from relight.factor_kernel import unwrap
    from relight.factor_predict import predict_terms
    from relight.factorization import convergence, factorize

    if isinstance(factors, bool) or not isinstance(factors, int) or not 0 <= factors <= MAX_FACTORS:
        raise InputError(f"factors must be an integer in 0..{MAX_FACTORS}, got {factors!r}")
    brdf = unwrap(brdf)
    kwargs: dict[str, Any] = {"domain": domain, "n_theta": resolution, "n_phi": phi if phi is not None else resolution,
                              "grid": grid, "include_cosine": include_cosine, "method": method}
    res = factorize(brdf, n_factors=factors, n_values=min(MAX_VALUES, 2 * resolution * resolution), **kwargs)
    pred: dict[str, Any] | None
    try:
        pred = predict_terms(brdf, domain=domain, include_cosine=include_cosine)
        note = None
    except InputError as exc:
        pred, note = None, str(exc)
    conv = None
    if check_convergence:
        c = convergence(brdf, **kwargs)
        conv = {k: v for k, v in c.items() if k != "results"}
    doc = res.as_dict(MAX_VALUES)
    doc["brdf"] = brdf.spec() if isinstance(brdf, FrameBRDF) else brdf_to_spec(brdf)
    doc["predicted_terms"] = _keys(pred["terms"]) if pred else None
    if pred:
        doc["prediction"] = {k: (_keys(v) if isinstance(v, dict) and all(isinstance(x, float) for x in v) else v)
                             for k, v in pred.items()}
    else:
        doc["prediction"] = {"method": None, "note": note}
    doc["convergence"] = conv
    if res.factors:
        doc["factors"] = {"sigma": [f.sigma for f in res.factors], "m": [f.m for f in res.factors]}
    doc["radial_transfer"] = _radial_transfer(brdf) if include_cosine else None
    return doc, res


def _radial_transfer(brdf: Any) -> list[float] | None:
    """|F_l| of a lobe about R (the sphere's singular values, eq. 9; relight's transfer factors) up to the order
    holding all but 1e-8 of its energy, or None for other BRDFs."""
    from relight.brdf.base import RadialLobe
    from relight.brdf.coefficients import spectrum_for_tolerance
    from relight.factor_predict import SPECTRUM_TAIL, mean_lobe

    if not isinstance(brdf, RadialLobe) or brdf.center != "R":
        return None
    spec, _ = spectrum_for_tolerance(mean_lobe(brdf), SPECTRUM_TAIL)
    return [float(abs(x)) for x in spec.transfer[:, 0]]


def _disk_nodes(res: Factorization, lower: bool) -> NDArray[np.int64]:
    """Index of the grid node nearest to each pixel of a DISK x DISK orthographic view of the (upper or lower)
    hemisphere, -1 outside the disk."""
    g = res.grid
    c = (np.arange(DISK) + 0.5) / DISK * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    mu = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0)) * (-1.0 if lower else 1.0)
    phi = np.mod(np.arctan2(y, x), 2.0 * np.pi)
    it = np.abs(mu[..., None] - g.mu).argmin(axis=-1)
    ip = np.rint(phi / (2.0 * np.pi) * g.n_phi).astype(np.int64) % g.n_phi
    return np.where(r2 <= 1.0, it * g.n_phi + ip, -1)


def _colour(v: NDArray[np.float64]) -> NDArray[np.uint8]:
    """Red positive, blue negative, white 0 (values in [-1, 1])."""
    a = np.clip(np.abs(v), 0.0, 1.0)
    rgb = np.ones(v.shape + (3,))
    rgb[..., 1] -= a
    rgb[..., 2] -= np.where(v > 0, a, 0.0)
    rgb[..., 0] -= np.where(v < 0, a, 0.0)
    return np.asarray(np.rint(rgb * 255.0), dtype=np.uint8)


def factor_image(res: Factorization) -> NDArray[np.uint8]:
    """The leading factors as one RGB image (module docstring): 2 rows (g, h) of F disks (two per factor over the
    sphere: upper, lower), 2 pixel gaps, grey background."""
    if not res.factors:
        raise InputError("the factorization holds no factor images (factors=0)")
    halves = [False, True] if res.grid.domain == "sphere" else [False]
    nodes = [_disk_nodes(res, lower) for lower in halves]
    cell = DISK + 2
    width = len(res.factors) * len(halves) * cell
    img = np.full((2 * cell, width, 3), 128, dtype=np.uint8)
    for k, f in enumerate(res.factors):
        for row, fn in enumerate((f.g, f.h)):
            flat = fn.ravel()
            scale = float(np.abs(flat).max()) or 1.0
            for j, idx in enumerate(nodes):
                tile = _colour(np.where(idx >= 0, flat[np.maximum(idx, 0)], 0.0) / scale)
                tile[idx < 0] = 128
                x0 = (k * len(halves) + j) * cell
                img[row * cell: row * cell + DISK, x0: x0 + DISK] = tile
    return img


def png_bytes(img: NDArray[np.uint8]) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img, mode="RGB").save(buf, format="PNG")
    return buf.getvalue()
