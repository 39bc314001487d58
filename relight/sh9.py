"""Order-2 (9-coefficient) spherical-harmonic lighting in the conventions engines read (issue 17, item 2).

Every engine below writes its nine real harmonics as a constant ``K_k`` (with or without the Condon–Shortley sign)
times one of the same nine polynomials of the unit direction ``d = (x, y, z)``, in the same order
(three.js ``SphericalHarmonics3.getAt``, Babylon ``SH3ylmBasisTrigonometricTerms``, Filament's
``Irradiance_SphericalHarmonics`` shader; Sloan 2008, "Stupid Spherical Harmonics Tricks", App. A2):

    P = [1, y, z, x, x y, y z, 3 z^2 - 1, x z, x^2 - y^2]
    K = [sqrt(1/4pi), sqrt(3/4pi) (x3), sqrt(15/4pi), sqrt(15/4pi), sqrt(5/16pi), sqrt(15/4pi), sqrt(15/16pi)]

and the radiance coefficients are ``c_k = int L(d) K_k P_k(d) dOmega``. The clamped-cosine convolution (irradiance,
Ramamoorthi & Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps", eq. 8-9) scales band l
by ``A_0 = pi``, ``A_1 = 2 pi / 3``, ``A_2 = pi / 4``. The conventions (docs/conventions.md, "SH9"):

* ``three``: ``c_k`` with K positive: ``SphericalHarmonics3.coefficients`` / ``LightProbe`` (radiance; three's
  ``getIrradianceAt`` and shader apply A_l themselves).
* ``babylon``: ``s_k c_k``, ``s = [+, -, +, -, +, -, +, -, +]`` (Babylon's ``SH3ylmBasisConstants`` carry the
  Condon–Shortley sign): ``SphericalHarmonics.FromArray`` of radiance, then ``convertIncidentRadianceToIrradiance``,
  ``convertIrradianceToLambertianRadiance`` and ``SphericalPolynomial.FromHarmonics``, as Babylon's own cube-map path.
* ``gltf``: ``A_l s_k c_k``, the irradiance coefficients of ``EXT_lights_image_based`` (Babylon's loader reads them
  with ``SphericalHarmonics.FromArray`` and divides by pi).
* ``filament``: ``(A_l / pi) K_k c_k``, cmgen ``--sh-shader``'s pre-scaled form: the shader's ``sum f_k P_k(n)`` is
  the irradiance over pi (sign-free: ``K_k c_k`` does not depend on the sign of K_k).
* ``unity``: ``U_k (A_l / pi) K_k c_k``, Unity's ``SphericalHarmonicsL2`` (``sh[rgb, k]``; ``RenderSettings.
  ambientProbe``, ``LightProbes``): the same pre-scaled irradiance-over-pi numbers as ``filament``, which Unity's
  shader reads as ``sum f_k P_k(n)`` through its packing ``unity_SHA* = (f_3, f_1, f_2, f_0 - f_6)``,
  ``unity_SHB* = (f_4, f_5, 3 f_6, f_7)``, ``unity_SHC = f_8`` (``SHEvalLinearL0L1``, ``SHEvalLinearL2``), but
  on Unity's left-handed axes: Unity's direction is relight's ``(-x, y, z)`` (+Y up, +Z forward; the X flip with
  which glTFast and UnityGLTF import glTF), so ``U = [+, +, +, -, -, +, +, -, +]``, the sign of ``P_k`` under
  ``x -> -x``.
* ``raw``: relight's own real SH coefficients of radiance to l = 2 (``relight.sh``, index ``l^2 + l + m`` in the SH
  frame ``(X, Z, Y)``, docs/conventions.md).

Directions are relight's world frame, which is three.js' and glTF's (+Y up, equirectUv) and the GL direction of the
exported cube maps' texels (``relight.cube_chain``), so an export's SH and its cube agree. Coefficients are pixel
sums with each pixel's exact solid angle (the brute force's quadrature).
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from relight.conventions import latlong_dirs, pixel_solid_angles, require_rgb_latlong
from relight.errors import InputError

FloatArray = NDArray[np.float64]

CONVENTIONS: Final = ("three", "gltf", "filament", "babylon", "unity", "raw")
#: Coefficient names in the order of the engines' arrays (Babylon's field names).
NAMES: Final = ("l00", "l1_1", "l10", "l11", "l2_2", "l2_1", "l20", "l21", "l22")
#: Degree of each coefficient.
DEGREE: Final = np.array([0, 1, 1, 1, 2, 2, 2, 2, 2])
#: ``K_k`` (module docstring): 0.282095, 0.488603, 1.092548, 0.315392, 0.546274 as three.js rounds them.
K: Final = np.array([math.sqrt(1 / (4 * math.pi))] + [math.sqrt(3 / (4 * math.pi))] * 3
                    + [math.sqrt(15 / (4 * math.pi))] * 2 + [math.sqrt(5 / (16 * math.pi))]
                    + [math.sqrt(15 / (4 * math.pi)), math.sqrt(15 / (16 * math.pi))])
#: The Condon–Shortley signs of Babylon's constants (odd m).
CS_SIGN: Final = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
#: Sign of each ``P_k`` when x changes sign: relight's frame to Unity's (module docstring, ``unity``).
UNITY_SIGN: Final = np.array([1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
#: Clamped-cosine transfer per band, ``A_l`` (Ramamoorthi & Hanrahan 2001, eq. 9).
A_L: Final = np.array([math.pi, 2 * math.pi / 3, math.pi / 4])
#: What each convention's numbers are (JSON ``quantity``).
QUANTITY: Final = {"three": "radiance", "babylon": "radiance", "gltf": "irradiance", "filament": "irradiance/pi",
                   "unity": "irradiance/pi", "raw": "radiance"}
#: The frame each convention's directions are in (JSON ``frame``).
FRAME: Final = "relight world (+Y up, three.js equirectUv; GL cube directions of the exports)"
UNITY_FRAME: Final = "Unity world (left-handed, +Y up, +Z forward): relight's (-x, y, z)"


def polynomials(d: NDArray[np.floating]) -> FloatArray:
    """The nine polynomials ``P_k`` of directions (..., 3), shape (..., 9) (module docstring)."""
    d = np.asarray(d, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"directions must have a trailing axis of length 3, got shape {d.shape}")
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y], axis=-1)


def radiance_coefficients(pixels: NDArray[np.floating]) -> FloatArray:
    """``c_k = int L K_k P_k dOmega`` (K positive) of a lat-long map (H, W, 3) by its pixel sum, shape (9, 3)."""
    env = np.asarray(require_rgb_latlong(pixels), dtype=np.float64)
    h, w = env.shape[:2]
    basis = (polynomials(latlong_dirs(h, w)) * K).reshape(-1, 9)
    weighted = (env * pixel_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    return np.asarray(basis.T @ weighted, dtype=np.float64)  # BLAS: ~10x einsum's loop on a 1024 x 512 map


def convert(c: FloatArray, convention: str) -> FloatArray:
    """Radiance coefficients ``c`` (9, 3) (K positive) in ``convention`` (not ``raw``; module docstring)."""
    a = A_L[DEGREE][:, None]
    if convention == "three":
        return np.asarray(c, dtype=np.float64)
    if convention == "babylon":
        return np.asarray(CS_SIGN[:, None] * c, dtype=np.float64)
    if convention == "gltf":
        return np.asarray(a * CS_SIGN[:, None] * c, dtype=np.float64)
    if convention == "filament":
        return np.asarray(a / math.pi * K[:, None] * c, dtype=np.float64)
    if convention == "unity":
        return np.asarray(UNITY_SIGN[:, None] * a / math.pi * K[:, None] * c, dtype=np.float64)
    raise InputError(f"unknown SH convention {convention!r}; use one of {', '.join(CONVENTIONS)}")


def raw_coefficients(pixels: NDArray[np.floating]) -> FloatArray:
    """relight's real SH coefficients to l = 2 (``relight.sh`` lighting projection), shape (9, 3)."""
    from relight import sh
    from relight.prefilter import project_lighting

    lighting = project_lighting(np.asarray(pixels, dtype=np.float64), 2)
    return np.asarray(sh.to_real(lighting.alm, 2).T, dtype=np.float64)


def sh9(pixels: NDArray[np.floating], convention: str) -> dict[str, Any]:
    """The JSON object of ``relight sh``: ``convention``, ``quantity``, ``names`` and ``coefficients`` (9 RGB)."""
    if convention not in CONVENTIONS:
        raise InputError(f"unknown SH convention {convention!r}; use one of {', '.join(CONVENTIONS)}")
    coeffs = raw_coefficients(pixels) if convention == "raw" else convert(radiance_coefficients(pixels), convention)
    names = [f"l{l}m{m}" for l in range(3) for m in range(-l, l + 1)] if convention == "raw" else list(NAMES)
    return {"convention": convention, "quantity": QUANTITY[convention], "names": names,
            "frame": UNITY_FRAME if convention == "unity" else FRAME,
            "coefficients": [[float(v) for v in row] for row in coeffs]}


def all_conventions(pixels: NDArray[np.floating]) -> dict[str, Any]:
    """Every convention's coefficients (the export sidecars embed this), from one pixel sum."""
    c = radiance_coefficients(pixels)
    out: dict[str, Any] = {}
    for conv in CONVENTIONS:
        coeffs = raw_coefficients(pixels) if conv == "raw" else convert(c, conv)
        out[conv] = {"quantity": QUANTITY[conv], "coefficients": [[float(v) for v in row] for row in coeffs]}
    return out
