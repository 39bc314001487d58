"""Frequency-space prefiltering of radially symmetric lobes (seed 000 §3.1, §6, App. C "radially symmetric").

Pipeline (App. C with P = 0):

1. BRDF coefficients ``Lambda_l rho_l`` by quadrature, and the order F_rho for the tolerance (§5.1);
2. lighting coefficients ``L_lm`` by pixel quadrature to ``F_rho`` (O(F S_L^2)); the lighting order F_L for the same
   tolerance; ``F_B = min(F_L, F_rho)`` (minimum-of-orders rule, §5.1);
3. ``B_lm = Lambda_l rho_l L_lm`` (eq. 5), O(F_B^2);
4. synthesis of the reflection map ``B(alpha, beta)`` on an S x 2S lat-long grid, O(F_B S^2) (and optionally a cube
   map at its texel directions).

The output map is indexed by the lobe's central direction C: the reflection vector R for Phong-like lobes, the
normal N for a Lambertian lobe (albedo 1: outgoing radiance E(N)/pi).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from relight import __version__, indexing, sh, validate
from relight.brdf.base import RadialLobe
from relight.brdf.coefficients import (
    RadialSpectrum,
    lambda_l,
    radial_transfer,
    ringing_minimum,
    spectrum_for_tolerance,
    window_factors,
)
from relight.conventions import LUMINANCE_WEIGHTS, check_latlong_shape, require_rgb_latlong
from relight.errors import InputError
from relight.orders import OrderChoice, appendix_b_bound, order_for_tolerance, uncaptured
from relight.reports import LatlongOutput, PrefilterReport, Ringing

FloatArray = NDArray[np.float64]

#: Default tolerance: the paper's epsilon = 0.01 used for the Phong timings of §7.4.
DEFAULT_EPSILON = 0.01
#: Resolution rule S ~ 10 F (seed 000 §5.2), bounded to a useful range.
MIN_SIZE, MAX_SIZE = 32, 2048
WINDOWS = ("none", "hann", "lanczos")


def size_for_order(order: int) -> int:
    """Output rows S for order F by the paper's S ~ 10F rule (§5.2), clamped to [32, 2048], even."""
    s = int(np.clip(10 * max(order, 1), MIN_SIZE, MAX_SIZE))
    return s + (s % 2)


class Timer:
    """Collects wall-clock seconds per named stage."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.seconds[name] = self.seconds.get(name, 0.0) + now - self._t
        self._t = now


@dataclass
class LightingSpectrum:
    """Lighting coefficients of an environment map and its luminance energy budget."""

    alm: NDArray[np.complex128]  # (3, nalm)
    lmax: int
    total_energy: float  # int Y^2 dOmega over the pixels (luminance)

    @property
    def luminance_alm(self) -> NDArray[np.complex128]:
        # a plain weighted sum: complex tensordot goes through a threaded BLAS, 400x slower on a loaded machine
        w = LUMINANCE_WEIGHTS
        return np.asarray(w[0] * self.alm[0] + w[1] * self.alm[1] + w[2] * self.alm[2], dtype=np.complex128)

    def band_energy(self) -> FloatArray:
        return sh.power_spectrum(self.luminance_alm, self.lmax)


def project_lighting(
    pixels: NDArray[np.floating],
    lmax: int,
    *,
    backend: sh.Backend = "ducc0",
    weights: Literal["fejer", "area"] = "fejer",
) -> LightingSpectrum:
    """``L_lm`` to order lmax by quadrature, and the total luminance energy of the map (seed 000 §5.1)."""
    h, w = check_latlong_shape(pixels.shape)
    alm = sh.project(pixels, lmax, backend=backend, weights=weights)
    px = np.asarray(pixels)
    lum = px @ LUMINANCE_WEIGHTS.astype(px.dtype)  # float32 input stays float32 here: an energy estimate
    ring_w = sh.quadrature_weights(h, weights)
    total = float(ring_w @ np.square(lum, dtype=np.float64).mean(axis=1))
    return LightingSpectrum(alm=alm, lmax=lmax, total_energy=total)


def choose_orders(
    spectrum: RadialSpectrum,
    lighting: LightingSpectrum,
    epsilon: float | None,
    order: int | None,
    f_rho: int,
    f_cap: int,
    transfer: FloatArray,
) -> OrderChoice:
    """Minimum-of-orders rule (§5.1) and the predicted uncaptured energies at F_B (§5.1 and App. B)."""
    e_light = lighting.band_energy()
    f_l = order_for_tolerance(e_light, lighting.total_energy, epsilon) if epsilon is not None else None
    if order is not None:
        f_b = min(order, f_cap)
    else:
        f_b = min(f_rho, f_cap, f_l if f_l is not None else f_rho)
    eps_rho = float(spectrum.epsilon()[min(f_b, spectrum.lmax)])
    eps_l = float(uncaptured(e_light, lighting.total_energy)[min(f_b, lighting.lmax)])
    light_f = sh.truncate(lighting.luminance_alm, lighting.lmax, f_b)
    b_lum = sh.power_spectrum(light_f, f_b) * np.mean(transfer[: f_b + 1] ** 2, axis=1)
    brdf_total = float(np.max(spectrum.total_energy))
    eps_b = appendix_b_bound(
        lambda_next=float(lambda_l(f_b + 1)[-1]),
        eps_lighting=eps_l,
        lighting_total=lighting.total_energy,
        eps_brdf=eps_rho,
        brdf_total=brdf_total,
        captured_output_energy=float(b_lum.sum()),
    )
    return OrderChoice(
        F_L=f_l,
        F_rho=f_rho,
        F_B=f_b,
        P_B=0,
        eps_lighting=eps_l,
        eps_brdf=eps_rho,
        eps_min_of_errors=min(eps_l, eps_rho),
        eps_appendix_b=eps_b,
    )


@dataclass
class PrefilterResult:
    """A prefiltered reflection map (S x 2S x 3, indexed by the lobe centre) with its report."""

    map: FloatArray
    coefficients: NDArray[np.complex128]  # B_lm, (3, nalm(F_B))
    report: PrefilterReport
    cube: FloatArray | None = None


def prefilter_radial(
    pixels: NDArray[np.floating],
    lobe: RadialLobe,
    *,
    epsilon: float | None = None,
    order: int | None = None,
    size: int | None = None,
    cube_size: int | None = None,
    window: str = "none",
    backend: sh.Backend = "ducc0",
    weights: Literal["fejer", "area"] = "fejer",
) -> PrefilterResult:
    """Prefilter a lat-long environment map (H, W, 3) with a radially symmetric lobe (seed 000 §6, App. C).

    Give either ``epsilon`` (the paper's uncaptured-energy tolerance; default 0.01) or an explicit ``order`` F.
    ``size`` is the output rows S (default: S ~ 10 F_B). ``weights`` selects the pixel quadrature (Fejér's first
    rule, default, or exact pixel areas); ``window`` is the optional ringing control
    (``relight.brdf.coefficients.window_factors``). The report carries orders, predicted errors (minimum of orders
    and App. B bound, as energies and as relative RMS), the ringing bound and seconds per stage.
    """
    if epsilon is not None and order is not None:
        raise InputError("give either epsilon or order, not both")
    if order is None and epsilon is None:
        epsilon = DEFAULT_EPSILON
    if epsilon is not None:
        validate.in_range("epsilon", epsilon, 0.0, 1.0, lo_open=True, hi_open=True)
    if order is not None:
        validate.at_least("order", order, 0)
    if size is not None:
        validate.in_range("size", validate.integer("size", size), 2, MAX_SIZE)
    if window not in WINDOWS:
        raise InputError(f"unknown window {window!r}; use one of {', '.join(WINDOWS)}")
    pixels = require_rgb_latlong(pixels)
    h, w = pixels.shape[:2]
    f_cap = h - 1  # pixel quadrature on H rings resolves orders below H
    timer = Timer()

    if order is not None:
        # nothing above the map's resolved orders is ever used: F_B <= H - 1
        spectrum = radial_transfer(lobe, min(order, f_cap))
        f_rho = min(order, f_cap)
    else:
        assert epsilon is not None
        spectrum, f_rho = spectrum_for_tolerance(lobe, epsilon)
    timer.lap("brdf_coefficients")

    f_proj = min(f_rho, f_cap)
    lighting = project_lighting(pixels, f_proj, backend=backend, weights=weights)
    timer.lap("lighting_projection")

    transfer = spectrum.transfer
    if transfer.shape[0] <= f_proj:
        transfer = radial_transfer(lobe, f_proj).transfer
    choice = choose_orders(spectrum, lighting, epsilon, order, f_rho, f_cap, transfer)
    f_b = choice.F_B
    timer.lap("order_selection")

    l_idx, _ = indexing.healpy_lm(f_b)
    factors = transfer[: f_b + 1] * window_factors(f_b, window)[:, None]  # (F_B+1, C)
    alm = sh.truncate(lighting.alm, lighting.lmax, f_b)
    b_lm = alm * factors[l_idx].T  # (3, nalm): grey lobes broadcast over RGB
    timer.lap("convolution")

    s = size if size is not None else size_for_order(f_b)
    out = sh.synthesize(b_lm, f_b, s, 2 * s, backend=backend)
    timer.lap("synthesis")

    # Ringing bound: B >= min(u_F, 0) * int L dOmega, with int L dOmega = sqrt(4 pi) L_00 (Y_00 = 1/sqrt(4 pi)).
    kernel_min = ringing_minimum(factors)
    flux = np.sqrt(4.0 * np.pi) * lighting.alm[:, 0].real
    ringing_floor = kernel_min.min() * flux
    timer.lap("ringing_bound")

    cube = None
    if cube_size is not None:
        from relight.conventions import dirs_to_angles
        from relight.envmap import cube_face_dirs

        theta, phi = dirs_to_angles(cube_face_dirs(cube_size).reshape(-1, 3))
        cube = sh.evaluate(b_lm, f_b, theta, phi).reshape(6, cube_size, cube_size, 3)
        timer.lap("cube_synthesis")

    orders = choice.report()
    from relight.shrm.view_bands import radial_by_view  # issue 18: the same error for every view band

    want = min(f_cap, max(f_b + max(16, f_b // 2), 96))  # the bands beyond F_B from the map, not App. B's step
    lig_pred = lighting if lighting.lmax >= want else project_lighting(pixels, want, backend=backend, weights=weights)
    by_view = radial_by_view(lobe, lig_pred, f_b, window=None if window == "none" else window_factors(f_b, window))
    timer.lap("prediction")
    report = PrefilterReport(
        center=str(lobe.center),
        brdf=lobe.spec(),
        epsilon=epsilon,
        order_requested=order,
        window=window,
        orders=orders,
        predicted=replace(orders.predicted(), by_view=by_view),
        ringing=Ringing(
            kernel_min=float(kernel_min.min()),
            lower_bound_rgb=[float(x) for x in ringing_floor],
            min_output_rgb=[float(x) for x in out.reshape(-1, out.shape[-1]).min(axis=0)],
        ),
        input={"height": h, "width": w},
        output=LatlongOutput(height=s, width=2 * s, cube_size=cube_size),
        timings=dict(timer.seconds),
        total_seconds=float(sum(timer.seconds.values())),
        backend=backend,
        relight_version=__version__,
    )
    return PrefilterResult(map=out, coefficients=b_lm, report=report, cube=cube)
