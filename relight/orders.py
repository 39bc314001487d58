"""Error analysis: orders F (and P) from a tolerance (seed 000 §5.1, App. B, App. D).

The paper's tolerance ``epsilon`` is an *energy fraction not captured*: for a signal with band energies E_l and
total energy E_tot = int f^2 dOmega, an order-F expansion misses ``epsilon(F) = 1 - sum_{l<=F} E_l / E_tot``.

The project's error metric (``relight.metrics``) is the relative RMS error of the output over the sphere
(solid-angle weighted, on luminance). For an orthogonal truncation the two are related exactly by
``relative_rms = sqrt(epsilon_B)`` where epsilon_B is the output's uncaptured energy fraction
(``rms_from_energy``). Reports give both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from relight.reports import OrderReport

FloatArray = NDArray[np.float64]


def uncaptured(band_energy: NDArray[np.floating], total_energy: float) -> FloatArray:
    """``epsilon(F) = 1 - sum_{l<=F} E_l / E_tot`` for every F (clipped to [0, 1]; 0 for a zero signal)."""
    e = np.asarray(band_energy, dtype=np.float64)
    if total_energy <= 0.0:
        return np.zeros(e.shape[0])
    return np.asarray(np.clip(1.0 - np.cumsum(e) / total_energy, 0.0, 1.0), dtype=np.float64)


def order_for_tolerance(band_energy: NDArray[np.floating], total_energy: float, epsilon: float) -> int | None:
    """Smallest F with ``epsilon(F) <= epsilon`` (seed 000 §5.1), or None if the given bands do not reach it."""
    if not 0.0 < epsilon < 1.0:
        raise ValueError(f"epsilon must lie in (0, 1), got {epsilon}")
    ok = np.nonzero(uncaptured(band_energy, total_energy) <= epsilon)[0]
    return int(ok[0]) if ok.size else None


def phong_order(s: float, epsilon: float) -> int:
    """Closed form of App. D for normalised Phong: ``F ~ sqrt(-s log epsilon)`` (rounded up)."""
    if s <= 0.0 or not 0.0 < epsilon < 1.0:
        raise ValueError(f"need s > 0 and 0 < epsilon < 1, got s={s}, epsilon={epsilon}")
    return int(math.ceil(math.sqrt(-s * math.log(epsilon))))


def phong_angular_width(s: float, epsilon: float) -> tuple[float, float]:
    """App. D angular domain: ``cos theta* = epsilon^{1/(s+1)}`` and ``W = (1 - epsilon^{1/(s+1)}) / 2``."""
    c = epsilon ** (1.0 / (s + 1.0))
    return math.acos(c), 0.5 * (1.0 - c)


def rms_from_energy(epsilon: float) -> float:
    """Relative RMS error of an orthogonal truncation missing the energy fraction ``epsilon``: sqrt(epsilon)."""
    return math.sqrt(max(epsilon, 0.0))


def appendix_b_bound(
    lambda_next: float,
    eps_lighting: float,
    lighting_total: float,
    eps_brdf: float,
    brdf_total: float,
    captured_output_energy: float,
) -> float:
    """Conservative uncaptured-energy fraction of the output (seed 000 App. B).

    Notes
    -----
    With ``B_lm = Lambda_l rho_l L_lm``, the residual ``sum_{l>F} Lambda_l^2 rho_l^2 E^L_l`` is at most
    ``Lambda_{F+1}^2 (eps_rho rho_tot)(eps_L L_tot)`` because ``Lambda_l`` decreases and all terms are
    non-negative. (App. B writes ``Lambda_{F+1}``; it is squared here because the energies are squared norms.)
    Then ``epsilon_B <= B_res / (sum_{l<=F} |B_lm|^2 + B_res)``.
    """
    b_res = lambda_next**2 * (eps_lighting * lighting_total) * (eps_brdf * brdf_total)
    denom = captured_output_energy + b_res
    return float(b_res / denom) if denom > 0.0 else 0.0


@dataclass(frozen=True)
class OrderChoice:
    """Orders and predicted errors for one lobe (seed 000 §5.1: minimum-of-orders rule)."""

    F_L: int | None  # lighting order for epsilon (None: not reached within the orders examined)
    F_rho: int  # BRDF order for epsilon
    F_B: int  # output order = min(F_L, F_rho)
    P_B: int
    eps_lighting: float  # at F_B
    eps_brdf: float  # at F_B
    eps_min_of_errors: float  # min(eps_L, eps_rho) at F_B
    eps_appendix_b: float  # App. B bound at F_B

    def report(self) -> OrderReport:
        """The orders and predicted errors as a typed report (``relight.reports``; relative RMS = sqrt(epsilon))."""
        return OrderReport(
            F_L=self.F_L, F_rho=self.F_rho, F_B=self.F_B, P_B=self.P_B,
            epsilon_lighting=self.eps_lighting, epsilon_brdf=self.eps_brdf,
            epsilon_min_of_errors=self.eps_min_of_errors, rms_min_of_errors=rms_from_energy(self.eps_min_of_errors),
            epsilon_appendix_b=self.eps_appendix_b, rms_appendix_b=rms_from_energy(self.eps_appendix_b),
        )
