"""relight.raycast: Embree against the NumPy Möller–Trumbore oracle; the self-intersection offset on a plane."""

from __future__ import annotations

import numpy as np

from relight.mesh import RawMesh, build, sample_mesh
from relight.raycast import OFFSET_FRACTION, RayCaster, moller_trumbore, ray_offset
from relight.visibility import fibonacci_sphere, free_rays


def test_moller_trumbore_on_one_triangle() -> None:
    p0, p1, p2 = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    o = np.array([[0.25, 0.5, 2.0], [0.8, 0.8, 1.0], [0.25, 0.25, -1.0]])
    d = np.array([[0.0, 0, -1], [0.0, 0, -1], [0.0, 0, -1]])
    t, u, v = moller_trumbore(p0, p1, p2, o, d)
    # hit at t = 2 with barycentrics (u, v) = (x, y); outside (u + v = 1.6 > 1); behind the origin (t = -1)
    assert np.allclose([t[0], u[0], v[0]], [2.0, 0.25, 0.5]) and np.isnan(t[1]) and t[2] == -1.0


def test_embree_finds_the_same_hits_as_the_numpy_oracle() -> None:
    mesh = sample_mesh("bunny").normalised()
    rng = np.random.default_rng(42)
    n = 1500
    origins = rng.uniform(-1.5, 1.5, (n, 3))
    targets = rng.uniform(-0.5, 0.5, (n, 3))
    dirs = targets - origins
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    fast = RayCaster(mesh.positions, mesh.faces).intersect(origins, dirs)
    slow = RayCaster(mesh.positions, mesh.faces, backend="numpy").intersect(origins, dirs)
    # Embree intersects in float32: a ray passing within ~1e-6 of an edge may pick either neighbour. Such rays
    # are recognised by the oracle's barycentric margin min(u, v, 1 - u - v) and left out (a handful).
    margin = np.minimum(np.minimum(slow.u, slow.v), 1.0 - slow.u - slow.v)
    clear = (slow.prim < 0) | (margin > 1e-5)
    assert np.count_nonzero(~clear) < 0.01 * n
    assert np.count_nonzero(slow.prim >= 0) > 0.3 * n  # the test exercises hits and misses alike
    assert np.array_equal(fast.prim[clear], slow.prim[clear])
    hit = clear & (slow.prim >= 0)
    assert np.abs(fast.t[hit] - slow.t[hit]).max() < 1e-5  # float32 rounding of distances ~1
    assert np.abs(fast.u[hit] - slow.u[hit]).max() < 1e-4 and np.abs(fast.v[hit] - slow.v[hit]).max() < 1e-4
    # occlusion queries agree with the nearest-hit queries, and tfar cuts hits beyond it
    assert np.array_equal(RayCaster(mesh.positions, mesh.faces).occluded(origins, dirs), fast.prim >= 0)
    near = RayCaster(mesh.positions, mesh.faces).occluded(origins, dirs, tfar=1.0)
    sure = clear & (np.abs(slow.t - 1.0) > 1e-5)  # float32 distances within 1e-5 of tfar may go either way
    assert np.array_equal(near[sure], ((slow.prim >= 0) & (slow.t < 1.0))[sure])


def test_offset_origins_on_a_plane_see_exactly_the_upper_half_space() -> None:
    half = 1.0
    k = 21
    xs = np.linspace(-half, half, k)
    x, z = np.meshgrid(xs, xs, indexing="ij")
    pos = np.stack([x.ravel(), np.zeros(k * k), z.ravel()], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)])  # wound so the normal is +Y
    mesh = build(RawMesh(pos, faces))
    assert np.allclose(mesh.normals, [0, 1, 0])
    eps = ray_offset(mesh.positions)
    assert eps == OFFSET_FRACTION * np.sqrt(2.0) * half
    dirs = fibonacci_sphere(2048)
    inside = np.abs(mesh.positions[:, [0, 2]]).max(axis=1) < half - 1e-9
    interior = np.flatnonzero(inside)
    free = free_rays(RayCaster(mesh.positions, mesh.faces), mesh.positions[interior], mesh.normals[interior], dirs,
                     eps)
    # expected: a ray from (x, eps, z) going down meets y = 0 at (x, z) + eps (dx, dz) / -dy, occluded iff that
    # point lies on the square; rays going up are never occluded (no acne)
    p = mesh.positions[interior]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = eps / -dirs[None, :, 1]
        hx = p[:, None, 0] + s * dirs[None, :, 0]
        hz = p[:, None, 2] + s * dirs[None, :, 2]
    down = dirs[None, :, 1] < 0.0
    on = down & (np.abs(hx) <= half) & (np.abs(hz) <= half)
    near_edge = down & (np.abs(np.maximum(np.abs(hx), np.abs(hz)) - half) < 1e-4)  # float32 at the border
    assert np.all(free[:, dirs[:, 1] > 0.0])
    assert np.array_equal(free[~near_edge], ~on[~near_edge])
