"""The angular method's work for the cost model (seed 000 App. D): pairs (output pixel, input pixel) visited and
lobe evaluations, following ``relight.reference`` and ``relight.reference_view`` (the same block plan,
:func:`relight.reference_view.view_groups`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight.costmodel.timing import integrand_eval_seconds

FloatArray = NDArray[np.float64]


def angular_pairs(height: int, size: int, theta_star: float) -> int:
    """Pairs (output pixel, input pixel) that ``reference_radial`` visits: the rows within theta* (+ half a pixel)
    of each output ring, times the columns of both."""
    from relight.conventions import ring_thetas

    env_theta = ring_thetas(height)
    out_theta = ring_thetas(size)
    rows = np.abs(env_theta[None, :] - out_theta[:, None]) <= theta_star + 0.5 * np.pi / height
    return int(rows.sum()) * 2 * size * 2 * height


def angular_features(height: int, size: int, theta_star: float) -> dict[str, float]:
    """Angular method for a radial lobe truncated at theta* (App. D)."""
    return {"ang_pairs": float(angular_pairs(height, size, theta_star))}


def _cone_row_counts(c_theta: FloatArray, theta_star: FloatArray, env_theta: FloatArray, width: int) -> FloatArray:
    """Expected pixels of each ring inside each output's cone, (n_out, H): the ring's azimuthal share of the cone.

    A ring at polar angle ``t_r`` meets the cone of half-angle ``t*`` about a centre at ``t_c`` where
    ``cos dphi >= (cos t* - cos t_c cos t_r) / (sin t_c sin t_r)``: ``2 arccos(.) / (2 pi)`` of its pixels.
    """
    ct, st = np.cos(c_theta)[:, None], np.sin(c_theta)[:, None]
    cr, sr = np.cos(env_theta)[None, :], np.sin(env_theta)[None, :]
    cs = np.cos(theta_star)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (cs - ct * cr) / (st * sr)
    x = np.where(np.isfinite(x), x, np.where(cs <= ct * cr, -1.0, 1.0))
    return np.asarray(np.arccos(np.clip(x, -1.0, 1.0)) / np.pi * width, dtype=np.float64)


def angular_view_counts(
    brdf: Any, view: Sequence[float] | FloatArray, height: int, size: int, truncation: float,
    *, chunk_elems: int | None = None,
) -> tuple[int, list[int], float]:
    """(pairs visited, lobe evaluations per lobe, mean App. D W) of ``reference_view`` for one view (module
    docstring).

    Walks the blocks of ``relight.reference_view.block_plan``, the schedule ``reflected_radiance`` evaluates; a
    block's pairs inside the cones are the expected counts of :func:`_cone_row_counts` instead of a test of every
    pair, and a block that ``reference_view.is_dense`` would evaluate densely counts all its pairs.
    """
    from relight.conventions import latlong_dirs, ring_thetas
    from relight.reference_view import CHUNK_ELEMS, block_plan, is_dense
    from relight.shrm import brdf_lobes, halfway_normals, reflect_dirs, unit_view

    v = unit_view(view)
    r = latlong_dirs(size, 2 * size).reshape(-1, 3)
    n, ok = halfway_normals(r, v)
    n = n[ok]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)  # the normals and reflection vectors exactly as
    r = reflect_dirs(n, v)  # reflected_radiance derives them, so that block_plan sees the same cones
    width = 2 * height
    env_theta = ring_thetas(height)
    pairs = 0
    evals_per_lobe: list[int] = []
    w_sum, w_n = 0.0, 0
    facing = (n @ v) > 0.0
    for lobe in brdf_lobes(brdf):
        evals = 0
        plan = block_plan(lobe, n, r, v, height, truncation,
                          chunk_elems=CHUNK_ELEMS if chunk_elems is None else chunk_elems)
        w_sum += float((0.5 * (1.0 - np.cos(plan.theta_star)))[facing].sum())
        w_n += int(facing.sum())
        for grp in plan.groups:
            idx = grp.outputs
            inside = _cone_row_counts(plan.c_theta[idx], plan.theta_star[idx], env_theta[grp.rows], width).sum(axis=0)
            for sl in grp.blocks():
                block = idx.size * (sl.stop - sl.start) * width
                hit = float(inside[sl].sum())
                pairs += block
                evals += block if is_dense(hit, block) else int(round(hit))
        evals_per_lobe.append(evals)
    return pairs, evals_per_lobe, (w_sum / w_n if w_n else 0.0)


def angular_view_features(
    brdf: Any, view: Sequence[float] | FloatArray, height: int, size: int, truncation: float
) -> dict[str, float]:
    """Angular method for a view-dependent BRDF, one view (``relight.reference_view.reference_view``)."""
    from relight.shrm import brdf_lobes

    pairs, evals, _ = angular_view_counts(brdf, view, height, size, truncation)
    cost = sum(n * integrand_eval_seconds(lobe) for n, lobe in zip(evals, brdf_lobes(brdf), strict=True))
    return {"angv_pairs": float(pairs), "angv_evals": cost}
