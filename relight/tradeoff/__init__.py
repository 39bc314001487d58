"""Accuracy against time: the frequency method at several tolerances and the angular method at several truncations
(seed 000 §5.1, §6.2 Table 3, §7.4 Tables 4–5, App. D).

:func:`sweep` runs, for one (environment, BRDF) pair on one output grid (``S x 2S``):

* the **frequency method** for every tolerance ``epsilon``: a reflection map (``relight.prefilter.prefilter_radial``)
  for a single radially symmetric lobe, otherwise an SHRM (``relight.shrm.create_shrm``) and its eq. 12 map for one
  distant view (``relight.shrm.reflect``), since the angular method produces one view's map too (Table 5);
* the **angular method** (``relight.reference.reference_radial`` / ``relight.reference_view.reference_view``) for
  every lobe truncation (App. D: the cone holding ``1 - truncation`` of the lobe);
* the **reference**: the angular method without truncation (every pixel of the sphere), the ground truth of every
  measured error.

Each point records the predicted error (the frequency method's minimum-of-errors estimate ``sqrt(epsilon_B)``,
§5.1, with App. B's bound alongside; the angular method's dropped lobe fraction, which is its exact relative error
for a uniform environment), the measured error (``relight.metrics.relative_rms`` against the reference), the
predicted seconds (``relight.costmodel``, for the orders the run chose) and the measured seconds (wall clock; the
BRDF coefficient cache is cleared first, so every point pays for its own order search; runs under a quarter second
are repeated and the fastest kept). ``pareto`` marks the points
no other point of the same method beats in both measured error and measured time; ``pareto_overall`` the same over
both methods.

**Against Mitsuba 3.** When the material has an exact Mitsuba 3 twin (``relight.mitsuba_twin.twin``:
Torrance–Sparrow with ``fresnel="none"``, Beckmann or GGX, and Lambert), Mitsuba is installed and the map can be
shown to it exactly (H even), every point also records ``mitsuba_error``: its error against an independent renderer.
Mitsuba renders once per sweep (the image does not depend on the point): a unit sphere under the map, seen by an
orthographic camera along the sweep's view (``view``, also for view-independent maps), direct light only,
:class:`~relight.mitsuba_compare.TwinSettings` (64 x 64 pixels, 8192 samples per pixel). Each point's output map
becomes the same image (per sub-pixel, 4 x 4 per pixel: N from the sphere, ``R = 2 (N.V) N - V``, the map looked up
bilinearly at its centre direction: R for view maps and R-centred lobes, N for Lambert's map), and the two images
are compared on 4 x 4-pixel block means of Rec. 709 luminance over the blocks lying entirely within image radius
0.8 (N within 53 degrees of V; grazing views are excluded, where both the SHRM's orders and the pixel footprints
diverge): ``mitsuba_error`` is the relative RMS over those blocks. ``image_error`` is the same metric against the
angular reference's image instead of Mitsuba's, so that it can be compared with ``mitsuba_error`` on equal terms;
the sphere-wide ``measured_error`` is not comparable with either: it also counts grazing views, where an SHRM's
error is largest.

``meta.mitsuba`` (:class:`~relight.tradeoff.report.MitsubaComparison`) records the settings, the render's seconds
(not part of any point's), and two floors:

* ``noise``: the relative RMS of the blocks' Monte Carlo standard deviations (estimated by Mitsuba's ``moment``
  integrator from the render's own samples): the expected ``mitsuba_error`` of a perfect map. It is 1.5–5.5e-3 on
  the five sample maps (64 rows; Beckmann 0.05 and 0.2, GGX 0.2, Lambert) at the default settings, for renders of
  2–6 s on a 2-core machine (``llvm_ad_rgb``), so ``mitsuba_error`` resolves errors of about 1e-2 and above, and a
  finer point's ``mitsuba_error`` stops falling at the floor; below it only the angular reference measures. One
  render's actual noise scatters widely about the floor (0.5 to 2.2 times it over 12 seeds on the studio map): the
  few brightest blocks dominate the relative RMS and their Monte Carlo estimates are heavy-tailed.
* ``reference_error``: the angular reference itself turned into the same image, against Mitsuba. It is the
  consistency check of the whole comparison (camera, map orientation, BSDF, units) and the floor below which
  ``mitsuba_error`` cannot separate points: the noise, plus what every map shares, the bilinear lookup of the
  ``S x 2S`` output grid and the reference's pixel-centre sum over the map (Mitsuba integrates the pixels' areas).
  With S equal to the input rows it is at the noise level (``tests/relight/test_tradeoff_mitsuba.py``); at a
  coarser grid the interpolation shows (2.6 % for Beckmann alpha = 0.2 on the studio map at 32 rows and S = 16).

Otherwise ``meta.mitsuba`` has ``computed`` False and a ``reason`` (no twin, Mitsuba not installed, an odd
map height, a failed render, or ``mitsuba=False``) and the points carry ``mitsuba_error`` and ``image_error`` None.

:func:`window_tradeoff` reports what optional windowing (``prefilter_radial(window=...)``) costs in accuracy and
gains in ringing (the negative lobe of the band-limited kernel, Gibbs overshoot).

Modules: :mod:`~relight.tradeoff.sweeps` (:func:`sweep`), :mod:`~relight.tradeoff.points` (one point of either
method, :class:`TradeoffPoint`), :mod:`~relight.tradeoff.mitsuba` (the Mitsuba 3 comparison),
:mod:`~relight.tradeoff.window` (:func:`window_tradeoff`) and :mod:`~relight.tradeoff.plots` (:func:`write_tradeoff`,
:func:`plot`; matplotlib is optional, the ``plots`` extra, imported only there).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from relight import lazy

if TYPE_CHECKING:
    from relight.tradeoff.plots import (
        plot,
        write_tradeoff,
    )
    from relight.tradeoff.points import (
        QUICK_SECONDS,
        REPEAT,
        is_reflection_map,
        pareto_flags,
    )
    from relight.tradeoff.report import (
        TradeoffMeta,
        TradeoffPoint,
    )
    from relight.tradeoff.sweeps import (
        DEFAULT_EPSILONS,
        DEFAULT_SHRM_EPSILONS,
        DEFAULT_TRUNCATIONS,
        DEFAULT_VIEW,
        MAX_DEFAULT_SIZE,
        Progress,
        Tradeoff,
        default_size,
        sweep,
    )
    from relight.tradeoff.window import (
        window_tradeoff,
    )

#: Public name -> defining module, imported on first use (PEP 562): importing the package stays cheap.
_EXPORTS: dict[str, str] = {
    "DEFAULT_EPSILONS": "sweeps",
    "DEFAULT_SHRM_EPSILONS": "sweeps",
    "DEFAULT_TRUNCATIONS": "sweeps",
    "DEFAULT_VIEW": "sweeps",
    "MAX_DEFAULT_SIZE": "sweeps",
    "Progress": "sweeps",
    "QUICK_SECONDS": "points",
    "REPEAT": "points",
    "Tradeoff": "sweeps",
    "TradeoffMeta": "report",
    "TradeoffPoint": "report",
    "default_size": "sweeps",
    "is_reflection_map": "points",
    "pareto_flags": "points",
    "plot": "plots",
    "sweep": "sweeps",
    "window_tradeoff": "window",
    "write_tradeoff": "plots",
}

__all__ = [
    "DEFAULT_EPSILONS",
    "DEFAULT_SHRM_EPSILONS",
    "DEFAULT_TRUNCATIONS",
    "DEFAULT_VIEW",
    "MAX_DEFAULT_SIZE",
    "Progress",
    "QUICK_SECONDS",
    "REPEAT",
    "Tradeoff",
    "TradeoffMeta",
    "TradeoffPoint",
    "default_size",
    "is_reflection_map",
    "pareto_flags",
    "plot",
    "sweep",
    "window_tradeoff",
    "write_tradeoff",
]


__getattr__, __dir__ = lazy.exports(__name__, _EXPORTS)
