"""The Gaussian-prefiltered environment chain of seed 002 (Green, Kautz & Durand 2007, §5.1, eq. 5).

Level j holds ``(G_{sigma_j} * L)``, the environment convolved with the normalised spherical Gaussian of
``relight.brdf.vmf`` with ``sigma_j = sigma_0 ratio^j``: ratio 2 is the paper's ("twice the standard deviation of
the previous level"), sqrt(2) the option that halves the error of blending two levels (:func:`blend_kernel_error`).

Instead of the paper's one FFT-based convolution per level, relight projects the lighting *once*, to the order of
the sharpest level, and per level multiplies by the vMF's closed-form transfer and synthesises (seed 000's radial
prefilter, ``relight.prefilter``, with ``relight.prefilter.choose_orders``): each level's order F_j is the smaller
of the vMF's and the lighting's orders for the tolerance epsilon (seed 000 §5.1), capped at the map's ``H - 1``,
with seed 000 App. B's bound in its report; its rows are ``S_j ~ 10 F_j`` (seed 000 §5.2) capped at the input's
rows H (``size_cap``), since S ~ 10 F would ask for more rows than the map has for sharp levels. Doubling sigma halves
F and hence S: the seed-000 sizing rule *is* a mip chain. Levels are stored as float16 lat-long maps (the viewer's
texture format) in a folder with a ``chain.json`` manifest (:func:`write_chain`).

Dynamic environments (the paper's §7 limitation, "not currently possible"): the whole chain of a 1024 x 512 map is
one projection plus one synthesis per level, about a second on this machine (``bench/chain.py``), so a changed
environment is re-prefiltered in about a second, not offline.

A shader picks a fractional level ``x = log(sigma / sigma_0) / log(ratio)`` and blends the two neighbouring levels
linearly (:func:`sample_chain`). The blend of two Gaussians is not a Gaussian: :func:`blend_kernel_error` gives its
relative L2 error against the exact intermediate Gaussian ``sigma_0 ratio^x`` in closed form.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from relight import __version__, indexing, sh, validate
from relight.brdf.coefficients import spectrum_for_tolerance
from relight.brdf.vmf import VonMisesFisher, check_sigma, sigma_to_kappa, vmf_inner
from relight.conventions import require_rgb_latlong
from relight.errors import InputError
from relight.prefilter import DEFAULT_EPSILON, MIN_SIZE, choose_orders, project_lighting, size_for_order
from relight.reports import OMIT_NONE, Report

FloatArray = NDArray[np.float64]

#: The paper's ratio between levels (§5.1) and the finer option.
RATIOS = {"2": 2.0, "sqrt2": math.sqrt(2.0)}
#: Default widest level: a lobe of sigma 90 degrees is nearly the cosine-weighted hemisphere; wider lobes use the
#: last level (their lookups clamp there).
DEFAULT_SIGMA_MAX = math.pi / 2
#: Most levels a chain may have (sigma_0 = 1e-3 rad with ratio sqrt 2 reaches 90 degrees in 24 levels).
MAX_LEVELS = 32
MANIFEST = "chain.json"


def default_sigma0(height: int) -> float:
    """The map's pixel angle ``pi / H``: no lobe sharper than a pixel can be resolved by the map."""
    return math.pi / height


def chain_sigmas(sigma0: float, ratio: float, *, levels: int | None = None, sigma_max: float = DEFAULT_SIGMA_MAX
                 ) -> FloatArray:
    """``sigma_j = sigma_0 ratio^j`` for ``levels`` levels, or until the first level reaching ``sigma_max``."""
    s0 = check_sigma(sigma0, "sigma0")
    validate.in_range("chain: ratio", ratio, 1.0, None, lo_open=True)
    if levels is None:
        if not sigma_max >= s0:
            raise InputError(f"chain: sigma_max must be >= sigma0 ({s0:g}), got {sigma_max!r}")
        levels = int(math.ceil(math.log(sigma_max / s0) / math.log(ratio) - 1e-9)) + 1
    levels = validate.int_in_range("chain: levels", levels, 1, MAX_LEVELS)
    sig = s0 * ratio ** np.arange(levels, dtype=np.float64)
    if sig[-1] > math.pi:
        raise InputError(f"chain: the widest level would have sigma {sig[-1]:.3g} > pi; use fewer levels")
    return np.asarray(sig, dtype=np.float64)


@dataclass
class ChainLevel:
    """One level: ``(G_sigma * L)`` on an S x 2S lat-long grid (float32 in memory) and its orders/errors."""

    sigma: float
    map: NDArray[np.float32]
    orders: dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class ChainReport(Report):
    """What :func:`build_chain` did (the ``report`` of ``chain.json``): the chain's parameters, the projection order,
    the input's shape, the blend's kernel error per fraction (:func:`blend_kernel_error`) and seconds per stage. Every
    key is optional (left out while None): a chain read from a manifest without a report, or assembled from stored
    levels, has none."""

    representation: str | None = field(default=None, metadata=OMIT_NONE)
    sigma0: float | None = field(default=None, metadata=OMIT_NONE)
    ratio: float | None = field(default=None, metadata=OMIT_NONE)
    epsilon: float | None = field(default=None, metadata=OMIT_NONE)
    sigmas: list[float] | None = field(default=None, metadata=OMIT_NONE)
    projection_order: int | None = field(default=None, metadata=OMIT_NONE)
    input: dict[str, int] | None = field(default=None, metadata=OMIT_NONE)
    blend_kernel_error: dict[str, float] | None = field(default=None, metadata=OMIT_NONE)
    timings: dict[str, float] | None = field(default=None, metadata=OMIT_NONE)
    relight_version: str | None = field(default=None, metadata=OMIT_NONE)

    @classmethod
    def from_json(cls, data: Any) -> ChainReport:
        """From the JSON form (``chain.json``'s ``report``); unknown keys are ignored, missing ones stay None."""
        if not isinstance(data, dict):
            raise TypeError(f"a chain report is a JSON object, got {type(data).__name__}")
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})


@dataclass
class GaussianChain:
    sigma0: float
    ratio: float
    levels: list[ChainLevel]
    report: ChainReport = field(default_factory=ChainReport)

    @property
    def sigmas(self) -> FloatArray:
        return np.array([lv.sigma for lv in self.levels], dtype=np.float64)


def build_chain(
    pixels: NDArray[np.floating],
    *,
    sigma0: float | None = None,
    ratio: float = 2.0,
    levels: int | None = None,
    sigma_max: float = DEFAULT_SIGMA_MAX,
    epsilon: float = DEFAULT_EPSILON,
    size_cap: int | None = None,
    uniform_size: bool = False,
) -> GaussianChain:
    """The Gaussian chain of a lat-long map (H, W, 3) (module docstring): one projection, one synthesis per level;
    ``uniform_size`` synthesises every level at the largest size (the slices of a GPU 3-D texture,
    ``relight.gl.gaussian``)."""
    validate.in_range("chain: epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    px = require_rgb_latlong(pixels)
    h, w = px.shape[:2]
    s0 = default_sigma0(h) if sigma0 is None else sigma0
    sig = chain_sigmas(s0, ratio, levels=levels, sigma_max=sigma_max)
    cap = h if size_cap is None else validate.at_least("chain: size_cap", size_cap, 2)
    f_cap = h - 1
    t0 = time.perf_counter()
    lobes = [VonMisesFisher(float(s)) for s in sig]
    specs = [spectrum_for_tolerance(lobe, epsilon) for lobe in lobes]
    f_rho = [min(f, f_cap) for _, f in specs]
    f_proj = max(f_rho)
    t1 = time.perf_counter()
    lighting = project_lighting(px, f_proj)
    t2 = time.perf_counter()
    out: list[ChainLevel] = []
    synth = 0.0
    for lobe, (spec, _), fr in zip(lobes, specs, f_rho, strict=True):
        transfer = lobe.transfer(f_proj)
        choice = choose_orders(spec, lighting, epsilon, None, fr, f_cap, transfer)
        f_b = choice.F_B
        l_idx, _ = indexing.healpy_lm(f_b)
        b_lm = sh.truncate(lighting.alm, lighting.lmax, f_b) * transfer[: f_b + 1, 0][l_idx][None, :]
        s = cap if uniform_size else max(min(size_for_order(f_b), cap), min(MIN_SIZE, cap))
        s -= s % 2 if s > 2 else 0
        ts = time.perf_counter()
        m = sh.synthesize(b_lm, f_b, s, 2 * s).astype(np.float32)
        synth += time.perf_counter() - ts
        orders = {**dataclasses.asdict(choice.report()), "size": s}
        out.append(ChainLevel(sigma=float(lobe.sigma), map=m, orders=orders))
    report = ChainReport(
        representation="gaussian_chain",
        sigma0=float(sig[0]),
        ratio=float(ratio),
        epsilon=float(epsilon),
        sigmas=[float(x) for x in sig],
        projection_order=int(f_proj),
        input={"height": h, "width": w},
        blend_kernel_error={str(f): blend_kernel_error(ratio, f) for f in (0.25, 0.5, 0.75)},
        timings={"vmf_orders": t1 - t0, "lighting_projection": t2 - t1, "synthesis": synth,
                 "total": time.perf_counter() - t0},
        relight_version=__version__,
    )
    return GaussianChain(sigma0=float(sig[0]), ratio=float(ratio), levels=out, report=report)


def blend_kernel_error(ratio: float, frac: float, *, sigma: float = 1e-3) -> float:
    """Relative L2 error of the linear blend ``(1 - f) G_s + f G_{s ratio}`` against ``G_{s ratio^f}``.

    Closed form from the inner products of concentric vMF lobes (:func:`relight.brdf.vmf.vmf_inner`); for
    ``sigma`` << 1 it does not depend on sigma (the planar-Gaussian limit; 1e-3 rad by default).
    """
    validate.in_range("frac", frac, 0.0, 1.0)
    k = sigma_to_kappa(np.array([sigma, sigma * ratio, sigma * ratio**frac]))
    c = np.array([1.0 - frac, frac, -1.0])
    gram = vmf_inner(k[:, None], k[None, :])
    num = float(c @ gram @ c)
    return float(math.sqrt(max(num, 0.0) / float(gram[2, 2])))


def level_coordinate(chain_sigmas_: FloatArray, sigma: NDArray[np.floating]) -> FloatArray:
    """Fractional level ``x = log(sigma / sigma_0) / log(ratio)`` clamped to [0, levels - 1]."""
    s = np.asarray(chain_sigmas_, dtype=np.float64)
    sg = np.maximum(np.asarray(sigma, dtype=np.float64), 1e-300)
    if s.size == 1:
        return np.zeros_like(sg)
    x = np.log(sg / s[0]) / np.log(s[1] / s[0])
    return np.asarray(np.clip(x, 0.0, s.size - 1.0), dtype=np.float64)


def sample_chain(maps: list[NDArray[np.floating]], sigmas: FloatArray, dirs: NDArray[np.floating],
                 sigma: NDArray[np.floating]) -> FloatArray:
    """``(G_sigma * L)(d)`` approximated as a shader does: bilinear lookups in the two levels around sigma,
    blended linearly in the level coordinate (:func:`level_coordinate`). dirs (n, 3), sigma (n,) -> (n, 3)."""
    from relight.conventions import sample_latlong

    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    x = level_coordinate(sigmas, np.asarray(sigma, dtype=np.float64).reshape(-1))
    j0 = np.floor(x).astype(np.intp)
    f = x - j0
    out = np.zeros((d.shape[0], 3))
    for j, m in enumerate(maps):
        wgt = np.where(j0 == j, 1.0 - f, 0.0) + np.where(j0 + 1 == j, f, 0.0)
        sel = wgt > 0.0
        if np.any(sel):
            out[sel] += wgt[sel, None] * sample_latlong(np.asarray(m, dtype=np.float64)[None], d[sel])[:, 0]
    return out


# ------------------------------------------------------------------------------------------------------ files
def write_chain(folder: str | os.PathLike[str], chain: GaussianChain) -> dict[str, Any]:
    """Write ``level_JJ.exr`` (float16 RGB lat-long) per level and ``chain.json``; returns the manifest."""
    from relight.envmap import to_half_safe, write_exr

    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    entries = []
    clamped = 0
    for j, lv in enumerate(chain.levels):
        name = f"level_{j:02d}.exr"
        half, n = to_half_safe(lv.map)
        clamped += n
        write_exr(d / name, half.astype(np.float32), half=True)
        entries.append({"file": name, "sigma": lv.sigma, "height": int(lv.map.shape[0]),
                        "width": int(lv.map.shape[1]), "orders": lv.orders})
    man = {"format": "relight-gaussian-chain", "version": 1, "dtype": "float16", "layout": "latlong",
           "sigma0": chain.sigma0, "ratio": chain.ratio, "levels": entries, "half_clamped": clamped,
           "report": chain.report.to_json()}
    (d / MANIFEST).write_text(json.dumps(man, indent=2))
    return man


def read_chain(folder: str | os.PathLike[str]) -> GaussianChain:
    """Read a folder written by :func:`write_chain` (maps as stored: float16 values in float32 arrays)."""
    from relight.envmap import read_image

    d = Path(folder)
    p = d / MANIFEST
    if not p.is_file():
        raise InputError(f"chain: no {MANIFEST} in {os.fspath(folder)!r}")
    try:
        man = json.loads(p.read_text(encoding="utf-8"))
        entries = man["levels"]
        levels = [ChainLevel(sigma=float(e["sigma"]), map=read_image(d / str(e["file"]))[0].astype(np.float32),
                             orders=dict(e.get("orders", {}))) for e in entries]
        chain = GaussianChain(sigma0=float(man["sigma0"]), ratio=float(man["ratio"]), levels=levels,
                              report=ChainReport.from_json(man.get("report", {})))
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as exc:
        raise InputError(f"chain: {p} is not a valid chain manifest ({exc})") from None
    if not levels:
        raise InputError(f"chain: {p} has no levels")
    return chain
