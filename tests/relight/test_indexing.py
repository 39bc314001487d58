"""Tests for relight.indexing: every packing layout against an independent enumeration (round trips, sizes).

The references enumerate the layouts by nested loops in the order their definitions state (healpy: m outer,
l inner; full: l outer, m = -l..l inner), independent of the closed-form index formulas under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from relight import alm_rotation, indexing, sh

ORDERS = [0, 1, 2, 7, 64]


def healpy_enumeration(lmax: int) -> list[tuple[int, int]]:
    return [(l, m) for m in range(lmax + 1) for l in range(m, lmax + 1)]


def full_enumeration(lmax: int) -> list[tuple[int, int]]:
    return [(l, m) for l in range(lmax + 1) for m in range(-l, l + 1)]


@pytest.mark.parametrize("lmax", ORDERS)
def test_healpy_layout_matches_enumeration(lmax: int) -> None:
    pairs = healpy_enumeration(lmax)
    l, m = indexing.healpy_lm(lmax)
    assert list(zip(l.tolist(), m.tolist(), strict=True)) == pairs
    assert indexing.healpy_size(lmax) == len(pairs)
    ls, ms = (np.array(x) for x in zip(*pairs, strict=True))
    np.testing.assert_array_equal(indexing.healpy_index(ls, ms, lmax), np.arange(len(pairs)))
    assert indexing.healpy_lmax(len(pairs)) == lmax


@pytest.mark.parametrize("lmax", ORDERS)
def test_full_layout_matches_enumeration(lmax: int) -> None:
    pairs = full_enumeration(lmax)
    l, m = indexing.full_lm(lmax)
    assert list(zip(l.tolist(), m.tolist(), strict=True)) == pairs
    assert indexing.full_size(lmax) == len(pairs) == (lmax + 1) ** 2
    assert [indexing.full_index(a, b) for a, b in pairs] == list(range(len(pairs)))
    np.testing.assert_array_equal(indexing.full_indices(l, m), np.arange(len(pairs)))
    for deg in range(lmax + 1):
        block = indexing.full_block(deg)
        assert pairs[block] == [(deg, k) for k in range(-deg, deg + 1)]
    assert indexing.full_lmax(len(pairs)) == lmax


def test_healpy_with_mmax_counts_the_truncated_triangle() -> None:
    lmax, mmax = 9, 4
    assert indexing.healpy_size(lmax, mmax) == sum(1 for l, m in healpy_enumeration(lmax) if m <= mmax)


@pytest.mark.parametrize("size", [0, 2, 4, 7, 11])
def test_sizes_that_are_no_layout_are_rejected(size: int) -> None:
    # 1, 3, 6, 10 are healpy triangles and 1, 4, 9 full squares; the sizes here are neither (4 only full).
    with pytest.raises(ValueError, match="healpy"):
        indexing.healpy_lmax(size)
    if size != 4:
        with pytest.raises(ValueError, match="full"):
            indexing.full_lmax(size)


def test_out_of_range_pairs_name_the_values() -> None:
    with pytest.raises(ValueError, match="l=2, m=3"):
        indexing.full_index(2, 3)
    with pytest.raises(ValueError, match="lmax=4"):
        indexing.healpy_index(5, 0, 4)
    with pytest.raises(ValueError, match="lmax=4"):
        indexing.healpy_index(3, -1, 4)
    with pytest.raises(ValueError, match="must be a non-negative integer"):
        indexing.full_size(-1)


def test_real_basis_and_rotation_use_the_full_layout() -> None:
    """``sh.to_real`` places Yr_lm at full_index(l, m): a single complex a_lm (m > 0) lands on exactly the two
    entries (l, +-m); ``alm_rotation.rotate_alm`` reads the full layout: a rotation about z multiplies a_lm by
    e^{-i m alpha} at full_index(l, m)."""
    lmax = 5
    l, m = 4, 3
    alm = np.zeros(indexing.healpy_size(lmax), dtype=np.complex128)
    alm[indexing.healpy_index(l, m, lmax)] = 1.0 + 2.0j
    real = sh.to_real(alm, lmax)
    assert set(np.flatnonzero(real).tolist()) == {indexing.full_index(l, m), indexing.full_index(l, -m)}
    full = np.zeros(indexing.full_size(lmax), dtype=np.complex128)
    full[indexing.full_index(l, m)] = 1.0
    alpha = 0.3
    rotated = alm_rotation.rotate_alm(full, lmax, alpha, 0.0, 0.0, method="reference")
    expected = np.zeros_like(full)
    expected[indexing.full_index(l, m)] = np.exp(-1j * m * alpha)
    np.testing.assert_allclose(rotated, expected, atol=1e-13)  # exact phase up to rounding of one product
