"""Cost model of prefiltering (seed 000 §6.2 Table 3, App. C, App. D), calibrated on the running machine.

Seed 000 Table 3 gives the asymptotic costs: ``O(F_B S_B^2)`` for a radially symmetric (1-D) lobe,
``O(F_B P_B^2 S_B^2)`` for an SHRM, and ``O(W S_L^2 S_B^2)`` for the angular method, W the fraction of the
environment's pixels a lobe touches (App. D). Here each stage of relight's pipeline gets a linear model
``t = sum_k c_k phi_k`` in features ``phi_k`` counted from the operation's sizes and orders, and the constants
``c_k`` (seconds per unit) are fitted by non-negative least squares on relative error to a few timed runs on this
machine (:func:`calibrate`, a few seconds), cached in a JSON file keyed by machine and relight version
(:func:`load_calibration`).

Modules: :mod:`~relight.costmodel.features` (the stages' features), :mod:`~relight.costmodel.angular` (the angular
method's pairs and evaluations, on ``relight.reference_view.block_plan``), :mod:`~relight.costmodel.timing` (seconds
per lobe evaluation), :mod:`~relight.costmodel.calibration` (the fit and the timed runs) and
:mod:`~relight.costmodel.store` (the cache file). This package re-exports their public names.

Notes: the terms
----------------
``C`` colour channels (3), ``S_L x 2 S_L`` input, ``S_B x 2 S_B`` output, orders F, P.

* **SH projection of the lighting** (App. C step 1, ``relight.prefilter.project_lighting``). The paper's separable
  algorithm costs ``O(F S_L^2)``: a direct DFT over phi for 2F + 1 values of m on every ring. ducc0 does that step
  by FFT, ``O(S_L^2 log S_L)``, and keeps the paper's ``O(F^2 S_L)`` Legendre sums over theta, so the features are
  ``proj_call = C``, ``proj_px = C S_L 2S_L log2(2 S_L)`` and ``proj_leg = C S_L (F + 1)^2``.
* **Synthesis** (App. C step 3, eq. 14): one ducc0 synthesis per map, colour and ``|q|`` group; with S ~ 10 F the
  Legendre part ``S_B (F + 1)^2`` is the paper's ``F S_B^2`` per map, ``(P + 1)^2`` maps for a general SHRM,
  P + 1 without azimuthal dependence, 1 for a radial lobe (Table 3's ``F_B P_B^2 S_B^2``). Spin-weighted syntheses
  (q != 0, two output fields) get their own constants: ``syn_px``/``syn_leg`` (q = 0) and ``synq_px``/``synq_leg``
  (``S_B 2S_B log2(2 S_B)`` and ``S_B (F + 1)^2`` summed over the syntheses), plus ``syn_call`` per call and
  ``comp_call`` per component (its report and predicted errors).
* **BRDF coefficients** (App. C step 1). A radial lobe's ``Lambda_l rho_l`` by composite quadrature costs
  ``O(F S_rho)`` with S_rho the quadrature nodes (about ``32 (F + 2)``, more for narrow lobes): ``lobe1d = sum over
  the order search's probes of (F + 1) x nodes`` (:func:`radial_nodes`), and the ringing bound
  ``ring = (F_B + 1) x samples`` (:func:`ringing_work`), both ``O(F^2)``. A general lobe is tabulated on the
  ``S_rho x T_rho x T_rho`` grid of ``relight.brdf.lpq`` for every probe of the order search, ``O(P S_rho
  T_rho^2)``: ``brdf_evals`` = grid points x this lobe's seconds per ``rho_hat`` evaluation (measured live by
  :func:`lobe_eval_seconds`, so a costly model such as Torrance–Sparrow is priced as such) and ``brdf_ops`` =
  grid points x (Q + 1) for the cosine transform and Legendre sums.
* **One view** (eq. 8 and eq. 12, ``relight.shrm.reflect`` on a fresh SHRM): ``view_base = S_B 2S_B`` (the
  normals of every pixel), ``view_px`` = maps x ``S_B 2S_B`` (the eq. 12 sum), ``eq8_px = sum_p (2p + 1)^2
  S_B 2S_B`` (eq. 8's rotation of a general component) and ``lookup_px = S_B 2S_B`` per N- or T-centred component
  (its bilinear lookup at N or T(N)).
* **Angular method** (``relight.reference.reference_radial``): ``ang_pairs`` = (output pixel, input pixel) pairs
  visited. App. D's ``W = (1 - cos theta*) / 2`` counts the pixels inside the lobe's cone; this implementation visits
  the whole latitude band that can meet the cone, ``W_band ~ 2 theta* / pi`` of the rows, so ``ang_pairs =
  W_band S_L 2S_L S_B 2S_B`` exactly (:func:`angular_pairs`; the tradeoff reports both W). For view-dependent
  BRDFs (``relight.reference_view``): ``angv_pairs`` pairs visited and ``angv_evals`` = lobe evaluations (the pairs
  inside the cones, or every pair of a row block that code evaluates densely, ``reference_view.DENSE_FRACTION``) x
  seconds per evaluation (:func:`integrand_eval_seconds`, timed the way that code evaluates the lobe), counted on the
  very blocks that code runs (``reference_view.block_plan``; :func:`angular_view_counts`).
* ``lobe_call`` and ``ring_call``: fixed costs per lobe and per ringing bound (Python overheads);
  ``call`` (1 per prefilter) and ``conv = (F + 1)^2``: order selection (power spectra) and the convolution
  ``B_lm = Lambda_l rho_l L_lm`` (App. C step 2, ``O(F_B^2)`` for radial lobes).

The fit is per stage (each stage's features against that stage's own timings from the reports), which keeps every
constant determined by the runs that exercise it. Predictions are for the machine the calibration ran on; the
machines are noisy, so :class:`Calibration` keeps the in-sample ratio of predicted to measured time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from relight import lazy

if TYPE_CHECKING:
    from relight.costmodel.angular import (
        angular_features,
        angular_pairs,
        angular_view_counts,
        angular_view_features,
    )
    from relight.costmodel.calibration import (
        CAL_ANGULAR,
        CAL_RADIAL,
        CAL_SHRM,
        CAL_VIEW,
        DEFAULT_CONSTANTS,
        Calibration,
        Prediction,
        calibrate,
        calibration_key,
        default_calibration,
        fit,
        machine_info,
        report_stages,
    )
    from relight.costmodel.features import (
        CHANNELS,
        FEATURES,
        STAGES,
        LobePlan,
        add_features,
        brdf_features,
        n_maps,
        prefilter_report_features,
        probe_orders,
        projection_features,
        radial_features,
        radial_nodes,
        radial_probes,
        ringing_work,
        shrm_features,
        shrm_lobe_plans,
        shrm_report_features,
        synthesis_counts,
        synthesis_features,
        tabulation_points,
        view_features,
    )
    from relight.costmodel.store import (
        cache_dir,
        cache_path,
        forget,
        load_calibration,
        save_calibration,
    )
    from relight.costmodel.timing import (
        integrand_eval_seconds,
        lobe_eval_seconds,
    )

#: Public name -> defining module, imported on first use (PEP 562): importing the package stays cheap.
_EXPORTS: dict[str, str] = {
    "CAL_ANGULAR": "calibration",
    "CAL_RADIAL": "calibration",
    "CAL_SHRM": "calibration",
    "CAL_VIEW": "calibration",
    "CHANNELS": "features",
    "Calibration": "calibration",
    "DEFAULT_CONSTANTS": "calibration",
    "FEATURES": "features",
    "LobePlan": "features",
    "Prediction": "calibration",
    "STAGES": "features",
    "add_features": "features",
    "angular_features": "angular",
    "angular_pairs": "angular",
    "angular_view_counts": "angular",
    "angular_view_features": "angular",
    "brdf_features": "features",
    "cache_dir": "store",
    "cache_path": "store",
    "calibrate": "calibration",
    "calibration_key": "calibration",
    "default_calibration": "calibration",
    "fit": "calibration",
    "forget": "store",
    "integrand_eval_seconds": "timing",
    "load_calibration": "store",
    "lobe_eval_seconds": "timing",
    "machine_info": "calibration",
    "n_maps": "features",
    "prefilter_report_features": "features",
    "probe_orders": "features",
    "projection_features": "features",
    "radial_features": "features",
    "radial_nodes": "features",
    "radial_probes": "features",
    "report_stages": "calibration",
    "ringing_work": "features",
    "save_calibration": "store",
    "shrm_features": "features",
    "shrm_lobe_plans": "features",
    "shrm_report_features": "features",
    "synthesis_counts": "features",
    "synthesis_features": "features",
    "tabulation_points": "features",
    "view_features": "features",
}

__all__ = [
    "CAL_ANGULAR",
    "CAL_RADIAL",
    "CAL_SHRM",
    "CAL_VIEW",
    "CHANNELS",
    "Calibration",
    "DEFAULT_CONSTANTS",
    "FEATURES",
    "LobePlan",
    "Prediction",
    "STAGES",
    "add_features",
    "angular_features",
    "angular_pairs",
    "angular_view_counts",
    "angular_view_features",
    "brdf_features",
    "cache_dir",
    "cache_path",
    "calibrate",
    "calibration_key",
    "default_calibration",
    "fit",
    "forget",
    "integrand_eval_seconds",
    "load_calibration",
    "lobe_eval_seconds",
    "machine_info",
    "n_maps",
    "prefilter_report_features",
    "probe_orders",
    "projection_features",
    "radial_features",
    "radial_nodes",
    "radial_probes",
    "report_stages",
    "ringing_work",
    "save_calibration",
    "shrm_features",
    "shrm_lobe_plans",
    "shrm_report_features",
    "synthesis_counts",
    "synthesis_features",
    "tabulation_points",
    "view_features",
]


__getattr__, __dir__ = lazy.exports(__name__, _EXPORTS)
