"""Wigner small-d matrices to high degree, and rotation of spherical-harmonic coefficients.

Seed 000 (Ramamoorthi & Hanrahan 2002) rotates the BRDF into the frame of the reflection vector with the matrices
``D^l_{mq}(alpha)`` (Table 1; App. A eq. 14; App. C step 3: ``B_mpq(alpha) = sum_l B_lmpq D^l_mq(alpha)``). This
module evaluates them stably for any degree (tested to l = 2048) and any angle, including 0, pi/2, pi and angles next
to them.

Convention (written once; every function here uses it)
------------------------------------------------------
``d^l_{m'm}(beta) = <l m'| exp(-i beta J_y) |l m>``: the Wigner/Edmonds small-d matrix with the Condon-Shortley
phase (Edmonds 1957 §4.1; Varshalovich et al. 1988 §4.3; Sakurai "Modern Quantum Mechanics" §3.8), e.g.
``d^1_{10}(beta) = -sin(beta)/sqrt(2)``, ``d^{l}_{l,l}(beta) = cos^{2l}(beta/2)``. The full matrix is::

    D^l_{m'm}(alpha, beta, gamma) = exp(-i m' alpha) d^l_{m'm}(beta) exp(-i m gamma)

for the rotation ``R = R_z(alpha) R_y(beta) R_z(gamma)`` (active, right-handed, z-y-z Euler angles; the matrices
act on the SH frame coordinates ``x = sin(theta) cos(phi), y = sin(theta) sin(phi), z = cos(theta)``). With the
orthonormal complex harmonics with Condon-Shortley phase of ``scipy.special.sph_harm_y`` and ducc0,
``Y_lm(theta, phi) = sqrt((2l+1)/(4pi) (l-m)!/(l+m)!) P_l^m(cos theta) exp(i m phi)``, the identity this module
guarantees (and ``tests/relight/test_wigner.py`` checks against scipy) is::

    Y_lm(R^{-1} x) = sum_{m'} Y_lm'(x) D^l_{m'm}(R)

so the field ``f(x) = sum a_lm Y_lm(x)`` rotated actively, ``f'(x) = f(R^{-1} x)``, has coefficients
``a'_{lm'} = sum_m D^l_{m'm}(R) a_lm`` (:func:`relight.alm_rotation.rotate_alm`).

Symmetries (Edmonds 1957 §4.2; used to seed the recursion and checked by the tests)::

    d^l_{m'm}(beta) = (-1)^{m-m'} d^l_{mm'}(beta) = d^l_{-m,-m'}(beta) = d^l_{mm'}(-beta)
    d^l_{m'm}(pi - beta) = (-1)^{l+m'} d^l_{m',-m}(beta)

Relation to the ``spherical`` package (moble; Gumerov-Duraiswami "Wigner H" recursion, arXiv:1403.7698), used
as the independent reference in the tests: its ``H^{m'm}_l(beta)`` satisfies ``d^l_{m'm} = eps_{m'} eps_{-m} H``
with ``eps_k = (-1)^k`` for ``k > 0`` and 1 otherwise, and equals the ``d`` defined here (checked numerically).

Algorithm
---------
For each pair (m, q) the three-term recurrence in the degree (Kostelec & Rockmore 2008, "FFTs on the rotation
group", J. Fourier Anal. Appl. 14; the same recurrence drives libsharp/ducc0's spin-weighted transforms)::

    d^{l+1}_{mq} = (l+1)(2l+1) / sqrt(((l+1)^2 - m^2)((l+1)^2 - q^2))
                   * [ (cos(beta) - m q / (l (l+1))) d^l_{mq}
                       - sqrt((l^2 - m^2)(l^2 - q^2)) / (l (2l+1)) d^{l-1}_{mq} ]

starts at ``l0 = max(|m|, |q|)`` from the closed form (Wigner's sum, Edmonds §4.1, with one surviving term)::

    S(n, k) := d^n_{nk}(beta) = (-1)^{n-k} sqrt(C(2n, n+k)) cos(beta/2)^{n+k} sin(beta/2)^{n-k}

and runs upward. It is forward-stable: from ``l0`` the wanted solution is the growing one through the evanescent
region and both solutions are of the same size in the oscillatory region (as for associated Legendre functions).
The seeds ``S(n, k)`` overflow (binomials to 2^4096) and underflow (powers of sin/cos) in double precision long
before l = 2048, the failure of naive recursions noted in ``docs/facts.md``; here every value is carried as a mantissa
times an integer power of two (the "extended exponent" technique of libsharp, Reinecke 2011) and rescaled by exact
powers of two, so no precision is lost to scaling, and the result is the exact double ``ldexp(mantissa, exponent)``
(a true value below ~1e-308 underflows to 0). The seeds themselves are built by the exact-ratio recursions
``S(n, k) = -sqrt(2n(2n-1)/((n+k)(n-k))) cos(beta/2) sin(beta/2) S(n-1, k)``, ``S(n, n) = cos^2(beta/2)
S(n-1, n-1)`` and ``S(n, -n) = sin^2(beta/2) S(n-1, -(n-1))``, each step rounding once, so their relative error
grows like ``sqrt(n)`` ulps. The factorial (Racah) sum is never used: it is garbage by l ~ 300.

Two further measures keep the error at a few ulps up to l = 2048 (measured against 50-digit mpmath: <= 2e-14
absolute, unitarity <= 1e-14, at beta = 1e-8, 1e-3, pi/2, pi - 1e-6, ...):

* Every angle is first reduced exactly to ``0 <= beta' <= pi/2`` (d is a polynomial in ``c = cos(beta/2)`` and
  ``s = sin(beta/2)``: flipping the sign of one multiplies ``d_mq`` by ``(-1)^(m-q)``; swapping them is
  ``d_mq(beta) = (-1)^(l+m) d_{m,-q}(pi - beta)``), and ``cos(beta)`` enters only as ``1 - 2 s^2``. Rounding
  ``cos(beta)`` instead is a bias repeated at every step and amplified ~l^2 near beta = 0 or pi (3e-12 at l = 300).
* The recurrence is run in Reinsch's difference form (unknowns ``d^l`` and ``d^l - d^{l-1}``, see ``_step``):
  at small beta the sequence varies slowly and the plain three-term form loses ~l^1.5 ulps (1e-12 at l = 2048,
  beta = 1e-3).

Cost: O(lmax * n_m * n_q) per angle for ``n_m`` values of m and ``n_q`` values of q; memory O(n_m * n_q) per angle
for :func:`iter_wigner_d`. The result is accurate for the given double angle (e.g. ``pi - 1e-6``).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray

from relight import validate
from relight.errors import InputError

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int64]

#: Rescaling step of the extended-exponent arithmetic: a mantissa whose magnitude exceeds 2^_SCALE_BITS is
#: multiplied by 2^-_SCALE_BITS (exact) and its exponent raised by _SCALE_BITS. 2^400 ~ 1e120 leaves a margin of
#: ~1e188 below the double overflow threshold for the growth of one recurrence step.
_SCALE_BITS = 400
_SCALE_LIMIT = float(2.0**_SCALE_BITS)


def check_lmax(lmax: int, name: str = "lmax") -> int:
    return validate.at_least(name, lmax, 0)


def _check_beta(beta: ArrayLike) -> FloatArray:
    b = validate.finite_array("beta", np.asarray(beta, dtype=np.float64))
    return b


def _check_indices(values: ArrayLike, lmax: int, name: str) -> IntArray:
    v = np.asarray(values)
    if v.ndim != 1 or v.size == 0:
        raise InputError(f"{name} must be a non-empty 1-D sequence of integers, got shape {v.shape}")
    if not np.issubdtype(v.dtype, np.integer):
        raise InputError(f"{name} must hold integers, got dtype {v.dtype}")
    vi = v.astype(np.int64)
    if np.any(np.abs(vi) > lmax):
        bad = vi[np.abs(vi) > lmax][0]
        raise InputError(f"{name} must satisfy |{name[:-1]}| <= lmax = {lmax}, got {int(bad)}")
    return vi


def iter_wigner_d(
    lmax: int, beta: ArrayLike, qs: ArrayLike, *, ms: ArrayLike | None = None
) -> Iterator[tuple[int, FloatArray]]:
    """Yield ``(l, d)`` for l = 0 .. lmax with ``d[..., i, j] = d^l_{ms[i], qs[j]}(beta)``.

    ``d`` has shape ``beta.shape + (len(ms), len(qs))``; entries with ``|m| > l`` or ``|q| > l`` are 0.
    ``ms`` defaults to ``-lmax .. lmax``. Memory stays O(len(beta) * len(ms) * len(qs)) however large lmax is,
    which is what the SHRM sum ``B_mpq(alpha) = sum_l B_lmpq d^l_mq(alpha)`` (seed 000 App. C step 3) needs.
    Each yielded array is a fresh array the caller may keep. See the module docstring for the convention and the
    recurrence (Kostelec & Rockmore 2008, extended-exponent seeds).
    """
    lmax = check_lmax(lmax)
    b = _check_beta(beta)
    q_arr = _check_indices(qs, lmax, "qs")
    m_arr = np.arange(-lmax, lmax + 1, dtype=np.int64) if ms is None else _check_indices(ms, lmax, "ms")
    out_shape = b.shape + (m_arr.size, q_arr.size)
    flat = b.ravel()
    c = np.cos(0.5 * flat)  # cos(beta/2)
    s = np.sin(0.5 * flat)  # sin(beta/2)
    # d is a polynomial in (c, s) (Wigner's sum, Edmonds §4.1): flipping the sign of one of them multiplies d_mq by
    # (-1)^(m-q), and swapping them (beta -> pi - beta) gives d_mq(beta) = (-1)^(l+m) d_{m,-q}(pi - beta). Both
    # reduce every angle exactly to 0 <= beta' <= pi/2, where the recurrence is run.
    flip = (c * s) < 0.0
    c, s = np.abs(c), np.abs(s)
    refl = s > c
    parity_mq = np.where((m_arr[:, None] - q_arr[None, :]) % 2 == 0, 1.0, -1.0)
    parity_m = np.where(m_arr % 2 == 0, 1.0, -1.0)[:, None]
    groups = []
    for sel, q_eff in ((~refl, q_arr), (refl, -q_arr)):
        idx = np.flatnonzero(sel)
        if idx.size:
            cg, sg = (c[idx], s[idx]) if q_eff is q_arr else (s[idx], c[idx])
            groups.append((idx, q_eff is not q_arr, _recurse(lmax, cg, sg, m_arr, q_eff)))
    gens = [g for _, _, g in groups]
    for ell in range(lmax + 1):
        out = np.empty((flat.size, m_arr.size, q_arr.size))
        for (idx, reflected, _), gen in zip(groups, gens, strict=True):
            _, vals = next(gen)
            out[idx] = vals * (parity_m if ell % 2 == 0 else -parity_m) if reflected else vals
        out[flip] *= parity_mq
        yield ell, out.reshape(out_shape)


def _recurse(
    lmax: int, c: FloatArray, s: FloatArray, ms: IntArray, qs: IntArray
) -> Iterator[tuple[int, FloatArray]]:
    """The recursion of the module docstring for ``c = cos(beta/2) >= s = sin(beta/2) >= 0`` (nb,).

    Yields ``(l, d)`` with ``d`` of shape (nb, len(ms), len(qs)); see :func:`_step` for the form of the recurrence.
    """
    nb, nq = c.size, qs.size
    # Internally the m values are ordered by |m| so that the m's active at degree l (|m| <= l) form a prefix.
    order = np.argsort(np.abs(ms), kind="stable")
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    m_sorted = ms[order]
    n_active = np.searchsorted(np.abs(m_sorted), np.arange(lmax + 1), side="right")  # count of |m| <= l, per l
    kmax = int(np.abs(qs).max())

    s2 = s * s
    two_s2 = 2.0 * s2  # 1 - cos(beta), to full relative precision
    cs = c * s  # sin(beta)/2
    cc = c * c

    # Seeds S(n, k) = d^n_{nk}(beta) for |k| <= min(n, kmax), as mantissa * 2^exponent; column k + kmax.
    s_mant = np.zeros((nb, 2 * kmax + 1))
    s_exp = np.zeros((nb, 2 * kmax + 1), dtype=np.int64)
    s_mant[:, kmax] = 1.0  # S(0, 0) = d^0_00 = 1

    # Recurrence state for the |m|-sorted m's: d^l and the difference d^l - d^{l-1}, as mantissas sharing the
    # power-of-two exponent `ex`.
    x = np.zeros((nb, ms.size, nq))
    dx = np.zeros((nb, ms.size, nq))
    ex = np.zeros((nb, ms.size, nq), dtype=np.int64)

    for ell in range(lmax + 1):
        if ell > 0:
            _advance_seeds(ell, kmax, s_mant, s_exp, cs, cc, s2)
        na_prev = int(n_active[ell - 1]) if ell > 0 else 0
        na = int(n_active[ell])
        if ell > 0 and na_prev > 0:
            sl = slice(0, na_prev)
            _step(ell - 1, two_s2, m_sorted[sl], qs, x[:, sl], dx[:, sl], ex[:, sl])
        _plant_seeds(ell, kmax, s_mant, s_exp, m_sorted[:na], qs, na_prev, x[:, :na], dx[:, :na], ex[:, :na])
        out = np.zeros((nb, ms.size, nq))
        out[:, :na] = np.ldexp(x[:, :na], ex[:, :na])
        yield ell, out[:, inverse]


def _advance_seeds(
    n: int, kmax: int, s_mant: FloatArray, s_exp: IntArray, cs: FloatArray, cc: FloatArray, ss: FloatArray
) -> None:
    """Move ``S(n-1, k)`` to ``S(n, k)`` in place (module docstring, exact-ratio seed recursions)."""
    top = min(n - 1, kmax)
    ks = np.arange(-top, top + 1)
    cols = slice(kmax - top, kmax + top + 1)
    diag_hi = s_mant[:, kmax + top] * cc if n <= kmax else None  # S(n, n) = cos^2(beta/2) S(n-1, n-1)
    diag_lo = s_mant[:, kmax - top] * ss if n <= kmax else None  # S(n, -n) = sin^2(beta/2) S(n-1, -(n-1))
    ratio = -np.sqrt((2.0 * n) * (2.0 * n - 1.0) / ((n + ks) * (n - ks)))
    s_mant[:, cols] *= ratio[None, :] * cs[:, None]
    if diag_hi is not None and diag_lo is not None:
        s_mant[:, kmax + n] = diag_hi
        s_exp[:, kmax + n] = s_exp[:, kmax + top]
        s_mant[:, kmax - n] = diag_lo
        s_exp[:, kmax - n] = s_exp[:, kmax - top]
    mant, de = np.frexp(s_mant)
    s_mant[...] = mant
    s_exp += de


def _step(ell: int, two_s2: FloatArray, m: IntArray, qs: IntArray, x: FloatArray, dx: FloatArray, ex: IntArray) -> None:
    """Advance ``(d^ell, d^ell - d^{ell-1})`` to ``(d^{ell+1}, d^{ell+1} - d^ell)`` in place.

    Notes
    -----
    With ``P_k = (k^2 - m^2)(k^2 - q^2)``, the recurrence of the module docstring reads
    ``d^{l+1} = a (T0 - 2 s^2) d^l - a b d^{l-1}`` with ``a = (l+1)(2l+1)/sqrt(P_{l+1})``,
    ``T0 = 1 - m q/(l(l+1))``, ``a b = (l+1) sqrt(P_l) / (l sqrt(P_{l+1}))`` and ``2 s^2 = 1 - cos(beta)``.
    In the three-term form the two large terms nearly cancel when beta is small (the sequence varies slowly), and
    rounding errors grow like ``l^1.5`` (1e-12 at l = 2048, beta = 1e-3). We use instead the difference form of
    Reinsch's modification (Stoer & Bulirsch, *Introduction to Numerical Analysis*, §2.3.3) in the unknowns
    ``d^l`` and ``Delta^l = d^l - d^{l-1}``::

        Delta^{l+1} = a b Delta^l + g d^l - 2 a s^2 d^l,     d^{l+1} = d^l + Delta^{l+1},

    where ``g = a (T0 - b) - 1`` (0 when m = q) is evaluated without cancellation: writing ``sqrt(P_k) = A_k - r_k``
    with ``A_k = k^2 - (m^2 + q^2)/2``, ``D = (m^2 - q^2)/2`` and ``r_k = D^2 / (A_k + sqrt(P_k)) >= 0``,
    ``g = [(2l+1)(m - q)^2 / 2 + (l+1) r_l + l r_{l+1}] / (l sqrt(P_{l+1}))``. At l = 0 (only m = q = 0):
    ``a = 1``, ``a b = g = 0``, giving ``d^1_00 = 1 - 2 s^2 = cos(beta)``.
    """
    lf = float(ell)
    mf = m.astype(np.float64)[:, None]
    qf = qs.astype(np.float64)[None, :]
    started = np.abs(qs)[None, :] <= ell  # entries with |q| > ell are still 0 and are seeded later
    m2, q2 = mf * mf, qf * qf
    half_sum, half_diff = 0.5 * (m2 + q2), 0.5 * (m2 - q2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sp1 = np.sqrt(((lf + 1.0) ** 2 - m2) * ((lf + 1.0) ** 2 - q2))  # sqrt(P_{l+1}) > 0 on started entries
        a = np.where(started, (lf + 1.0) * (2.0 * lf + 1.0) / sp1, 0.0)
        if ell == 0:
            ab = np.zeros_like(a)
            g = np.zeros_like(a)
        else:
            sp0 = np.sqrt(np.maximum((lf * lf - m2) * (lf * lf - q2), 0.0))
            ab = np.where(started, (lf + 1.0) * sp0 / (lf * sp1), 0.0)
            big_a0 = lf * lf - half_sum
            big_a1 = (lf + 1.0) ** 2 - half_sum
            dd = half_diff * half_diff
            r0 = np.where(dd > 0.0, dd / (big_a0 + sp0), 0.0)
            r1 = np.where(dd > 0.0, dd / (big_a1 + sp1), 0.0)
            num = (2.0 * lf + 1.0) * 0.5 * (mf - qf) ** 2 + (lf + 1.0) * r0 + lf * r1
            g = np.where(started, num / (lf * sp1), 0.0)
    new_dx = (ab[None] * dx + g[None] * x) - (a[None] * two_s2[:, None, None]) * x
    dx[...] = new_dx
    x += new_dx
    big = np.abs(x) > _SCALE_LIMIT
    if np.any(big):
        x[big] = np.ldexp(x[big], -_SCALE_BITS)
        dx[big] = np.ldexp(dx[big], -_SCALE_BITS)
        ex[big] += _SCALE_BITS


def _plant_seeds(
    n: int,
    kmax: int,
    s_mant: FloatArray,
    s_exp: IntArray,
    m: IntArray,
    qs: IntArray,
    na_prev: int,
    x: FloatArray,
    dx: FloatArray,
    ex: IntArray,
) -> None:
    """Write the starting values d^n_{mq} for every (m, q) with max(|m|, |q|) = n (module docstring).

    The difference ``d^n - d^{n-1}`` starts equal to ``d^n`` (the value at n - 1 is 0; it only ever enters
    multiplied by ``sqrt(P_n) = 0``).
    """
    if n == 0:
        hit = qs == 0
        x[:, :, hit] = 1.0  # d^0_00 = 1 (only m = 0 is active)
        dx[:, :, hit] = 1.0
        return
    # (a) new rows |m| = n, all |q| <= n: d^n_{n q} = S(n, q), d^n_{-n, q} = (-1)^{n+q} S(n, -q).
    rows = np.arange(na_prev, m.size)
    qok = np.abs(qs) <= n
    if rows.size and np.any(qok):
        qsel = qs[qok]
        for r in rows:
            if m[r] > 0:
                col = kmax + qsel
                sign = np.ones(qsel.size)
            else:
                col = kmax - qsel
                sign = np.where((n + qsel) % 2 == 0, 1.0, -1.0)
            x[:, r, qok] = s_mant[:, col] * sign[None, :]
            dx[:, r, qok] = x[:, r, qok]
            ex[:, r, qok] = s_exp[:, col]
    # (b) new columns |q| = n on the older rows |m| < n: d^n_{m n} = (-1)^{n-m} S(n, m), d^n_{m,-n} = S(n, -m).
    if na_prev == 0:
        return
    mo = m[:na_prev]
    for j in np.flatnonzero(np.abs(qs) == n):
        if qs[j] > 0:
            col = kmax + mo
            sign = np.where((n - mo) % 2 == 0, 1.0, -1.0)
        else:
            col = kmax - mo
            sign = np.ones(mo.size)
        x[:, :na_prev, j] = s_mant[:, col] * sign[None, :]
        dx[:, :na_prev, j] = x[:, :na_prev, j]
        ex[:, :na_prev, j] = s_exp[:, col]


def wigner_d(lmax: int, beta: ArrayLike, qmax: int | None = None) -> FloatArray:
    """All ``d^l_{mq}(beta)`` for ``0 <= l <= lmax``, ``|m| <= lmax``, ``|q| <= qmax`` (module docstring convention).

    Returns shape ``beta.shape + (lmax+1, 2*lmax+1, 2*qmax+1)`` indexed ``[..., l, m + lmax, q + qmax]``, zero where
    ``|m| > l`` or ``|q| > l``. ``qmax`` defaults to ``lmax`` (full matrices, O(lmax^3) per angle). The array has
    ``(lmax+1)(2 lmax+1)(2 qmax+1)`` doubles per angle (740 MB at lmax = 2048, qmax = 5): for large lmax use
    :func:`wigner_d_q` or :func:`iter_wigner_d`.
    """
    lmax = check_lmax(lmax)
    qm = lmax if qmax is None else check_lmax(qmax, "qmax")
    if qm > lmax:
        raise InputError(f"qmax must be <= lmax = {lmax}, got {qm}")
    b = _check_beta(beta)
    out = np.zeros(b.shape + (lmax + 1, 2 * lmax + 1, 2 * qm + 1))
    for ell, d in iter_wigner_d(lmax, b, np.arange(-qm, qm + 1)):
        out[..., ell, :, :] = d
    return out


def wigner_d_q(lmax: int, beta: ArrayLike, q: int) -> FloatArray:
    """``d^l_{mq}(beta)`` for one q, all l <= lmax and |m| <= lmax: shape ``beta.shape + (lmax+1, 2*lmax+1)``.

    Indexed ``[..., l, m + lmax]``; zero where ``|m| > l`` or ``|q| > l``. Same convention and recurrence as
    :func:`wigner_d` (module docstring); O(lmax^2) work and memory per angle.
    """
    lmax = check_lmax(lmax)
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or abs(int(q)) > lmax:
        raise InputError(f"q must be an integer with |q| <= lmax = {lmax}, got {q!r}")
    b = _check_beta(beta)
    out = np.zeros(b.shape + (lmax + 1, 2 * lmax + 1))
    for ell, d in iter_wigner_d(lmax, b, [int(q)]):
        out[..., ell, :] = d[..., 0]
    return out


def wigner_d_matrix(ell: int, beta: ArrayLike) -> FloatArray:
    """The full ``(2l+1) x (2l+1)`` matrix ``d^l_{m'm}(beta)``, indexed ``[..., m' + l, m + l]``.

    O(l^3) per angle (the recurrence runs through all lower degrees). Convention: module docstring.
    """
    ell = check_lmax(ell, "l")
    full = np.arange(-ell, ell + 1)
    d = np.zeros(())
    for _, d_l in iter_wigner_d(ell, beta, full, ms=full):
        d = d_l
    return d


def wigner_D_matrix(ell: int, alpha: float, beta: float, gamma: float) -> ComplexArray:
    """``D^l_{m'm}(R) = exp(-i m' alpha) d^l_{m'm}(beta) exp(-i m gamma)`` for ``R = R_z(alpha) R_y(beta) R_z(gamma)``.

    Indexed ``[m' + l, m + l]``; satisfies ``Y_lm(R^{-1} x) = sum_m' Y_lm'(x) D^l_{m'm}(R)`` (module docstring).
    """
    d = wigner_d_matrix(ell, float(beta))
    mm = np.arange(-ell, ell + 1)
    return np.asarray(np.exp(-1j * mm * alpha)[:, None] * d * np.exp(-1j * mm * gamma)[None, :], dtype=np.complex128)
