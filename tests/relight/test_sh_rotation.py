"""Tests of relight.sh_rotation (real SH rotation from 3 x 3 matrices, seed 003 Appendix).

References: relight.wigner's complex ``D^l_{m'm}`` (a different algorithm: Euler angles and the Wigner-d
recursion) converted to the real basis through relight.sh's ``from_real``/``to_real``; direct evaluation of the
real harmonics at rotated points (``relight.shrm.real_harmonics``); Gauss–Legendre x trapezoid projection for the
local-frame (parity) rule. Tolerances: the IR recursion and the Wigner path each round a few ulps per band, so
1e-12 up to l = 14 (measured ~3e-15); projection tests are exact up to quadrature rounding (1e-12).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from relight import indexing, sh
from relight.alm_rotation import rotation_matrix_zyz
from relight.errors import InputError
from relight.sh_rotation import (
    SH_FROM_WORLD,
    band_rotations,
    band_signs,
    block_diagonal,
    local_rotations,
    rotate_coefficients,
    rotation_about_z,
)
from relight.shrm import real_harmonics
from relight.tangent_frames import projected_frames
from relight.wigner import wigner_D_matrix

LMAX = 14
F64 = NDArray[np.float64]


def wigner_real(angles: tuple[float, float, float], lmax: int) -> F64:
    """Dense real rotation from relight.wigner for R = Rz(a) Ry(b) Rz(g): every real unit vector through
    ``sh.from_real``, the complex ``D`` per band (full m layout via ``a_{l,-m} = (-1)^m conj(a_lm)``), then
    ``sh.to_real``."""
    a, b, g = angles
    n = (lmax + 1) ** 2
    alm = sh.from_real(np.eye(n), lmax)  # (n, n_alm), healpy layout m >= 0
    rotated = np.zeros_like(alm)
    for ell in range(lmax + 1):
        m = np.arange(ell + 1)
        pos = indexing.healpy_index(ell, m, lmax)
        full = np.zeros((n, 2 * ell + 1), dtype=complex)
        full[:, ell + m] = alm[:, pos]
        full[:, ell - m] = (-1.0) ** m * np.conj(alm[:, pos])
        new = full @ wigner_D_matrix(ell, a, b, g).T
        rotated[:, pos] = new[:, ell + m]
    return np.asarray(sh.to_real(rotated, lmax).T)


#: Euler angles (z-y-z) including the singular beta = 0, pi and beta within 1e-8 of them (the reference is built
#: from the angles, so it stays exact there; the rotation under test sees only the 3 x 3 matrix).
HARD_ANGLES = [(0.3, 1.1, -2.0), (2.5, 2.9, 0.4), (-1.0, 0.2, 3.0), (0.7, 0.0, 0.0), (0.4, 0.0, 0.9),
               (0.0, np.pi, 0.0), (1.2, np.pi, -0.3), (0.5, 1e-8, 0.2), (-0.8, np.pi - 1e-8, 1.9)]


def hard_rotations() -> F64:
    return np.array([rotation_matrix_zyz(*abg) for abg in HARD_ANGLES])


def test_matches_wigner_real_basis_to_1e12_up_to_l14() -> None:
    rs = hard_rotations()
    blocks = block_diagonal(band_rotations(rs, LMAX))
    for k, abg in enumerate(HARD_ANGLES):
        ref = wigner_real(abg, LMAX)
        assert np.abs(blocks[k] - ref).max() < 1e-12, k


def test_rotated_field_is_f_of_r_inverse_x() -> None:
    # The defining identity, by direct evaluation: f'(x) = f(R^-1 x) with c' = M c.
    rng = np.random.default_rng(3)
    lmax = 8
    c = rng.normal(size=((lmax + 1) ** 2, 1))
    r = Rotation.random(1, random_state=4).as_matrix()[0]
    x = rng.normal(size=(200, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    c_rot = rotate_coefficients(band_rotations(r, lmax), c)

    def field(coef: F64, d: F64) -> F64:
        th = np.arctan2(np.hypot(d[:, 0], d[:, 1]), d[:, 2])
        return np.asarray(real_harmonics(lmax, th, np.arctan2(d[:, 1], d[:, 0])) @ coef[:, 0])

    assert np.abs(field(c_rot, x) - field(c, x @ r)).max() < 1e-12  # (R^-1 x)^T = x^T R


def test_orthogonality_and_composition() -> None:
    rs = hard_rotations()
    m = block_diagonal(band_rotations(rs, LMAX))
    assert np.abs(m @ np.swapaxes(m, -1, -2) - np.eye((LMAX + 1) ** 2)).max() < 1e-12
    r12 = np.einsum("ij,njk->nik", rs[0], rs)
    m12 = block_diagonal(band_rotations(r12, LMAX))
    assert np.abs(m12 - m[0] @ m).max() < 1e-12


def test_about_z_closed_form() -> None:
    phi = np.array([0.0, 0.3, -2.0, np.pi])
    rz = Rotation.from_rotvec(np.outer(phi, [0.0, 0.0, 1.0])).as_matrix()
    a = block_diagonal(band_rotations(rz, 6))
    b = block_diagonal(rotation_about_z(phi, 6))
    assert np.abs(a - b).max() < 1e-13


def test_rejects_improper_and_non_orthogonal() -> None:
    with pytest.raises(InputError, match="proper"):
        band_rotations(np.diag([1.0, 1.0, -1.0]), 2)
    with pytest.raises(InputError, match="orthogonal"):
        band_rotations(np.eye(3) * 1.1, 2)
    with pytest.raises(InputError, match="lmax"):
        band_rotations(np.eye(3), -1)


def project_local(coef_world: F64, frame: F64, lmax: int, n_t: int = 40, n_p: int = 80) -> F64:
    """Brute force: real coefficients of L(F^T u) in local coordinates u (Gauss–Legendre x trapezoid, exact for
    band-limited L: the product of two band-lmax functions has degree 2 lmax < 2 n_t and < n_p)."""
    x, w = np.polynomial.legendre.leggauss(n_t)
    th = np.arccos(x)
    ph = (np.arange(n_p) + 0.5) * 2 * np.pi / n_p
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    u = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    wts = np.repeat(w, n_p) * 2 * np.pi / n_p
    world = u @ frame  # F^T u as rows
    sh_dirs = world @ SH_FROM_WORLD.T
    th_w = np.arctan2(np.hypot(sh_dirs[:, 0], sh_dirs[:, 1]), sh_dirs[:, 2])
    vals = real_harmonics(lmax, th_w, np.arctan2(sh_dirs[:, 1], sh_dirs[:, 0])) @ coef_world
    basis = real_harmonics(lmax, tt.ravel(), pp.ravel())
    return np.asarray(basis.T @ (vals * wts[:, None]))


@pytest.mark.parametrize("mirrored", [False, True])
def test_local_rotation_parity_rule(mirrored: bool) -> None:
    # docs/conventions.md "Parity": the world SH frame is a mirror of the world, so a right-handed local frame
    # needs (-1)^l M(-F P). A mirrored frame (glTF w = -1) needs M(F P). Checked against projection in local coords.
    rng = np.random.default_rng(5)
    lmax = 4
    coef = rng.normal(size=((lmax + 1) ** 2, 3))
    frames = projected_frames(rng.normal(size=(3, 3)), [0.3, 0.2, 0.9])
    if mirrored:
        frames[:, 1] *= -1.0
    blocks = local_rotations(frames, lmax)
    got = rotate_coefficients(blocks, coef[None])
    for k in range(3):
        ref = project_local(coef, frames[k], lmax)
        assert np.abs(got[k] - ref).max() < 1e-12


def test_band_signs() -> None:
    assert band_signs(2).tolist() == [1, -1, -1, -1, 1, 1, 1, 1, 1]
