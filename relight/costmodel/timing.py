"""Seconds per lobe evaluation, measured live for the cost model (seed 000 App. C: a BRDF's tabulation and the angular
method both cost evaluations times this). Cached per lobe spec for the process."""

from __future__ import annotations

import json
import math
import threading
import time

import numpy as np

from relight.brdf.base import Lobe

_eval_cache: dict[str, float] = {}
_eval_lock = threading.Lock()


def lobe_eval_seconds(lobe: Lobe, *, repeat: int = 5) -> float:
    """Seconds per ``rho_hat`` evaluation of this lobe (best of ``repeat`` on a 16^3 grid), cached per spec."""
    try:
        key: str | None = json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        key = None
    if key is not None and key in _eval_cache:
        return _eval_cache[key]
    n = 16
    t = (np.arange(n) + 0.5) * np.pi / n
    ti, to, ph = t[:, None, None], t[None, :, None], t[None, None, :]
    best = math.inf
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        lobe.rho_hat(ti, to, ph)
        best = min(best, time.perf_counter() - t0)
    per = best / n**3
    if key is not None:
        with _eval_lock:
            _eval_cache[key] = per
    return per

def integrand_eval_seconds(lobe: Lobe, *, repeat: int = 5) -> float:
    """Seconds per lobe evaluation the way ``relight.reference_view`` evaluates it: ``u(C . w)`` for a radial lobe,
    ``f(w, V, N)`` for a general isotropic BRDF, ``rho_hat`` otherwise (best of ``repeat`` on 4096 samples)."""
    from relight.brdf.base import IsotropicBRDF, RadialLobe

    try:
        key: str | None = json.dumps(["integrand", type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        key = None
    if key is not None and key in _eval_cache:
        return _eval_cache[key]
    if not isinstance(lobe, RadialLobe | IsotropicBRDF):
        return lobe_eval_seconds(lobe, repeat=repeat)
    n = 4096
    r = np.random.default_rng(0)
    w = r.standard_normal((n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    v = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (n, 3))
    nrm = np.broadcast_to(np.array([0.0, 0.6, 0.8]), (n, 3))
    best = math.inf
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        if isinstance(lobe, RadialLobe):
            lobe.u(w[:, 2])
        else:
            lobe.f(w, v, nrm)
        best = min(best, time.perf_counter() - t0)
    per = best / n
    if key is not None:
        with _eval_lock:
            _eval_cache[key] = per
    return per


def _eval_cache_put(lobe: Lobe, seconds: float) -> None:
    try:
        key = json.dumps([type(lobe).__qualname__, lobe.spec()], sort_keys=True)
    except (TypeError, ValueError):
        return
    with _eval_lock:
        _eval_cache[key] = seconds
