"""Costs of planner v2's representations: precompute seconds and per-frame milliseconds (issue 16 item 4; design
notes §5.4 "Cost-model features").

Like ``relight.costmodel`` (seed 000's stages), each cost is a linear model ``t = sum_k c_k phi_k`` in features
``phi_k`` counted from the job's sizes, with constants fitted by non-negative least squares on relative error
(``relight.costmodel.fit``) to timed runs (:func:`calibrate_precompute`, run by ``bench/planner_costs.py``, which
prints the constants written below).

Precompute features (seconds):

* ``fit_nodes``: Gaussian-lobe fit (seed 002 §4, ``relight.sgfit``) = elevations x slice nodes x K;
* ``chain_px`` and ``chain_leg``: Gaussian chain (§5.1, ``relight.gaussian_chain``) = input pixels x log2(width)
  (the one projection) and sum over levels of ``S_j (F_j + 1)^2`` (the syntheses; S_j ~ 10 F_j capped at H);
* ``table_evals`` and ``table_proj``: SH table (seed 003 §3, ``relight.sh_table``) = views x quadrature nodes (BRDF
  evaluations) and views x nodes x (F + 1)^2 (projections); views = R for isotropic BRDFs (1-D table), R^2 otherwise;
* ``rays`` and ``ray_proj``: per-vertex transfer (``relight.visibility``) = rays cast and rays x coefficients
  (``(F+1)^2`` for vectors, ``(F+1)^4`` for shadow matrices, K (F+1)^2 for in-out transport).

Per-frame features (milliseconds on the viewer's GPU path; counts per frame):

* ``px_lookup``: texture fetches per pixel x pixels (reflection maps: 1, SHRMs: their maps, Gaussian lobes: K,
  SH tables: ``ceil(n C / 4)`` RGBA texels, in-out: K factors h_k);
* ``px_madd``: multiply-adds per pixel x pixels (SH evaluation, dot products; on the analytic sphere the per-vertex
  work of a mesh happens per pixel);
* ``vx_madd``: multiply-adds per vertex x vertices (SH rotation ``sum_l (2l+1)^2``, transfer ``n`` or ``n^2``,
  in-out ``K n``, per colour).

The per-frame constants come from ``bench/planner_costs.py``'s moderngl runs (llvmpipe on the development machine:
absolute milliseconds describe that machine; the planner compares representations with them, and a budget on
another machine scales with its speed).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

#: Viewer canvas (pixels) and vertical field of view the per-frame pixel counts assume: a 1024 x 1024 canvas,
#: 45 degrees (three.js PerspectiveCamera default of the viewer).
CANVAS_PIXELS: Final = 1024 * 1024
FOV_DEG: Final = 45.0
#: Colour channels.
C: Final = 3

PRECOMPUTE_FEATURES: Final = ("fit_nodes", "chain_px", "chain_leg", "table_evals", "table_proj", "rays",
                              "ray_proj", "job_call")
FRAME_FEATURES: Final = ("px_lookup", "px_madd", "vx_madd", "draw")

#: Seconds per precompute feature unit, fitted by ``bench/planner_costs.py --full`` on the 2-core development machine
#: (under load; in-sample predicted / measured 0.6-1.3 except the smallest runs, whose fixed costs dominate).
PRECOMPUTE_CONSTANTS: dict[str, float] = {
    "fit_nodes": 1.02e-04,
    "chain_px": 9.97e-09,
    "chain_leg": 0.0,
    "table_evals": 7.01e-08,
    "table_proj": 1.88e-10,
    "rays": 4.55e-07,
    "ray_proj": 4.79e-10,
    "job_call": 1.30e-02,
}
#: Milliseconds per per-frame feature unit, fitted by ``bench/planner_costs.py`` (moderngl, llvmpipe).
FRAME_CONSTANTS: dict[str, float] = {
    "px_lookup": 2.0e-06,
    "px_madd": 2.0e-07,
    "vx_madd": 1.0e-07,
    "draw": 0.05,
}


@dataclass(frozen=True)
class Cost:
    """Features of one representation of one lobe: precompute (per job, before sharing) and per frame."""

    precompute: dict[str, float]
    frame: dict[str, float]

    def seconds(self, constants: Mapping[str, float] | None = None) -> float:
        c = PRECOMPUTE_CONSTANTS if constants is None else constants
        return float(sum(c[k] * v for k, v in self.precompute.items()))

    def frame_ms(self, constants: Mapping[str, float] | None = None) -> float:
        c = FRAME_CONSTANTS if constants is None else constants
        return float(sum(c[k] * v for k, v in self.frame.items()))


def screen_pixels(size: float, distance: float) -> float:
    """Pixels an object of bounding radius ``size`` at ``distance`` covers on the viewer's canvas
    (:data:`CANVAS_PIXELS`, :data:`FOV_DEG`): a disc of angular radius ``asin(r / d)``, at most the canvas."""
    half = math.radians(FOV_DEG) / 2.0
    ang = math.asin(min(1.0, size / distance))
    radius = min(1.0, math.tan(ang) / math.tan(half)) * math.sqrt(CANVAS_PIXELS) / 2.0
    return float(min(CANVAS_PIXELS, math.pi * radius * radius))


def rotation_madds(order: int) -> int:
    """Multiply-adds of one real SH rotation to order F: ``sum_l (2l + 1)^2`` (block diagonal per band)."""
    return sum((2 * l + 1) ** 2 for l in range(order + 1))


def add(*parts: Mapping[str, float]) -> dict[str, float]:
    out: dict[str, float] = {}
    for p in parts:
        for k, v in p.items():
            out[k] = out.get(k, 0.0) + float(v)
    return out


# ------------------------------------------------------------------------------------------------ precompute
def fit_features(elevations: int, nodes: int, lobes: int) -> dict[str, float]:
    return {"fit_nodes": float(elevations * nodes * lobes), "job_call": 1.0}


def chain_features(height: int, width: int, level_orders: list[int], level_rows: list[int]) -> dict[str, float]:
    leg = sum(s * (f + 1) ** 2 for f, s in zip(level_orders, level_rows, strict=True))
    px = sum(2 * s * s for s in level_rows) + height * width * math.log2(max(width, 2))
    return {"chain_px": float(px), "chain_leg": float(leg), "job_call": 1.0}


def table_features(views: int, nodes: int, order: int) -> dict[str, float]:
    return {"table_evals": float(views * nodes), "table_proj": float(views * nodes * (order + 1) ** 2),
            "job_call": 1.0}


def transfer_features(vertices: int, rays: int, coefficients: int) -> dict[str, float]:
    r = float(vertices * rays)
    return {"rays": r, "ray_proj": r * coefficients, "job_call": 1.0}


# ------------------------------------------------------------------------------------------------ per frame
def frame_features(representation: str, terms: Mapping[str, Any], pixels: float, vertices: int,
                   shadows: str = "none") -> dict[str, float]:
    """Per-frame features of one lobe drawn with ``representation`` (module docstring). ``vertices`` is 0 on the
    analytic sphere (its per-vertex work happens per pixel)."""
    per_vertex = vertices > 0
    out: dict[str, float] = {"draw": 1.0}

    def vx(madds: float) -> None:
        key, count = ("vx_madd", vertices) if per_vertex else ("px_madd", pixels)
        out[key] = out.get(key, 0.0) + madds * count

    if representation == "irradiance":
        n = (int(terms["F"]) + 1) ** 2
        out["px_madd"] = pixels * n * C
    elif representation == "diffuse_transfer":
        vx(terms["coefficients"] * C)
    elif representation in ("reflection_map", "shrm_q0", "shrm"):
        out["px_lookup"] = pixels * int(terms.get("maps", 1))
        out["px_madd"] = pixels * int(terms.get("maps", 1)) * C
    elif representation == "gaussian_lobes":
        k = int(terms["K"])
        out["px_lookup"] = pixels * 2 * k  # two chain levels blended per lobe
        nv = int(terms.get("visibility_coefficients", 0)) if shadows != "none" else 0
        out["px_madd"] = pixels * k * (C + nv)
    elif representation in ("sh_table", "prt_matrix"):
        f = int(terms["F"])
        n = (f + 1) ** 2
        out["px_lookup"] = pixels * math.ceil(n * C / 4)
        out["px_madd"] = pixels * n * C
        vx((rotation_madds(f) if representation == "sh_table" else n * n) * C)
    elif representation == "inout_prt":
        k, n = int(terms["K"]), int(terms["coefficients"])
        out["px_lookup"] = pixels * k
        out["px_madd"] = pixels * k * C
        vx(k * n * C)
    else:
        raise ValueError(f"no per-frame model for representation {representation!r}")
    return out


# ------------------------------------------------------------------------------------------------ calibration
def calibrate_precompute(*, quick: bool = True, seed: int = 0) -> tuple[dict[str, float], list[dict[str, Any]]]:
    """Time fits, chains, tables and transfers at a few sizes and fit :data:`PRECOMPUTE_FEATURES` by NNLS on
    relative error (``relight.costmodel.fit``). Returns the constants and the runs (features, measured seconds)."""
    import time

    import numpy as np

    from relight.brdf.spec import parse_brdf, parse_frame_brdf
    from relight.costmodel import fit
    from relight.gaussian_chain import build_chain
    from relight.mesh import sample_mesh
    from relight.sgfit import FitSettings, fit_gaussian_lobes
    from relight.sh_table import build_table, lobe_quadrature
    from relight.visibility import TransferSettings, compute_transfer

    rng = np.random.default_rng(seed)
    rows: list[tuple[dict[str, float], float]] = []

    def timed(feats: dict[str, float], fn: Any) -> None:
        t0 = time.perf_counter()
        fn()
        rows.append((feats, time.perf_counter() - t0))

    ts = parse_brdf("torrance-sparrow:alpha=0.2,fresnel=none")
    ts_frame = parse_frame_brdf("torrance-sparrow:alpha=0.2,fresnel=none")
    for elev, ng, npsi in ((4, 60, 10), (6, 80, 12)) if quick else ((4, 60, 10), (6, 80, 12), (8, 80, 12)):
        timed(fit_features(elev, ng * npsi, 3),
              lambda e=elev, g=ng, p=npsi: fit_gaussian_lobes(ts, FitSettings(elevations=e, n_gamma=g, n_psi=p,
                                                                              max_nfev=60)))
    for h in (32, 64) if quick else (32, 64, 128):
        px = rng.random((h, 2 * h, 3))
        chain = build_chain(px, epsilon=1e-2)
        feats = chain_features(h, 2 * h, [int(lv.orders["F_B"]) for lv in chain.levels],
                               [int(lv.orders["size"]) for lv in chain.levels])
        timed(feats, lambda p=px: build_chain(p, epsilon=1e-2))
    aniso = parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0")
    tables = ((ts_frame, 32, 4), (aniso, 16, 4), (aniso, 24, 6)) + (() if quick else (
        (ts_frame, 64, 8), (aniso, 16, 8), (aniso, 32, 4)))
    for f, res, order in tables:
        nodes = int(lobe_quadrature(f.lobe_width)[1].size)
        views = res if f.isotropic else res * res
        timed(table_features(views, nodes, order), lambda b=f, r=res, o=order: build_table(b, order=o, resolution=r))
    mesh = sample_mesh("teapot")
    transfers = ((256, 3, "diffuse_transfer"), (512, 2, "shadow_matrix")) + (() if quick else (
        (1024, 3, "diffuse_transfer"), (256, 4, "shadow_matrix"), (256, 6, "shadow_matrix")))
    for rays, order, kind in transfers:
        n = (order + 1) ** 2 * ((order + 1) ** 2 if kind == "shadow_matrix" else 1)
        timed(transfer_features(mesh.n_vertices, rays, n),
              lambda r=rays, o=order, k=kind: compute_transfer(mesh, TransferSettings(order=o, rays=r, kind=k)))
    consts = fit(rows, PRECOMPUTE_FEATURES)
    runs = [{"features": f, "measured": t, "predicted": sum(consts[k] * v for k, v in f.items())} for f, t in rows]
    return consts, runs
