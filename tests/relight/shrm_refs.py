"""Shared references for the SHRM tests (tests/relight/test_shrm_*.py).

Accuracy tests compare the eq. 12 map of an SHRM with ``relight.reference_view`` (brute-force eq. 1 over the
environment's pixels, independent of every SH routine) on sample maps area-averaged to 64 x 128, output 32 x 64.
A single view's R-indexed map contains every normal-view angle from 0 to 90 degrees (N = normalize(R + V)), so each
view covers grazing configurations; errors are measured on the R pixels whose angle between N and V is at most
89 degrees (``masked_rms``), and separately on the grazing band 70–89 degrees.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from relight import indexing, shrm
from relight.brdf.spec import parse_brdf
from relight.conventions import latlong_dirs
from relight.envmap import read_envmap, resample_latlong
from relight.metrics import relative_rms
from relight.reference_view import reference_view

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
S = 32  # output rows of the accuracy tests
VIEWS = [(0.0, 0.0, 1.0), (0.2, 0.95, 0.1), (-0.6, -0.3, 0.7)]
#: A single view's band error against the predicted orientation average's ``rms`` (check_against_reference).
SINGLE_VIEW = 3.0


@cache
def env(name: str = "courtyard", rows: int = 64) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


def masked_rms(a: np.ndarray, ref: np.ndarray, view: np.ndarray, lo_deg: float = 0.0, hi_deg: float = 89.0) -> float:
    """Relative RMS over the R pixels whose angle between N = normalize(R + V) and V lies in [lo, hi] degrees."""
    s = a.shape[0]
    v = np.asarray(view, float) / np.linalg.norm(view)
    n, ok = shrm.halfway_normals(latlong_dirs(s, 2 * s), v)
    ang = np.degrees(np.arccos(np.clip(n @ v, -1.0, 1.0)))
    keep = (ok & (ang >= lo_deg) & (ang <= hi_deg))[..., None]
    return relative_rms(np.where(keep, a, 0.0), np.where(keep, ref, 0.0))


def random_inputs(f: int, p: int, rng: np.random.Generator, channels: int = 3) -> tuple[np.ndarray, np.ndarray]:
    l, m = indexing.healpy_lm(f)
    alm = (rng.standard_normal((channels, l.size)) + 1j * rng.standard_normal((channels, l.size))) / np.sqrt(1 + l)
    alm[:, m == 0] = alm[:, m == 0].real
    rho = rng.standard_normal((f + 1, p + 1, p + 1, 1)) / (1.0 + np.arange(f + 1))[:, None, None, None]
    return alm, rho


def check_against_reference(spec: str, view: tuple[float, float, float], f_hi: int, size: int, p_hi: int = 12,
                             tol_89: float = 0.035, tol_80: float = 0.02, env_rows: int = 64) -> None:
    """The eq. 12 map of SHRMs for one view against ``reference_view``; tolerances:

    * orders chosen for epsilon = 0.03: per band of the report's ``predicted.by_view`` (issue 18; N.V in [0, 0.3],
      [0.3, 0.7], [0.7, 1], i.e. angles between N and V of 72.5-90, 45.6-72.5 and 0-45.6 degrees) the view's relative
      RMS m is at most ``SINGLE_VIEW`` (3) times the predicted ``rms`` in every band, and at least ``rms / 3 -
      0.005 / 3`` in the bands N.V >= 0.3. One view is one slice of the lighting's orientations, not their average
      (which tests/relight/test_view_bands.py holds to [m, 3 m + 0.005] in every band, rim included): over 40 views
      of courtyard (microfacet sigma = 0.1, whole rings of 400 texels per band) a single view's band error spread
      over 0.52-1.57 times ``rms`` above N.V = 0.3, hence 3 both ways there, and over 0.36-2.65 times at the rim,
      where one view can fall further below (0.30 for sigma = 0.2 at VIEWS[1]): there only the upper side holds
      for a single view. (Before issue 18 the check was m <= sqrt(epsilon_brdf) over 0-89 degrees, 4-10 times above
      the measurement and with no lower side: a prediction ten times too large passed.)
    * generous orders (F_hi, P_hi): below ``tol_89`` over 0-89 degrees and ``tol_80`` over 0-80 degrees (measured
      1-2.5 % and 0.5-1.5 % for microfacet at P = 12, 2.5-3.7 % and 1-2 % for skin at P = 16);
    * grazing band 70-89 degrees: the error falls by at least 30 % from P = 4 to P_hi — near grazing rho_hat varies
      fastest with theta_o, so the SHRM converges there slowly but surely in P (microfacet ~0.15 -> ~0.06).
    """
    e = env(rows=env_rows)
    lobe = parse_brdf(spec)
    v = np.array(view)
    ref = reference_view(e, lobe, v, size)
    assert np.all(np.isfinite(ref)) and ref.max() > 0
    sm = shrm.create_shrm(e, lobe, epsilon=0.03, size=size)
    got = shrm.reflect(sm, v)
    for band in sm.report["predicted"]["by_view"]:
        lo, hi = band["ndotv"]
        m = masked_rms(got, ref, v, lo_deg=float(np.degrees(np.arccos(hi))), hi_deg=float(np.degrees(np.arccos(lo))))
        rms = band["rms"]
        assert m <= SINGLE_VIEW * rms, (spec, view, band["ndotv"], m, rms)
        if lo >= 0.3:
            assert m >= rms / SINGLE_VIEW - 0.005 / SINGLE_VIEW, (spec, view, band["ndotv"], m, rms)
    lo_p = shrm.reflect(shrm.create_shrm(e, lobe, order=f_hi, p_order=4, size=size), v)
    hi_p = shrm.reflect(shrm.create_shrm(e, lobe, order=f_hi, p_order=p_hi, size=size), v)
    assert masked_rms(hi_p, ref, v) < tol_89
    assert masked_rms(hi_p, ref, v, hi_deg=80.0) < tol_80
    assert masked_rms(hi_p, ref, v, lo_deg=70.0) < 0.7 * masked_rms(lo_p, ref, v, lo_deg=70.0)
