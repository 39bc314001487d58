"""In-out factorization SVD (relight.factorization, relight.factor_kernel; Mahajan, Tseng & Ramamoorthi 2008).

References: the paper's closed form (eq. 9: sigma = F_l with multiplicity 2l + 1, factors = real SH), relight's
closed-form Phong transfer (``phong_transfer``, Ramamoorthi & Hanrahan 2001), scipy's spherical harmonics,
polynomial kernels with exact singular values, and the dense SVD as a second algorithm for the block SVD.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import subspace_angles
from scipy.special import sph_harm_y

from relight.brdf.coefficients import phong_transfer
from relight.brdf.spec import parse_brdf, parse_frame_brdf
from relight.errors import InputError
from relight.factor_kernel import make_grid, make_kernel
from relight.factorization import convergence, factorize, terms_for


def weighted_matrix(spec: str, domain: str, n_theta: int, n_phi: int, grid: str = "gauss") -> np.ndarray:
    """``W^1/2 rho W^1/2`` built here from the kernel and the grid (rows outgoing, columns incident)."""
    g = make_grid(domain, n_theta, n_phi, grid)
    k = make_kernel(parse_brdf(spec), domain=domain)
    d = g.directions()
    sw = np.sqrt(g.weights)
    return np.asarray(k.full(d[None, :, :], d[:, None, :]) * sw[:, None] * sw[None, :])


def real_sh(l: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real orthonormal Y_lm, m = -l..l, from scipy (columns), shape (theta.size, 2l + 1)."""
    cols = []
    for m in range(-l, l + 1):
        y = sph_harm_y(l, abs(m), theta, phi)
        cols.append(y.real if m == 0 else math.sqrt(2.0) * (y.real if m > 0 else y.imag))
    return np.stack(cols, axis=1)


def test_phong_sphere_singular_values_are_F_l() -> None:
    # Eq. 9: on the sphere sigma = F_l (2l + 1 times). Gauss–Legendre 40 x trapezoid 40 integrates the clamped
    # lobe (C^{s-1} at its cut-off) to ~1e-8 (design notes §4.4); 1e-6 is the requirement.
    for s in (10, 30):
        res = factorize(parse_brdf(f"phong:s={s}"), domain="sphere", n_theta=40, n_values=100)
        f_l = phong_transfer(float(s), 9)
        for l in range(10):
            band = res.singular_values[l * l : (l + 1) ** 2]
            assert np.max(np.abs(band - f_l[l])) < 1e-6, (s, l, band, f_l[l])
            assert set(res.frequencies[l * l : (l + 1) ** 2]) == set(range(l + 1))


def test_sphere_singular_subspaces_are_sh_bands() -> None:
    # Degenerate values: compare subspaces, never vectors. g spans {Y_lm}; the operator maps Y_lm to
    # F_l (-1)^m Y_lm (eq. 9: Y_lm(R) = (-1)^m Y_lm(w_o)), checked on the matrix itself.
    # The clamped lobe (C^9 at its cut-off) is not a polynomial: at 24 x 24 nodes the odd bands carry a quadrature
    # error of 4e-8 in angle and 4e-9 in the matrix action (16 nodes: 2e-5, 4e-6; 32: 7e-10, 6e-11).
    n = 24
    a = weighted_matrix("phong:s=10", "sphere", n, n)
    g = make_grid("sphere", n, n)
    th, ph = np.repeat(g.theta, n), np.tile(g.phi, n)
    sw = np.sqrt(g.weights)[:, None]
    u, s, vt = np.linalg.svd(a)
    f_l = phong_transfer(10.0, 3)
    for l in range(4):
        y = real_sh(l, th, ph) * sw
        lo, hi = l * l, (l + 1) ** 2
        assert np.max(subspace_angles(vt[lo:hi].T, y)) < 1e-6
        assert np.max(subspace_angles(u[:, lo:hi], y)) < 1e-6
        sign = np.array([(-1.0) ** m for m in range(-l, l + 1)])
        np.testing.assert_allclose(a @ y, f_l[l] * y * sign, atol=1e-8)


def test_hemisphere_modes_keep_a_single_m() -> None:
    # Paper §3.4, Fig. 4: over the hemisphere the modes mix l but not m. Checked on the dense SVD, where nothing
    # imposes it, by the energy of each singular vector per azimuthal frequency |m|.
    n_t, n_p = 12, 16
    a = weighted_matrix("phong:s=10", "hemisphere", n_t, n_p)
    u, s, vt = np.linalg.svd(a)
    checked = 0
    for k in range(24):
        # only vectors whose value is separated from every other value are unique up to an (m, -m) rotation
        gaps = np.abs(s - s[k]) / s[0]
        gaps[k] = np.inf
        partner = np.argmin(gaps)
        if gaps[partner] < 1e-9 and k < partner:
            continue
        for vec in (vt[k], u[:, k]):
            spec = np.abs(np.fft.rfft(vec.reshape(n_t, n_p), axis=1)) ** 2
            per_m = spec.sum(axis=0)
            assert per_m.max() / per_m.sum() > 1.0 - 1e-8, (k, per_m / per_m.sum())
        checked += 1
    assert checked >= 12


@pytest.mark.parametrize(
    ("spec", "cosine"),
    [("phong:s=20", True), ("microfacet:sigma=0.3", True), ("torrance-sparrow:alpha=0.3,fresnel=none", False)],
)
def test_block_svd_equals_dense_svd(spec: str, cosine: bool) -> None:
    # Same grid, two algorithms: the DFT block diagonalisation is exact, so the values agree to rounding
    # (relative 1e-12 of sigma_1). TS without the cosine is not symmetric: exercises the SVD path of a block.
    kw = {"n_theta": 10, "n_phi": 14, "include_cosine": cosine}
    dense = factorize(parse_brdf(spec), method="dense", n_factors=6, **kw)
    block = factorize(parse_brdf(spec), method="block", n_values=140, n_factors=6, **kw)
    s0 = dense.singular_values[0]
    np.testing.assert_allclose(block.singular_values, dense.singular_values[: block.singular_values.size],
                               atol=1e-12 * s0)
    assert block.terms == dense.terms
    assert block.total_energy == pytest.approx(dense.total_energy, rel=1e-12)
    # block factors are singular pairs of the dense operator: A g = sigma h, orthonormal under the weights
    a = weighted_matrix(spec, "hemisphere", 10, 14) if cosine else None
    w = block.grid.weights
    for f in block.factors:
        gv, hv = f.g.ravel(), f.h.ravel()
        assert np.sum(w * gv * gv) == pytest.approx(1.0, rel=1e-10)
        if a is not None:
            sw = np.sqrt(w)
            np.testing.assert_allclose(a @ (sw * gv), f.sigma * sw * hv, atol=1e-10 * s0)


def test_two_weighted_grids_agree_and_unweighted_does_not() -> None:
    # Gauss–Legendre and the paper's equal-area midpoint grid converge to the same operator: same K, leading
    # values within the midpoint rule's error (measured 5.3e-3 relative at 40 nodes), which is O(h^2): doubling
    # the nodes divides it by about 4 (> 3 asserted).
    b = parse_brdf("phong:s=10")
    gauss = factorize(b, n_theta=40, grid="gauss", n_values=30)
    area = factorize(b, n_theta=40, grid="equal-area", n_values=30)
    area2 = factorize(b, n_theta=80, grid="equal-area", n_values=30)
    assert gauss.terms == area.terms == area2.terms
    err = np.max(np.abs(area.singular_values[:20] / gauss.singular_values[:20] - 1.0))
    err2 = np.max(np.abs(area2.singular_values[:20] / gauss.singular_values[:20] - 1.0))
    assert err < 1e-2 and err2 < err / 3.0, (err, err2)
    # Gauss nodes without their weights (equal weights 2 pi / N): the values are wrong by far more
    g = make_grid("hemisphere", 16, 16)
    k = make_kernel(b)
    d = g.directions()
    unweighted = k.full(d[None, :, :], d[:, None, :]) * (2.0 * np.pi / d.shape[0])
    s_bad = np.linalg.svd(unweighted, compute_uv=False)
    assert abs(s_bad[0] - gauss.singular_values[0]) > 0.05 * gauss.singular_values[0]


def test_closed_form_kernels() -> None:
    # Lambert is rank one: rho = cos(theta_i)/pi -> sigma = ||cos|| ||1|| / pi = 2/sqrt(3) on the hemisphere;
    # without the cosine rho = 1/pi -> sigma = 2 pi / pi = 2.
    with_cos = factorize(parse_brdf("lambert"), n_theta=8)
    assert with_cos.singular_values[0] == pytest.approx(2.0 / math.sqrt(3.0), rel=1e-12)
    assert with_cos.terms == {0.9: 1, 0.95: 1, 0.99: 1}
    without = factorize(parse_brdf("lambert"), n_theta=8, include_cosine=False)
    assert without.singular_values[0] == pytest.approx(2.0, rel=1e-12)

    # An anisotropic callable (dense path): rho = wi_x wo_x + 2 wi_y wo_y -> sigma = 2 ||y||^2, ||x||^2 with
    # ||x||^2 = ||y||^2 = 2 pi / 3 over the hemisphere; rank 2, K = 2 at 99 % (energy 4 : 1 -> 80 % at K = 1).
    def aniso(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return np.asarray(wi[..., 0] * wo[..., 0] + 2.0 * wi[..., 1] * wo[..., 1])

    res = factorize(aniso, n_theta=8, include_cosine=False)
    assert res.method == "dense"
    np.testing.assert_allclose(res.singular_values[:3], [4 * math.pi / 3, 2 * math.pi / 3, 0.0], atol=1e-12)
    assert res.terms == {0.9: 2, 0.95: 2, 0.99: 2}


def test_resolution_convergence_check() -> None:
    ok = convergence(parse_brdf("phong:s=10"), n_theta=24)
    assert ok["converged"] and ok["resolutions"] == [[24, 24], [36, 36]]
    # eq. 14 at sigma = 0.2 is not converged at the paper's 40^4 (64 terms; 60 x 60 nodes: 79; converged 73 at
    # 200 x 256 and 300 x 384, README): the check says so
    bad = convergence(parse_brdf("microfacet:sigma=0.2"), n_theta=40)
    assert not bad["converged"]
    assert bad["terms"][0]["0.99"] == 64


def test_terms_for_thresholds() -> None:
    v = np.sqrt(np.array([50.0, 40.0, 6.0, 3.0, 1.0]))
    assert terms_for(v, 100.0) == {0.9: 2, 0.95: 3, 0.99: 4}
    with pytest.raises(InputError, match="1.5"):
        terms_for(v, 100.0, (1.5,))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"domain": "disk"}, "disk"),
        ({"n_theta": 1}, "n_theta"),
        ({"n_theta": "40"}, "'40'"),
        ({"n_phi": True}, "n_phi"),
        ({"grid": "midpoint"}, "midpoint"),
        ({"thresholds": (0.9, 1.0)}, "thresholds"),
        ({"domain": "sphere", "include_cosine": False}, "hemisphere"),
        ({"method": "fast"}, "fast"),
        ({"n_factors": -1}, "n_factors"),
        ({"method": "dense", "n_theta": 100}, "too large"),
    ],
)
def test_bad_parameters(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        factorize(parse_brdf("phong:s=10"), **kwargs)  # type: ignore[arg-type]


def test_anisotropic_frame_brdfs() -> None:
    # relight.brdf.anisotropic's Ward equals the isotropic Ward for alpha_x = alpha_y: its dense SVD (frame path)
    # equals the isotropic block SVD on the same grid (two models, two algorithms; rounding only).
    kw = {"n_theta": 10, "n_phi": 12}
    aniso = factorize(parse_frame_brdf("ward:alpha_x=0.3,alpha_y=0.3,rho_d=0,rho_s=1"), **kw)
    iso = factorize(parse_brdf("ward:alpha=0.3,rho_d=0,rho_s=1"), n_values=120, **kw)
    assert aniso.method == "dense" and iso.method == "block"
    n = iso.singular_values.size
    np.testing.assert_allclose(aniso.singular_values[:n], iso.singular_values, atol=1e-11 * iso.singular_values[0])
    # Swapping alpha_x and alpha_y turns the BRDF by 90 deg about n: with n_phi divisible by 4 that permutes the
    # grid, so the singular values are identical; a genuinely anisotropic lobe differs from both isotropic ones.
    a = factorize(parse_frame_brdf("ward:alpha_x=0.2,alpha_y=0.4,rho_d=0,rho_s=1"), **kw)
    b = factorize(parse_frame_brdf("ward:alpha_x=0.4,alpha_y=0.2,rho_d=0,rho_s=1"), **kw)
    np.testing.assert_allclose(a.singular_values, b.singular_values, atol=1e-11 * a.singular_values[0])
    assert a.terms == b.terms
    # a lobe about the tangent goes through the frame interface (tangent = +x) and the dense SVD
    kk = factorize(parse_brdf("kajiya-kay:s=8"), n_theta=8)
    assert kk.method == "dense" and kk.terms[0.99] >= 2


def test_bad_brdfs() -> None:
    with pytest.raises(InputError, match="tangent"):
        factorize(parse_brdf("kajiya-kay:s=8"), include_cosine=False)
    with pytest.raises(InputError, match="isotropic"):
        factorize(lambda wi, wo: wi[..., 0], method="block", n_theta=4)
    with pytest.raises(InputError, match="shape"):
        factorize(lambda wi, wo: np.zeros(3), n_theta=4)
    with pytest.raises(InputError, match="cannot factor"):
        factorize(42)


def test_lowrank_blocks_match_full_decomposition(monkeypatch: pytest.MonkeyPatch) -> None:
    # Large blocks (>= LOWRANK_MIN_ROWS rows, lowered here to keep the test small) take the randomized low-rank
    # SVD; against the full eigen/SVD path on the same grid every listed value agrees to the low-rank tolerance
    # (1e-10 of the kernel's norm) and K is identical.
    import relight.factorization as fz

    b = parse_brdf("phong:s=10")
    monkeypatch.setattr(fz, "LOWRANK_MIN_ROWS", 100)
    low = factorize(b, n_theta=120, n_phi=8, n_values=60, n_factors=4)
    monkeypatch.setattr(fz, "LOWRANK_MIN_ROWS", 10**6)
    full = factorize(b, n_theta=120, n_phi=8, n_values=60, n_factors=4)
    k = min(low.singular_values.size, full.singular_values.size)
    assert k >= 60 and low.terms == full.terms
    np.testing.assert_allclose(low.singular_values[:k], full.singular_values[:k],
                               atol=1e-10 * math.sqrt(full.total_energy))
    for a, c in zip(low.factors, full.factors, strict=True):
        assert a.m == c.m and a.sigma == pytest.approx(c.sigma, rel=1e-10)
    # the range finder itself: a rank-5 matrix plus 1e-13 noise is captured with a residual at the noise level
    rng = np.random.default_rng(3)
    m = rng.standard_normal((300, 5)) @ rng.standard_normal((5, 300)) + 1e-13 * rng.standard_normal((300, 300))
    s, resid, u, vh = fz.lowrank_svd(m, 1e-9)
    ref = np.linalg.svd(m, compute_uv=False)
    assert resid <= 1e-9 and s.size == fz.LOWRANK_START
    np.testing.assert_allclose(s[:5], ref[:5], rtol=1e-12)
    np.testing.assert_allclose((u * s) @ vh, m, atol=1e-9)
