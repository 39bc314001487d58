"""The ``gaussian-lobes`` material of seed 002 (Green, Kautz & Durand 2007, eq. 3, §3.2, Fig. 3).

At N view elevations theta_o (radians, increasing, in [0, pi/2)) the cosine-weighted BRDF slice is a sum of K
normalised spherical Gaussians (``relight.brdf.vmf``)::

    T~_theta_o(w) = sum_k w_k G_{sigma_k}(c_k . w),   c_k = r rotated by mu_k toward n in the plane of incidence

(``docs/conventions.md``, "Gaussian lobes": sigma and mu in radians, mu > 0 toward the normal, w_k RGB = the lobe's
integral). Between elevations every parameter is interpolated linearly (the paper's §3.2 "interpolate the
parameters of our model to in-between views"); outside [theta_0, theta_{N-1}] the end elevation is used (clamped).

JSON form (what ``relight fit`` writes, and what a user may write or edit directly, the paper's run-time editing)::

    {"kind": "gaussian-lobes",
     "elevations": [{"theta_o": 0.0, "lobes": [{"mu": 0.0, "sigma": 0.28, "weight": [0.9, 0.9, 0.9]}, ...]}, ...]}

Every elevation has the same number of lobes K (pad with ``weight`` 0). Extra keys: ``"error"`` per elevation
and a top-level ``"fit"`` report are kept and ignored. As an ``IsotropicBRDF`` (``f = T~ / cos theta_i`` above the
horizon) the material also runs through every existing pipeline (SHRM, references): an independent route to
check the Gaussian renderer (``relight.sg_render``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from relight.brdf.base import FloatArray, IsotropicBRDF
from relight.brdf.vmf import SIGMA_MAX, SIGMA_MIN, sigma_to_kappa, vmf
from relight.errors import InputError

#: Most lobes per elevation accepted in a material (texture rows; the paper uses 3 or 4).
MAX_LOBES = 16
#: Most elevations accepted.
MAX_ELEVATIONS = 256


def _num(where: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
        raise InputError(f"gaussian-lobes: {where} must be a finite number, got {v!r}")
    return float(v)


class GaussianLobes(IsotropicBRDF):
    """K Gaussian lobes at N elevations (module docstring). Arrays: ``elevations`` (N,), ``mu`` and ``sigma``
    (N, K), ``weight`` (N, K, 3); ``errors`` (N,) and ``fit`` (report) optional."""

    kind: ClassVar[str] = "gaussian-lobes"
    channels: int = 3

    def __init__(self, elevations: Any, mu: Any, sigma: Any, weight: Any, *, errors: Any = None,
                 fit: Mapping[str, Any] | None = None) -> None:
        e = np.asarray(elevations, dtype=np.float64)
        m = np.asarray(mu, dtype=np.float64)
        s = np.asarray(sigma, dtype=np.float64)
        w = np.asarray(weight, dtype=np.float64)
        if e.ndim != 1 or not 1 <= e.size <= MAX_ELEVATIONS:
            raise InputError(f"gaussian-lobes: need 1..{MAX_ELEVATIONS} elevations, got shape {e.shape}")
        n = e.size
        if m.ndim != 2 or m.shape[0] != n or not 1 <= m.shape[1] <= MAX_LOBES or s.shape != m.shape:
            raise InputError(f"gaussian-lobes: mu and sigma must be (N, K) with N = {n}, 1 <= K <= {MAX_LOBES}, got "
                             f"{m.shape} and {s.shape}")
        if w.shape == m.shape:
            w = np.repeat(w[..., None], 3, axis=-1)
        if w.shape != m.shape + (3,):
            raise InputError(f"gaussian-lobes: weight must be (N, K, 3), got {w.shape}")
        for name, a in (("theta_o", e), ("mu", m), ("sigma", s), ("weight", w)):
            if not np.all(np.isfinite(a)):
                raise InputError(f"gaussian-lobes: {name} values must be finite")
        if e[0] < 0.0 or e[-1] >= math.pi / 2 or np.any(np.diff(e) <= 0.0):
            raise InputError(f"gaussian-lobes: theta_o must increase strictly within [0, pi/2), got "
                             f"{np.round(e, 6).tolist()}")
        if np.any(np.abs(m) > math.pi / 2):
            raise InputError(f"gaussian-lobes: mu must lie in [-pi/2, pi/2], got {m.ravel()[np.argmax(np.abs(m))]!r}")
        if np.any(s < SIGMA_MIN) or np.any(s > SIGMA_MAX):
            raise InputError(f"gaussian-lobes: sigma must lie in [{SIGMA_MIN:g}, {SIGMA_MAX:.6g}] radians, got "
                             f"{s.min():g} .. {s.max():g}")
        if np.any(w < 0.0):
            raise InputError(f"gaussian-lobes: weights must be >= 0, got {w.min():g}")
        self.elevations, self.mu, self.sigma, self.weight = e, m, s, w
        self.errors = None if errors is None else np.asarray(errors, dtype=np.float64)
        self.fit: dict[str, Any] = dict(fit or {})

    @property
    def n_lobes(self) -> int:
        return int(self.mu.shape[1])

    # ------------------------------------------------------------------------------------------------ lookup
    def params_at(self, theta_o: NDArray[np.floating]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(mu, sigma, weight) linearly interpolated at elevations theta_o (...,): (..., K), (..., K), (..., K, 3)."""
        t = np.clip(np.asarray(theta_o, dtype=np.float64), self.elevations[0], self.elevations[-1])
        e = self.elevations
        if e.size == 1:
            j = np.zeros(t.shape, dtype=np.intp)
            f = np.zeros(t.shape)
            nxt = j
        else:
            j = np.clip(np.searchsorted(e, t, side="right") - 1, 0, e.size - 2)
            f = (t - e[j]) / (e[j + 1] - e[j])
            nxt = j + 1
        fk = f[..., None]
        mu = self.mu[j] * (1.0 - fk) + self.mu[nxt] * fk
        sg = self.sigma[j] * (1.0 - fk) + self.sigma[nxt] * fk
        w = self.weight[j] * (1.0 - fk[..., None]) + self.weight[nxt] * fk[..., None]
        return mu, sg, w

    def transfer(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        """``T~(wi)`` for the view wo at normal n (unit vectors (..., 3)), shape (..., 3); 0 below the horizon."""
        ndv = np.clip(np.einsum("...k,...k->...", n, wo), -1.0, 1.0)
        theta_o = np.arccos(np.clip(ndv, 0.0, 1.0))
        r = 2.0 * ndv[..., None] * n - wo
        mu, sg, w = self.params_at(theta_o)
        c = lobe_centres(n, r, mu)
        t = np.einsum("...kj,...j->...k", c, np.broadcast_to(wi, r.shape))
        g = vmf(t, sigma_to_kappa(sg))  # (..., K)
        val = np.einsum("...k,...kc->...c", g, w)
        up = np.einsum("...k,...k->...", n, wi) > 0.0
        return np.asarray(np.where(up[..., None], val, 0.0), dtype=np.float64)

    def f(self, wi: FloatArray, wo: FloatArray, n: FloatArray) -> FloatArray:
        cos_i = np.einsum("...k,...k->...", n, wi)
        return np.asarray(self.transfer(wi, wo, n) / np.maximum(cos_i, 1e-12)[..., None], dtype=np.float64)

    # ------------------------------------------------------------------------------------------------ JSON
    def elevation_entries(self) -> list[dict[str, Any]]:
        out = []
        for i, th in enumerate(self.elevations):
            entry: dict[str, Any] = {"theta_o": float(th)}
            if self.errors is not None:
                entry["error"] = float(self.errors[i])
            entry["lobes"] = [{"mu": float(self.mu[i, k]), "sigma": float(self.sigma[i, k]),
                               "weight": [float(x) for x in self.weight[i, k]]} for k in range(self.n_lobes)]
            out.append(entry)
        return out

    def params(self) -> dict[str, Any]:
        out: dict[str, Any] = {"elevations": self.elevation_entries()}
        if self.fit:
            out["fit"] = self.fit
        return out

    @classmethod
    def from_spec(cls, elevations: Any, fit: Any = None, **extra: Any) -> GaussianLobes:
        """From the JSON form's ``elevations`` list (module docstring)."""
        if extra:
            raise InputError(f"gaussian-lobes: unknown key {sorted(extra)[0]!r}; valid keys are ['elevations', 'fit']")
        if not isinstance(elevations, list) or not elevations:
            raise InputError("gaussian-lobes: 'elevations' must be a non-empty list of {theta_o, lobes}")
        th, mu, sg, wt, err = [], [], [], [], []
        k_count = None
        for i, e in enumerate(elevations):
            if not isinstance(e, Mapping) or "theta_o" not in e or "lobes" not in e:
                raise InputError(f"gaussian-lobes: elevations[{i}] must be an object with theta_o and lobes")
            th.append(_num(f"elevations[{i}].theta_o", e["theta_o"]))
            lobes = e["lobes"]
            if not isinstance(lobes, list) or not lobes:
                raise InputError(f"gaussian-lobes: elevations[{i}].lobes must be a non-empty list")
            if k_count is None:
                k_count = len(lobes)
            elif len(lobes) != k_count:
                raise InputError(f"gaussian-lobes: every elevation needs the same number of lobes ({k_count}); "
                                 f"elevations[{i}] has {len(lobes)} (pad with weight 0)")
            row_m, row_s, row_w = [], [], []
            for k, lobe in enumerate(lobes):
                where = f"elevations[{i}].lobes[{k}]"
                if not isinstance(lobe, Mapping) or set(lobe) != {"mu", "sigma", "weight"}:
                    raise InputError(f"gaussian-lobes: {where} must have exactly mu, sigma and weight")
                row_m.append(_num(where + ".mu", lobe["mu"]))
                row_s.append(_num(where + ".sigma", lobe["sigma"]))
                wv = lobe["weight"]
                wl = [wv] if not isinstance(wv, list) else wv
                if len(wl) not in (1, 3):
                    raise InputError(f"gaussian-lobes: {where}.weight must be a number or [r, g, b]")
                vals = [_num(where + ".weight", x) for x in wl]
                row_w.append(vals * 3 if len(vals) == 1 else vals)
            mu.append(row_m)
            sg.append(row_s)
            wt.append(row_w)
            if "error" in e:
                err.append(_num(f"elevations[{i}].error", e["error"]))
        errors = err if len(err) == len(th) else None
        return cls(th, mu, sg, wt, errors=errors, fit=fit if isinstance(fit, Mapping) else None)


def lobe_centres(n: FloatArray, r: FloatArray, mu: FloatArray) -> FloatArray:
    """Lobe centres ``c_k = cos(mu_k) r + sin(mu_k) e`` (..., K, 3), e the unit vector along n's component
    perpendicular to r (toward n, in the plane of incidence). Where r = n (theta_o = 0: no plane) any perpendicular
    is used: mu is 0 there by symmetry, so c = r and no NaN arises."""
    nr = np.einsum("...k,...k->...", n, r)
    e = n - nr[..., None] * r
    norm = np.linalg.norm(e, axis=-1, keepdims=True)
    alt = np.cross(r, np.where(np.abs(r[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])))
    alt = alt / np.maximum(np.linalg.norm(alt, axis=-1, keepdims=True), 1e-300)
    e = np.where(norm > 1e-9, e / np.maximum(norm, 1e-300), alt)
    m = np.asarray(mu, dtype=np.float64)[..., None]
    return np.asarray(np.cos(m) * r[..., None, :] + np.sin(m) * e[..., None, :], dtype=np.float64)
