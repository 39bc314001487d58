"""SVD of the in-out BRDF factorization and the number of terms K (Mahajan, Tseng & Ramamoorthi 2008, eqs. 2, 10-13).

``factorize`` samples the kernel of ``relight.factor_kernel`` on a weighted grid and returns its singular values
(the sigma_k of eq. 2), the number of terms K capturing 90 / 95 / 99 % of the energy ``sum sigma_k^2`` (the
paper's §3.3–3.4 criterion) and the leading factors g_k (incident) and h_k (outgoing) as images on the grid nodes.

Two algorithms:

* ``dense`` (any kernel, the only one for anisotropic BRDFs): the (n_theta n_phi)^2 matrix ``W^1/2 rho W^1/2``
  and ``numpy.linalg.svd`` (the paper's §3.2 40^4 experiment).
* ``block`` (isotropic kernels): rho depends on phi_i - phi_o only, so on the uniform azimuth grid the matrix is
  block circulant and the unitary DFT in phi diagonalises it into one n_theta x n_theta block per azimuthal
  frequency m (the paper's §3.4 remark that m does not mix):
  ``B_m = W_mu^1/2 C_{-m} W_mu^1/2``, ``C_m[a, b] = (2 pi / n_phi) sum_j rho(mu_a, mu_b, phi_j) e^{-i m phi_j}``.
  Its singular values, with multiplicity 1 for m = 0 (and m = n_phi / 2) and 2 otherwise (the pair +-m), are
  exactly those of the dense matrix on the same grid, for O(n_theta^2 n_phi) evaluations and one small SVD per
  frequency instead of an O((n_theta n_phi)^3) SVD. Blocks are visited by decreasing Frobenius norm and the visit
  stops once the largest unvisited norm lies below the K-th singular value at the highest threshold (no unvisited
  value can then enter the top K; the total energy is known exactly from the samples). The factors are
  ``g = v_a W_a^{-1/2} e^{i m phi} / sqrt(2 pi)`` (real pairs: cos and sin), h likewise from u.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from relight import validate
from relight.errors import InputError
from relight.factor_kernel import Grid, Kernel, make_grid, make_kernel

FloatArray = NDArray[np.float64]

#: Energy fractions of the paper's §3.4 ("99 % ... 90 % or 95 % could as well be used").
THRESHOLDS: tuple[float, ...] = (0.9, 0.95, 0.99)
#: Memory for the azimuthal blocks held at once (bytes); more frequencies are handled in further passes.
BLOCK_MEMORY = 256 * 2**20
#: Kernel samples evaluated at once (elements of one chunk of rows).
CHUNK_ELEMS = 2**21
#: Blocks of at least this many rows use the randomized low-rank SVD (:func:`lowrank_svd`) instead of a full one.
LOWRANK_MIN_ROWS = 256
#: First rank tried by :func:`lowrank_svd` (doubled until the residual is met).
LOWRANK_START = 48
#: Residual of a low-rank block relative to the whole kernel's norm sqrt(sum sigma^2): values below it are dropped
#: and every returned value is exact to it, far below any K threshold's resolution.
LOWRANK_TOL = 1e-10
#: Relative distance within which singular values count as one degenerate group (quadrature error of the sphere's
#: 2l + 1 copies of F_l: 2e-10 at 40 x 40, bench/factorize.py; pairs +-m of the block SVD are bit-identical).
DEGENERATE_RTOL = 1e-8
#: Relative slack when comparing a cumulative energy with a threshold (rounding of sums of sigma^2).
_ENERGY_SLACK = 1e-12


@dataclass(frozen=True)
class Factor:
    """One term of eq. 2: sigma, its azimuthal frequency m (block method; -1 for dense) and the factor images
    ``g`` (incident) and ``h`` (outgoing), each (n_theta, n_phi) on the grid nodes, orthonormal in L^2."""

    sigma: float
    m: int
    g: FloatArray
    h: FloatArray


@dataclass
class Factorization:
    """The result of :func:`factorize` (see the module docstring)."""

    singular_values: FloatArray  # descending; complete down to ``complete_below``
    frequencies: NDArray[np.int64]  # azimuthal frequency |m| of each value (-1 for the dense method)
    total_energy: float  # sum of all sigma^2 = int int rho^2 over the grid
    terms: dict[float, int]
    grid: Grid
    method: str
    include_cosine: bool
    complete_below: float  # every singular value above this is listed
    factors: list[Factor] = field(default_factory=list)
    seconds: float = 0.0
    cpu_seconds: float = 0.0  # process CPU time (all threads): comparable across loads, unlike wall-clock
    blocks_decomposed: int = 0

    @property
    def terms_whole(self) -> dict[float, int]:
        """K per threshold rounded up to whole degenerate groups (:func:`whole_groups`)."""
        return {t: whole_groups(self.singular_values, k) for t, k in self.terms.items()}

    def captured(self, k: int) -> float:
        """Energy fraction of the first k terms."""
        return float(np.sum(self.singular_values[:k] ** 2) / self.total_energy) if self.total_energy > 0 else 1.0

    def as_dict(self, max_values: int = 400) -> dict[str, Any]:
        return {
            "terms": {f"{t:g}": k for t, k in self.terms.items()},
            "terms_whole_groups": {f"{t:g}": k for t, k in self.terms_whole.items()},
            "singular_values": [float(x) for x in self.singular_values[:max_values]],
            "frequencies": [int(x) for x in self.frequencies[:max_values]],
            "total_energy": self.total_energy,
            "complete_below": self.complete_below,
            "method": self.method,
            "domain": self.grid.domain,
            "grid": self.grid.kind,
            "n_theta": self.grid.n_theta,
            "n_phi": self.grid.n_phi,
            "include_cosine": self.include_cosine,
            "quantity": "f_r cos(theta_i)" if self.include_cosine else "f_r",
            "blocks_decomposed": self.blocks_decomposed,
            "seconds": self.seconds,
            "cpu_seconds": self.cpu_seconds,
        }


def terms_for(values: FloatArray, total: float, thresholds: tuple[float, ...] = THRESHOLDS) -> dict[float, int]:
    """Smallest K with ``sum_{k<=K} sigma_k^2 >= tau * total`` for every threshold tau (values descending)."""
    for t in thresholds:
        validate.in_range("thresholds", t, 0.0, 1.0, lo_open=True, hi_open=True)
    cum = np.cumsum(np.asarray(values, dtype=np.float64) ** 2)
    out: dict[float, int] = {}
    for t in thresholds:
        k = int(np.searchsorted(cum, t * total * (1.0 - _ENERGY_SLACK))) + 1
        out[float(t)] = min(k, int(cum.size)) if cum.size else 0
    return out


def whole_groups(values: FloatArray, k: int, rtol: float = DEGENERATE_RTOL) -> int:
    """K extended over the rest of the k-th value's degenerate group (values within rtol of it), so that a
    truncation never splits a pair (m, -m) or, on the sphere, a band: the full sum of such a group is
    frame-invariant, a split one is not (design notes §4.5.8)."""
    if k <= 0 or k >= values.size:
        return k
    ref = values[k - 1]
    while k < values.size and abs(values[k] - ref) <= rtol * max(abs(ref), 1e-300):
        k += 1
    return k


def _dense(kernel: Kernel, grid: Grid, thresholds: tuple[float, ...], n_factors: int) -> Factorization:
    dirs = grid.directions()
    sw = np.sqrt(grid.weights)
    n = dirs.shape[0]
    a = np.empty((n, n))
    rows = max(1, CHUNK_ELEMS // n)
    for r in range(0, n, rows):  # rows: outgoing w_o; columns: incident w_i
        a[r : r + rows] = kernel.full(dirs[None, :, :], dirs[r : r + rows, None, :])
    a *= sw[:, None] * sw[None, :]
    if n_factors > 0:
        u, s, vt = np.linalg.svd(a)
    else:
        s = np.linalg.svd(a, compute_uv=False)
    total = float(np.sum(a * a))
    factors = []
    shape = (grid.n_theta, grid.n_phi)
    for k in range(min(n_factors, s.size)):
        factors.append(Factor(sigma=float(s[k]), m=-1, g=(vt[k] / sw).reshape(shape), h=(u[:, k] / sw).reshape(shape)))
    return Factorization(
        singular_values=s, frequencies=np.full(s.size, -1, dtype=np.int64), total_energy=total,
        terms=terms_for(s, total, thresholds), grid=grid, method="dense", include_cosine=kernel.include_cosine,
        complete_below=0.0, factors=factors,
    )


def _multiplicity(m: int, n_phi: int) -> int:
    return 1 if m == 0 or 2 * m == n_phi else 2


def _assemble(kernel: Kernel, grid: Grid, keep: list[int], real: bool, energy: FloatArray | None) -> NDArray[Any]:
    """Blocks B_m for m in ``keep`` (len(keep), n_theta, n_theta); accumulates every frequency's ||B_m||^2."""
    assert kernel.iso is not None
    n, n_phi = grid.n_theta, grid.n_phi
    sw = np.sqrt(grid.w_mu)
    blocks = np.empty((len(keep), n, n), dtype=np.float64 if real else np.complex128)
    idx = np.asarray(keep, dtype=np.intp)
    rows = max(1, CHUNK_ELEMS // (n * n_phi))
    for r in range(0, n, rows):
        mu_o = grid.mu[r : r + rows]
        vals = kernel.iso(mu_o[:, None, None], grid.mu[None, :, None], grid.phi[None, None, :])
        spec = np.conj(np.fft.rfft(vals, axis=-1)) * (2.0 * np.pi / n_phi)  # C_{-m} for m = 0 .. n_phi // 2
        spec *= (sw[r : r + rows, None] * sw[None, :])[..., None]
        if energy is not None:
            energy += np.sum(spec.real**2 + spec.imag**2, axis=(0, 1))
        part = np.moveaxis(spec[..., idx], -1, 0)
        blocks[:, r : r + rows, :] = part.real if real else part
    return blocks


def _block_values(b: NDArray[Any]) -> FloatArray:
    """All singular values of a small block: |eigenvalues| of a real symmetric block (LAPACK syevd: about 3x cheaper
    than an SVD), else the SVD's."""
    if np.isrealobj(b) and np.allclose(b, b.T, rtol=0.0, atol=1e-13 * max(float(np.abs(b).max()), 1e-300)):
        ev = scipy.linalg.eigh(b, eigvals_only=True, driver="evd", check_finite=False)
        return np.asarray(np.sort(np.abs(ev))[::-1], dtype=np.float64)
    return np.asarray(np.linalg.svd(b, compute_uv=False), dtype=np.float64)


def lowrank_svd(b: NDArray[Any], tol: float, *, seed: int = 0) -> tuple[FloatArray, float, NDArray[Any], NDArray[Any]]:
    """Leading singular triplets of b up to a residual ``||b - Q Q^H b||_F <= tol``: ``(s, residual, u, vh)``.

    Randomized range finder with two power iterations (Halko, Martinsson & Tropp 2011, Algs. 4.4 and 5.1), the rank
    doubled from ``LOWRANK_START`` until the *measured* residual meets tol, so every singular value of b is matched
    to within tol (Weyl) and every value not returned is below tol. Falls back to the full SVD (residual 0) once the
    rank reaches half the block.
    """
    n = min(b.shape)
    rng = np.random.default_rng(seed)
    k = LOWRANK_START
    while 2 * k < n:
        q = np.linalg.qr(b @ rng.standard_normal((b.shape[1], k)))[0]
        for _ in range(2):
            q = np.linalg.qr(b @ np.linalg.qr(b.conj().T @ q)[0])[0]
        small = q.conj().T @ b
        resid = float(np.linalg.norm(b - q @ small))
        if resid <= tol:
            u, s, vh = np.linalg.svd(small, full_matrices=False)
            return np.asarray(s, dtype=np.float64), resid, q @ u, vh
        k *= 2
    u, s, vh = np.linalg.svd(b, full_matrices=False)
    return np.asarray(s, dtype=np.float64), 0.0, u, vh


def _block(
    kernel: Kernel, grid: Grid, thresholds: tuple[float, ...], n_factors: int, n_values: int
) -> Factorization:
    n_phi, n = grid.n_phi, grid.n_theta
    n_freq = n_phi // 2 + 1
    real = kernel.is_even()
    per_block = n * n * (8 if real else 16)
    window = max(1, min(n_freq, BLOCK_MEMORY // per_block))
    energy = np.zeros(n_freq)
    top = max(thresholds)
    values: dict[int, FloatArray] = {}
    keep = list(range(window))  # first pass: the lowest frequencies, and every frequency's energy
    blocks = _assemble(kernel, grid, keep, real, energy)
    total = float(sum(energy[m] * _multiplicity(m, n_phi) for m in range(n_freq)))
    pending = set(range(n_freq))
    # the K-th largest value so far at the top threshold (never above the final one, so skipping blocks whose
    # Frobenius norm lies below it is exact)
    sigma_k = -1.0
    residual = 0.0  # largest residual of a low-rank block: no value of it above this is missing
    while True:
        stored = {m: blocks[j] for j, m in enumerate(keep)}
        for m in sorted(keep, key=lambda q: -energy[q]):
            pending.discard(m)
            if math.sqrt(energy[m]) < sigma_k:  # every singular value of B_m is below the K-th: cannot count
                continue
            if n >= LOWRANK_MIN_ROWS:
                vals_m, resid, _, _ = lowrank_svd(stored[m], LOWRANK_TOL * math.sqrt(total))
                residual = max(residual, resid)
                values[m] = vals_m
            else:
                values[m] = _block_values(stored[m])
            merged = np.sort(np.concatenate([np.repeat(v, _multiplicity(q, n_phi)) for q, v in values.items()]))
            merged = merged[::-1]
            k_top = max(terms_for(merged, total, (top,))[top], n_values, n_factors)
            sigma_k = float(merged[min(k_top, merged.size) - 1])
        pending = {p for p in pending if math.sqrt(energy[p]) >= sigma_k}
        if not pending:
            break
        keep = sorted(pending, key=lambda q: -energy[q])[:window]
        blocks = _assemble(kernel, grid, keep, real, None)
    undecomposed = [m for m in range(n_freq) if m not in values]
    bound = max(math.sqrt(max((energy[p] for p in undecomposed), default=0.0)), residual)
    vals = np.concatenate([np.repeat(v, _multiplicity(q, n_phi)) for q, v in values.items()])
    freqs = np.concatenate([np.full(v.size * _multiplicity(q, n_phi), q, dtype=np.int64) for q, v in values.items()])
    order = np.argsort(-vals, kind="stable")
    vals, freqs = vals[order], freqs[order]
    listed = vals >= bound
    res = Factorization(
        singular_values=vals[listed], frequencies=freqs[listed], total_energy=total,
        terms=terms_for(vals, total, thresholds), grid=grid, method="block", include_cosine=kernel.include_cosine,
        complete_below=bound, blocks_decomposed=len(values),
    )
    if n_factors > 0:
        res.factors = _block_factors(kernel, grid, res, stored, real, n_factors)
    return res


def _block_factors(
    kernel: Kernel, grid: Grid, res: Factorization, stored: dict[int, NDArray[Any]], real: bool, n_factors: int
) -> list[Factor]:
    """Real factor images of the leading n_factors terms (pairs +-m as cos/sin), sorted by sigma."""
    want: dict[int, int] = {}
    for m in res.frequencies[:n_factors]:
        want[int(m)] = want.get(int(m), 0) + 1
    missing = [m for m in want if m not in stored]
    if missing:
        stored = {**stored, **dict(zip(missing, _assemble(kernel, grid, missing, real, None), strict=True))}
    sw = np.sqrt(grid.w_mu)
    out: list[Factor] = []
    for m, count in want.items():
        if grid.n_theta >= LOWRANK_MIN_ROWS:
            s, _, u, vh = lowrank_svd(stored[m], LOWRANK_TOL * math.sqrt(res.total_energy))
        else:
            u, s, vh = np.linalg.svd(stored[m])
        n_vec = (count + 1) // 2 if m > 0 and 2 * m != grid.n_phi else count
        for j in range(min(n_vec, s.size)):
            gu, hu = np.conj(vh[j]) / sw, u[:, j] / sw
            wave = np.exp(1j * m * grid.phi)[None, :] / math.sqrt(2.0 * math.pi)
            g, h = gu[:, None] * wave, hu[:, None] * wave
            if _multiplicity(m, grid.n_phi) == 1:
                # a real block has real vectors up to a common phase; rotate g to real and h with it
                phase = np.exp(-1j * np.angle(g.ravel()[np.argmax(np.abs(g))]))
                out.append(Factor(float(s[j]), m, np.real(g * phase), np.real(h * phase)))
            else:
                out.append(Factor(float(s[j]), m, math.sqrt(2.0) * g.real, math.sqrt(2.0) * h.real))
                out.append(Factor(float(s[j]), m, math.sqrt(2.0) * g.imag, math.sqrt(2.0) * h.imag))
    out.sort(key=lambda f: -f.sigma)
    return out[:n_factors]


def factorize(
    brdf: Any,
    *,
    domain: str = "hemisphere",
    n_theta: int = 40,
    n_phi: int | None = None,
    grid: str = "gauss",
    include_cosine: bool = True,
    method: str = "auto",
    thresholds: tuple[float, ...] = THRESHOLDS,
    n_factors: int = 0,
    n_values: int = 0,
) -> Factorization:
    """SVD of the BRDF matrix of ``brdf`` (a lobe, a sum of lobes or a callable f(wi, wo)); see the module docstring.

    ``n_phi`` defaults to ``n_theta`` (the paper's N^4 grid). ``method``: ``auto`` (block for isotropic kernels,
    dense otherwise), ``block`` or ``dense``. ``n_factors``: leading factor images to return; ``n_values``: the
    block method decomposes enough frequencies to list at least this many singular values (the dense one lists all).
    """
    if method not in ("auto", "block", "dense"):
        raise InputError(f"method must be auto, block or dense, got {method!r}")
    for name, v in (("n_factors", n_factors), ("n_values", n_values)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise InputError(f"{name} must be a non-negative integer, got {v!r}")
    g = make_grid(domain, n_theta, n_theta if n_phi is None else n_phi, grid)
    kernel = make_kernel(brdf, domain=domain, include_cosine=include_cosine)
    thresholds = tuple(sorted(float(t) for t in thresholds))
    terms_for(np.zeros(0), 0.0, thresholds)  # validates the thresholds
    if method == "block" and not kernel.isotropic:
        raise InputError(f"{kernel.description}: the block SVD needs an isotropic BRDF; use method='dense'")
    use_block = kernel.isotropic and method != "dense"
    if not use_block and (g.n_theta * g.n_phi) > 6400:
        raise InputError(f"a dense SVD of {g.n_theta} x {g.n_phi} nodes is too large (at most 6400 nodes)")
    t0, c0 = time.perf_counter(), time.process_time()
    res = _block(kernel, g, thresholds, n_factors, n_values) if use_block else _dense(kernel, g, thresholds, n_factors)
    res.seconds = time.perf_counter() - t0
    res.cpu_seconds = time.process_time() - c0
    return res


def convergence(
    brdf: Any, *, scale: float = 1.5, tolerance: float = 0.02, **kwargs: Any
) -> dict[str, Any]:
    """Resolution check: K at the given grid and at a grid ``scale`` times finer in theta and phi.

    ``converged`` when every threshold's K differs by at most ``max(1, tolerance K)``.
    """
    if not 1.0 < scale <= 4.0:
        raise InputError(f"scale must lie in (1, 4], got {scale}")
    coarse = factorize(brdf, **kwargs)
    fine_args = dict(kwargs)
    fine_args["n_theta"] = int(math.ceil(coarse.grid.n_theta * scale))
    fine_args["n_phi"] = int(math.ceil(coarse.grid.n_phi * scale))
    fine = factorize(brdf, **fine_args)
    diffs = {t: abs(fine.terms[t] - coarse.terms[t]) for t in coarse.terms}
    ok = all(d <= max(1.0, tolerance * fine.terms[t]) for t, d in diffs.items())
    return {
        "resolutions": [[coarse.grid.n_theta, coarse.grid.n_phi], [fine.grid.n_theta, fine.grid.n_phi]],
        "terms": [{f"{t:g}": k for t, k in r.terms.items()} for r in (coarse, fine)],
        "converged": ok,
        "tolerance": tolerance,
        "results": (coarse, fine),
    }
