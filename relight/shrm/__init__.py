"""Spherical Harmonic Reflection Maps (seed 000 §4 eqs. 5–8, §7.5 eq. 12, App. A eq. 14, App. C steps 2–3).

Seed 000 (Ramamoorthi & Hanrahan 2002) represents the reflected light field of a lobe centred on a direction C
(the reflection vector R, the normal N or the tangent T; §3.1) as a low-order expansion in the local outgoing
direction (eq. 6)::

    B(alpha, beta; theta_o, phi_o) = sum_{p <= P} sum_{|q| <= p} B_pq(alpha, beta) Y_pq(theta_o, phi_o)

where (alpha, beta) are the SH angles of C (``relight.conventions``: theta from +Y, phi the lat-long azimuth) and
(theta_o, phi_o) are the angles of the view V in the *local frame* of C: ``R_{alpha,beta} = R_z(beta) R_y(alpha)``
(SH frame ``(x', y', z') = (X, Z, Y)``), i.e. local x = theta-hat (towards increasing alpha), local y = phi-hat,
local z = C. In world coordinates::

    theta_hat = (cos a cos b, -sin a, cos a sin b), phi_hat = (-sin b, 0, cos b), C = (sin a cos b, cos a, sin a sin b)

Notes: the formula computed (eq. 5 and App. A's redefinition)
-----------------------------------------------------------
Writing ``L(R_{alpha,beta} w) = sum_lm L_lm Y_lm(R w)`` and using ``Y_lm(R w) = sum_q Y_lq(w) D^l_qm(R^{-1})`` with
``R^{-1} = R_y(-alpha) R_z(-beta)``, ``D^l_qm(R^{-1}) = d^l_qm(-alpha) e^{i m beta} = d^l_mq(alpha) e^{i m beta}``
(``relight.wigner``'s Edmonds convention), and the BRDF expansion of ``relight.brdf.lpq``, eq. 2 becomes::

    B_pq(alpha, beta) = sum_{l,m} L_lm rho_hat_lpq d^l_mq(alpha) e^{i m beta}       (eq. 14, App. C step 3)

So App. A's ``B_lmpq Lambda_l^{-1} D^l_mq`` with eq. 5's ``B_lmpq = Lambda_l L_lm rho_hat_lpq`` (Lambda_l cancels):
the coefficients synthesised are ``B_lmpq = L_lm rho_hat_lpq`` (App. A's redefinition), with ``D^l_mq(alpha) =
d^l_mq(alpha)``. For q = 0, ``d^l_m0(alpha) e^{i m beta} = Lambda_l Y_lm(alpha, beta)``, ``Lambda_l =
sqrt(4 pi / (2l + 1))``, so ``B_p0 = sum_lm (Lambda_l rho_hat_lp0 L_lm) Y_lm`` — an ordinary SH synthesis. For a
radially symmetric lobe ``rho_hat_l00 = sqrt(4 pi) rho_l`` and ``B = B_00 Y_00 = sum_lm Lambda_l rho_l L_lm Y_lm``,
exactly ``relight.prefilter``'s map (checked in the tests).

Real storage (identical to ``relight.sh.to_real``): the field is real, so ``B_{p,-q} = (-1)^q conj(B_pq)`` and each
SHRM coefficient is stored as a real RGB map ``Br_pq`` with ``B = sum Br_pq Yr_pq``, ``Yr_p0 = Y_p0``,
``Yr_{p,q>0} = sqrt2 (-1)^q Re Y_pq``, ``Yr_{p,q<0} = sqrt2 (-1)^q Im Y_{p|q|}``; i.e. ``Br_p0 = B_p0``,
``Br_{p,q>0} = sqrt2 (-1)^q Re B_pq``, ``Br_{p,-q} = -sqrt2 (-1)^q Im B_pq``.

Fast path (``backend="ducc0"``): ducc0's spin-weighted synthesis computes, for spin s > 0 with gradient-only
coefficients ``a^E_lm`` (``mode="GRAD_ONLY"``), ``Q + i U = (-1)^{s+1} sum_{l,m} a^E_lm Lambda_l^{-1}
d^l_{m,-s}(theta) e^{i m phi}`` (measured against ``relight.wigner``; the tests keep checking it). With
``a^E_lm = sqrt2 (-1)^{q+1} Lambda_l L_lm rho_hat_lpq`` and s = q this gives ``Q + i U = sqrt2 B_{p,-q}``, and by
the symmetry above ``Br_{p,q} = Q``, ``Br_{p,-q} = U``: one spin-q synthesis per (p, q >= 0, colour), O(F S^2)
each (App. C's O(F P^2 S^2) in all). Reference (``backend="wigner"``): the plain App. C step 3 — ``B_mpq(alpha) =
sum_l B_lmpq d^l_mq(alpha)`` with d from ``relight.wigner`` (stable to l = 2048), then ``sum_m B_mpq e^{i m beta}``
by an explicit DFT, then the real combinations. The two are tested against each other to l = 2048.

Global SHRM (eq. 8, distant viewer): ``B~_pq(alpha, beta) = sum_s d^p_qs(alpha) e^{-i q beta} B_ps(alpha, beta)``
(``D^p_sq(-alpha) = d^p_qs(alpha)``), from ``Y_pq(R^{-1} V) = sum_s Y_ps(V) D^p_sq(R)``, ``D^p_sq(R_z(b) R_y(a)) =
e^{-i s b} d^p_sq(a)``. Then eq. 12: ``B~(alpha, beta) = sum_pq B~r_pq(alpha, beta) Yr_pq(V)`` with V's SH angles.

Structure-aware size: a radially symmetric lobe needs P = 0 (one map); a lobe without azimuthal dependence
(Kajiya–Kay, §7.1) needs only q = 0 (P + 1 maps); a general isotropic lobe needs (P + 1)^2 maps. A sum-of-lobes
material gives one *component* per lobe, each with its own centre and orders.

Modules, one per object: :mod:`~relight.shrm.basis` (real basis ``Yr_pq``, stored terms),
:mod:`~relight.shrm.synthesis` (local maps, App. C step 3 / eq. 14), :mod:`~relight.shrm.rotation` (eq. 8),
:mod:`~relight.shrm.model` (:class:`SHRMComponent`, :class:`SHRM`; eq. 12), :mod:`~relight.shrm.geometry`
(frames, centres, lookups), :mod:`~relight.shrm.evaluation` (eq. 6 / eq. 12 maps and renders),
:mod:`~relight.shrm.explicit` (App. C explicit forms), :mod:`~relight.shrm.creation` (:func:`create_shrm`).
This package re-exports their public names and imports each module on first use (PEP 562 ``__getattr__``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from relight import lazy

if TYPE_CHECKING:
    from relight.shrm.basis import (
        SQRT2,
        Y00,
        Backend,
        Structure,
        complex_to_real,
        real_harmonics,
        real_to_complex,
        structure_of,
        terms_for,
    )
    from relight.shrm.creation import (
        MAX_SHRM_BYTES,
        brdf_lobes,
        create_shrm,
        predicted_errors,
    )
    from relight.shrm.evaluation import (
        evaluate_local,
        reflect,
        render_sphere,
        shade,
        sphere_geometry,
    )
    from relight.shrm.explicit import (
        explicit_maps,
        icosahedron_views,
        kautz_mccool_texture,
        view_grid,
    )
    from relight.shrm.geometry import (
        halfway_normals,
        lobe_centres,
        local_frame,
        local_view_angles,
        reflect_dirs,
        tangent_field,
        unit_view,
    )
    from relight.shrm.model import (
        SHRM,
        SHRMComponent,
    )
    from relight.shrm.rotation import (
        local_to_global,
    )
    from relight.shrm.synthesis import (
        synthesize_local,
    )

#: Public name -> the module defining it.
_EXPORTS: dict[str, str] = {
    "Structure": "basis",
    "Backend": "basis",
    "SQRT2": "basis",
    "Y00": "basis",
    "terms_for": "basis",
    "structure_of": "basis",
    "real_harmonics": "basis",
    "real_to_complex": "basis",
    "complex_to_real": "basis",
    "unit_view": "geometry",
    "local_frame": "geometry",
    "local_view_angles": "geometry",
    "tangent_field": "geometry",
    "lobe_centres": "geometry",
    "reflect_dirs": "geometry",
    "halfway_normals": "geometry",
    "synthesize_local": "synthesis",
    "local_to_global": "rotation",
    "SHRMComponent": "model",
    "SHRM": "model",
    "reflect": "evaluation",
    "sphere_geometry": "evaluation",
    "render_sphere": "evaluation",
    "shade": "evaluation",
    "evaluate_local": "evaluation",
    "icosahedron_views": "explicit",
    "view_grid": "explicit",
    "explicit_maps": "explicit",
    "kautz_mccool_texture": "explicit",
    "brdf_lobes": "creation",
    "predicted_errors": "creation",
    "MAX_SHRM_BYTES": "creation",
    "create_shrm": "creation",
}

__all__ = [
    "Backend", "MAX_SHRM_BYTES", "SHRM", "SHRMComponent", "SQRT2", "Structure", "Y00", "brdf_lobes",
    "complex_to_real", "create_shrm", "evaluate_local", "explicit_maps", "halfway_normals", "icosahedron_views",
    "kautz_mccool_texture", "lobe_centres", "local_frame", "local_to_global", "local_view_angles",
    "predicted_errors", "real_harmonics", "real_to_complex", "reflect", "reflect_dirs",
    "render_sphere", "shade", "sphere_geometry", "structure_of", "synthesize_local",
    "tangent_field", "terms_for", "unit_view", "view_grid",
]


__getattr__, __dir__ = lazy.exports(__name__, _EXPORTS)
