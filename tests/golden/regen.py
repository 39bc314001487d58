"""Golden outputs: a small fixed set of computations whose numbers must not change unless
``relight.ALGORITHM_VERSION`` is bumped (issue 11 item 7; ``tests/relight/test_golden.py``).

The set covers each numerical path a result depends on: the radial prefilter of a tiny synthetic map (Phong and
Lambert: orders, ``B_lm`` and the map), an SHRM of a microfacet lobe on it and its eq. 12 view, the BRDF's SHRM
coefficients ``rho_hat_lpq`` (App. C), and the orders and predicted errors of a scene plan and of a job plan.

Each output array is rounded before hashing to :data:`DIGITS` significant digits *relative to the array's scale*
(``10 ** ceil(log10 max|x|)``): the quantum is ``scale * 10 ** -DIGITS``, so values at the noise level of that array
(an exact zero computed as 1e-17) cannot flip the hash, and BLAS or FFT reordering (relative 1e-15 .. 1e-13 between
machines) moves a value across a rounding boundary with probability about 1e-6 per value, about 1e-3 per run of
this set (a few thousand values). Integers (orders) are hashed exactly.

Regenerate (after bumping ``relight.ALGORITHM_VERSION`` in ``relight/__init__.py``), from the repository root::

    python -m tests.golden.regen
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

import relight

#: Significant digits kept, relative to each array's power-of-ten scale (module docstring).
DIGITS = 8
GOLDEN = Path(__file__).with_name("golden.json")
#: Rows of the synthetic map (16 x 32): small enough that the whole set runs in about a second.
ROWS = 16
VIEW = (0.3, 0.5, 0.8)


def synthetic_map(rows: int = ROWS) -> np.ndarray:
    """An analytic, deterministic RGB lat-long map: a sky gradient, a soft sun and a coloured horizon band."""
    from relight.conventions import latlong_dirs

    d = latlong_dirs(rows, 2 * rows)  # (H, W, 3), +Y up (docs/conventions.md)
    sun = np.array([0.5, 0.6, 0.62])
    sun /= np.linalg.norm(sun)
    glow = np.clip(d @ sun, 0.0, None) ** 16
    sky = 0.3 + 0.2 * d[..., 1]
    band = np.exp(-((d[..., 1] / 0.2) ** 2))
    rgb = np.stack([sky + 3.0 * glow + 0.4 * band, sky + 2.5 * glow + 0.2 * band, 1.2 * sky + 2.0 * glow], axis=-1)
    return np.asarray(rgb, dtype=np.float64)


def _prefilter(lobe_spec: str) -> dict[str, Any]:
    from relight.brdf.spec import parse_brdf
    from relight.prefilter import prefilter_radial

    res = prefilter_radial(synthetic_map(), parse_brdf(lobe_spec), epsilon=0.01, size=8)  # type: ignore[arg-type]
    o = res.report.orders
    return {"orders": [o.F_rho, o.F_L if o.F_L is not None else -1, o.F_B], "coefficients": res.coefficients,
            "map": res.map, "predicted": np.array([o.epsilon_min_of_errors, o.epsilon_appendix_b], dtype=float)}


def _shrm() -> dict[str, Any]:
    from relight.brdf.models import Microfacet
    from relight.shrm import create_shrm, reflect

    sm = create_shrm(synthetic_map(), Microfacet(0.3), order=6, p_order=2, size=8)
    (comp,) = sm.components
    return {"orders": [comp.F, comp.P], "maps": comp.maps, "view": reflect(sm, np.array(VIEW))}


def _shrm_coefficients() -> dict[str, Any]:
    from relight.brdf import lpq
    from relight.brdf.models import Microfacet

    c = lpq.brdf_coefficients(Microfacet(0.3), 8, 4)
    return {"rho": c.rho}


def _scene_plan() -> dict[str, Any]:
    from relight import costmodel, planning

    scene = planning.scene_from_dict({"environment": "golden", "epsilon": 0.05, "size": 8, "objects": [
        {"name": "a", "size": 1, "distance": 3, "material": "lambert+phong:s=32"},
        {"name": "b", "size": 1, "distance": 30, "material": "microfacet:sigma=0.3"}]})
    rep = planning.plan_scene(scene, synthetic_map(), calibration=costmodel.default_calibration()).report
    orders = [[c.F_rho, c.P_rho, c.F_L if c.F_L is not None else -1, c.F_B, c.P_B, c.n_maps] for c in rep.computations]
    errors = [c.predicted.get("epsilon_min_of_errors", math.nan) for c in rep.computations]
    return {"orders": orders, "lighting": [rep.lighting.F_proj], "errors": np.array(errors)}


def _job_plan() -> dict[str, Any]:
    from relight import costmodel
    from relight.planning import plan_job
    from relight.prefilter import project_lighting

    lig = project_lighting(synthetic_map(), ROWS - 1)
    info = {"height": ROWS, "width": 2 * ROWS, "sh_power_spectrum": lig.band_energy().tolist(),
            "total_energy": lig.total_energy}
    out: dict[str, Any] = {}
    for spec in ({"kind": "phong", "s": 32.0}, {"kind": "microfacet", "sigma": 0.3}):
        p = plan_job(info, spec, {"epsilon": 0.05}, calibration=costmodel.default_calibration())
        out[spec["kind"]] = [p.orders.F_rho or -1, p.orders.F_L if p.orders.F_L is not None else -1, p.orders.F_B,
                             p.orders.P_B, p.size]
        out[spec["kind"] + "_errors"] = np.array([p.predicted_error.epsilon_min_of_errors,
                                                  p.predicted_error.epsilon_appendix_b], dtype=float)
    return out


#: The golden set: name -> computation returning named arrays (floats, rounded) and integer lists (exact).
COMPUTATIONS: dict[str, Callable[[], dict[str, Any]]] = {
    "prefilter_phong": lambda: _prefilter("phong:s=32"),
    "prefilter_lambert": lambda: _prefilter("lambert"),
    "shrm_microfacet": _shrm,
    "shrm_coefficients_microfacet": _shrm_coefficients,
    "scene_plan": _scene_plan,
    "job_plan": _job_plan,
}


def quantize(values: Any) -> dict[str, Any]:
    """The hashed form of one output (module docstring): integers as they are; floats (real and imaginary parts of
    complex values alike) as integer multiples of ``10 ** (e - DIGITS)`` with ``10 ** e`` the array's scale."""
    a = np.asarray(values)
    if a.dtype.kind in "iub":
        return {"shape": list(a.shape), "int": a.astype(np.int64).ravel().tolist()}
    parts = np.stack([a.real, a.imag], axis=-1) if a.dtype.kind == "c" else a.astype(np.float64)
    finite = np.isfinite(parts)
    peak = float(np.abs(parts[finite]).max()) if finite.any() else 0.0
    e = math.ceil(math.log10(peak)) if peak > 0.0 else 0
    q = np.where(finite, np.round(np.where(finite, parts, 0.0) / 10.0 ** (e - DIGITS)), 0.0).astype(np.int64)
    return {"shape": list(a.shape), "exp": e, "q": q.ravel().tolist(), "nonfinite": np.flatnonzero(~finite).tolist()}


def digest(outputs: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of every quantized output, keyed by name."""
    payload = {k: quantize(v) for k, v in sorted(outputs.items())}
    return hashlib.sha256(json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def compute() -> dict[str, dict[str, Any]]:
    """Per computation: its digest, the number of values and each array's scale (to see what moved)."""
    out: dict[str, dict[str, Any]] = {}
    for name, fn in COMPUTATIONS.items():
        outputs = fn()
        out[name] = {"sha256": digest(outputs),
                     "values": int(sum(np.asarray(v).size for v in outputs.values())),
                     "scales": {k: quantize(v).get("exp") for k, v in sorted(outputs.items())}}
    return out


def main() -> None:
    data = {"algorithm_version": relight.ALGORITHM_VERSION, "digits": DIGITS, "computations": compute()}
    GOLDEN.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    print(f"wrote {GOLDEN} for ALGORITHM_VERSION {relight.ALGORITHM_VERSION}: {len(data['computations'])} "
          "computations")


if __name__ == "__main__":
    main()
