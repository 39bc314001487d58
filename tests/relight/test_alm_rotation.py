"""Rotation of SH coefficients (relight.alm_rotation): the rotated coefficients synthesise the rotated field
(scipy's harmonics, an independent synthesis), ducc0's fast path equals the Wigner-matrix reference, degree norms
are preserved, the real-field (healpy layout) wrapper agrees with the complex one, and bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.special import sph_harm_y

from relight import indexing
from relight.alm_rotation import rotate_alm, rotate_alm_healpy, rotation_matrix_zyz
from relight.errors import InputError


def test_rotation_matrix_is_zyz() -> None:
    rot = rotation_matrix_zyz(0.2, 0.0, 0.3)
    np.testing.assert_allclose(rot, rotation_matrix_zyz(0.5, 0.0, 0.0), atol=1e-15)
    # R_y(beta) carries +z toward +x
    np.testing.assert_allclose(rotation_matrix_zyz(0.0, 0.5, 0.0) @ [0, 0, 1], [np.sin(0.5), 0, np.cos(0.5)])


def synth(alm: NDArray[np.complex128], lmax: int, x: NDArray[np.float64]) -> NDArray[np.complex128]:
    th, ph = np.arccos(np.clip(x[:, 2], -1, 1)), np.arctan2(x[:, 1], x[:, 0])
    ell = np.concatenate([np.full(2 * k + 1, k) for k in range(lmax + 1)])
    m = np.concatenate([np.arange(-k, k + 1) for k in range(lmax + 1)])
    return np.asarray(sph_harm_y(ell[None, :], m[None, :], th[:, None], ph[:, None]) @ alm)


@pytest.mark.parametrize("method", ["ducc0", "reference"])
def test_rotate_alm_rotates_the_field(method: str) -> None:
    """f'(x) = f(R^{-1} x) for a random complex field, checked by synthesis with scipy."""
    rng = np.random.default_rng(42)
    lmax = 6
    alm = rng.normal(size=(lmax + 1) ** 2) + 1j * rng.normal(size=(lmax + 1) ** 2)
    angles = (0.4, 2.1, -1.3)
    x = rng.normal(size=(25, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    rotated = rotate_alm(alm, lmax, *angles, method=method)
    np.testing.assert_allclose(synth(rotated, lmax, x), synth(alm, lmax, x @ rotation_matrix_zyz(*angles)), atol=1e-12)


def test_rotate_alm_ducc0_matches_reference_and_batches() -> None:
    rng = np.random.default_rng(42)
    lmax = 20
    alm = rng.normal(size=(2, (lmax + 1) ** 2)) + 1j * rng.normal(size=(2, (lmax + 1) ** 2))
    fast = rotate_alm(alm, lmax, 1.0, 0.5, -2.0)
    ref = rotate_alm(alm, lmax, 1.0, 0.5, -2.0, method="reference")
    np.testing.assert_allclose(fast, ref, atol=1e-13)
    # norm per degree is preserved
    for ell in range(lmax + 1):
        sl = slice(ell * ell, (ell + 1) ** 2)
        np.testing.assert_allclose(np.linalg.norm(fast[:, sl], axis=-1), np.linalg.norm(alm[:, sl], axis=-1))


def test_rotate_alm_healpy_layout() -> None:
    rng = np.random.default_rng(42)
    lmax = 8
    # a real field: a_{l,-m} = (-1)^m conj(a_lm), a_l0 real
    full = np.zeros((lmax + 1) ** 2, complex)
    hp = []
    for m in range(lmax + 1):
        for ell in range(m, lmax + 1):
            v = rng.normal() + (1j * rng.normal() if m else 0.0)
            full[indexing.full_index(ell, m)] = v
            full[indexing.full_index(ell, -m)] = (-1) ** m * np.conj(v)
            hp.append(v)
    out_hp = rotate_alm_healpy(np.array(hp), lmax, 0.3, 1.2, 2.0)
    out_full = rotate_alm(full, lmax, 0.3, 1.2, 2.0, method="reference")
    k = 0
    for m in range(lmax + 1):
        for ell in range(m, lmax + 1):
            assert out_hp[k] == pytest.approx(out_full[indexing.full_index(ell, m)], abs=1e-13)
            k += 1


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: rotate_alm(np.zeros(5), 1, 0, 0, 0), "alm"),
        (lambda: rotate_alm(np.zeros(4), 1, 0, np.inf, 0), "beta"),
        (lambda: rotate_alm(np.zeros(4), 1, 0, 0, 0, method="fast"), "method"),
    ],
)
def test_invalid_input(call: object, field: str) -> None:
    with pytest.raises(InputError, match=field):
        call()  # type: ignore[operator]
