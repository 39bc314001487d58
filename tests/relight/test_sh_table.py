"""Tests of the per-view SH tables (relight.sh_table, relight.view_maps) and table shading (relight.sh_render).

Independent references: a world-frame brute force over lat-long pixels of a band-limited environment (the model's
own ``fcos`` with world directions and frames: no table, no SH rotation, no parity rule), Gauss–Legendre x
trapezoid projection in the local frame (no lobe quadrature, no rotation), closed forms (Lambert: Ramamoorthi &
Hanrahan's A_l; cap lights: quadrature of the indicator), and the design notes' missing-energy figures.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from relight import sh
from relight.brdf.coefficients import lambert_transfer
from relight.brdf.frame import FrameBRDF
from relight.brdf.spec import parse_frame_brdf
from relight.conventions import latlong_dirs, pixel_solid_angles
from relight.envmap import read_envmap, resample_latlong
from relight.errors import InputError
from relight.sh_render import cap_light, environment_coefficients, evaluate_world, shade, window_lighting
from relight.sh_rotation import band_signs, local_rotations, rotate_coefficients
from relight.sh_table import (
    DEFAULT_LAYOUT,
    SHTable,
    build_table,
    expand_isotropic,
    product_energy,
    project_views,
    write_table,
)
from relight.shrm import real_harmonics
from relight.tangent_frames import projected_frames
from relight.view_maps import map_views

F64 = NDArray[np.float64]
DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
ORDER = 4
VIEW = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])


@cache
def band_limited_light() -> F64:
    """studio.exr to bands <= 4 plus an off-axis coloured cap light: a lighting that is not mirror-symmetric."""
    env = np.asarray(resample_latlong(read_envmap(DATA / "studio.exr").pixels, 64), dtype=np.float64)
    return environment_coefficients(env, ORDER) + cap_light([0.4, 0.3, 0.8], 0.3, [5.0, 3.0, 1.0], ORDER)


@cache
def brute_grid(rows: int = 256) -> tuple[F64, F64]:
    """Directions and ``L dOmega`` of the band-limited light on a lat-long grid (relight.sh.synthesize, ducc0)."""
    lam = sh.synthesize(sh.from_real(band_limited_light().T, ORDER), ORDER, rows)
    lam = np.moveaxis(lam, 0, -1) if lam.shape[0] == 3 else lam
    w = np.broadcast_to(pixel_solid_angles(rows, 2 * rows)[:, None], (rows, 2 * rows)).reshape(-1)
    return latlong_dirs(rows, 2 * rows).reshape(-1, 3), lam.reshape(-1, 3) * w[:, None]


def brute_force(brdf: FrameBRDF, frames: F64, view: F64) -> F64:
    dirs, lw = brute_grid()
    out = []
    for f in frames:
        val = brdf.fcos(dirs, view, np.broadcast_to(f, (dirs.shape[0], 3, 3)))
        out.append((val * lw).sum(axis=0))
    return np.array(out)


def sample_frames(k: int = 24) -> F64:
    rng = np.random.default_rng(0)
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[n @ VIEW < 0.15] *= -1.0
    n = n[n @ VIEW > 0.15]
    return projected_frames(n, [0.2, 0.9, 0.4])


EXACT_SPECS = ["ashikhmin-shirley:nu=12,nv=4,rs=0.05,rd=0.3",
               "torrance-sparrow:alpha_u=0.2,alpha_v=0.5,distribution=ggx",
               "torrance-sparrow:alpha_u=0.45,alpha_v=0.15,distribution=beckmann",
               "ward:alpha_x=0.2,alpha_y=0.4,rho_d=0.2,rho_s=0.5",
               "ggx:alpha=0.3", "lambert:albedo=0.8+phong:s=8"]


@pytest.mark.parametrize("spec", EXACT_SPECS)
def test_band_limited_light_is_exact(spec: str) -> None:
    # For lighting with bands <= F the table shading (eq. 1) is exact; what remains: the lobe quadrature (~1e-4)
    # and the brute force's pixel sums at 256 rows (a 0.7-degree grid): measured <= 6e-4 of the largest value;
    # with a table also the bilinear interpolation of the 64 x 64 map: measured <= 3.6e-3 (Beckmann 0.15).
    brdf = parse_frame_brdf(spec)
    frames = sample_frames()
    ref = brute_force(brdf, frames, VIEW)
    scale = np.abs(ref).max()
    light = band_limited_light()
    local_l = rotate_coefficients(local_rotations(frames, ORDER), light[None])
    vl = frames @ VIEW
    exact = np.einsum("nic,nic->nc", local_l, np.broadcast_to(project_views(brdf, vl, ORDER), local_l.shape))
    assert np.abs(exact - ref).max() < 1e-3 * scale
    table = build_table(brdf, order=ORDER, resolution=64)
    assert np.abs(shade(table, light, frames, VIEW, exact_azimuth=False) - ref).max() < 6e-3 * scale
    # the parity rule matters: dropping (-1)^l (treating the mirror SH frame as right-handed) mirrors the light
    # against the view, which this configuration (anisotropic or not) does not forgive (measured >= 0.76)
    wrong = np.einsum("nic,nic->nc", local_l * band_signs(ORDER)[:, None],
                      np.broadcast_to(project_views(brdf, vl, ORDER), local_l.shape))
    assert np.abs(wrong - ref).max() > 0.1 * scale


def test_lambert_table_is_view_independent_and_the_irradiance_path() -> None:
    table = build_table(parse_frame_brdf("lambert"), order=ORDER, resolution=16)
    l = np.repeat(np.arange(ORDER + 1), 2 * np.arange(ORDER + 1) + 1)
    m = np.arange(l.size) - l * l - l
    zonal = np.where(m == 0, lambert_transfer(ORDER)[l] * np.sqrt((2 * l + 1) / (4 * np.pi)), 0.0)
    # the product function max(s_z, 0) / pi has a kink on the horizon: the lobe quadrature reaches ~1e-6
    assert np.abs(table.coefficients[..., 0] - zonal).max() < 1e-5
    frames = sample_frames()
    light = band_limited_light()
    irradiance = evaluate_world(light * lambert_transfer(ORDER)[l][:, None], frames[:, 2])  # seed 000: A_l / pi
    assert np.abs(shade(table, light, frames, VIEW) - irradiance).max() < 1e-5 * np.abs(irradiance).max()


def local_projection(brdf: FrameBRDF, view: F64, order: int, n_t: int = 400, n_p: int = 400) -> tuple[F64, F64]:
    """Independent: Gauss–Legendre in cos(theta) on [0, 1] (f* vanishes below the horizon) x trapezoid in phi,
    directly in the local frame; returns the coefficients (n, C) and ``int f*^2``."""
    x, w = np.polynomial.legendre.leggauss(n_t)
    t = 0.5 * (x + 1.0)
    th = np.arccos(t)
    ph = (np.arange(n_p) + 0.5) * 2 * np.pi / n_p
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    s = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    wt = np.repeat(0.5 * w, n_p) * 2 * np.pi / n_p
    f = brdf.fcos_local(s, view[None])
    basis = real_harmonics(order, tt.ravel(), pp.ravel())
    return basis.T @ (f * wt[:, None]), (f**2 * wt[:, None]).sum(axis=0)


@pytest.mark.parametrize(("theta", "phi", "lo", "hi"), [(0.0, 0.0, 6.5, 7.6), (45.0, 0.0, 13.0, 19.0),
                                                        (45.0, 90.0, 13.0, 19.5)])
def test_ashikhmin_shirley_missing_energy(theta: float, phi: float, lo: float, hi: float) -> None:
    # Design notes §3.3: AS (48, 16), specular without Fresnel (R_s = 1), missing energy at n = 25: 7.1 % for the
    # normal view and 13-19 % at 45 degrees. Every order against the independent local-frame projection (400 x 400
    # nodes resolve the n = 48 lobe to ~1e-6 of its energy): agreement to 0.05 percentage points.
    brdf = parse_frame_brdf("ashikhmin-shirley:nu=48,nv=16,rs=1,rd=0")
    t, p = np.radians(theta), np.radians(phi)
    v = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
    ref_c, ref_total = local_projection(brdf, v, 14)
    for order in (2, 4, 6, 14):
        bands, total = product_energy(brdf, v, order)
        missing = 100.0 * (1.0 - bands.sum() / total[0])
        ref_missing = 100.0 * (1.0 - (ref_c[: (order + 1) ** 2] ** 2).sum() / ref_total[0])
        assert abs(missing - ref_missing) < 0.05, order
        if order == 4:
            assert lo <= missing <= hi


def test_energy_check_is_the_directional_albedo() -> None:
    brdf = parse_frame_brdf("ashikhmin-shirley:nu=24,nv=8,rs=0.9,rd=0.1")
    table = build_table(brdf, order=ORDER, resolution=16)
    albedo = table.albedo()
    assert np.all(albedo <= 1.0 + 1e-6) and np.all(albedo > 0.0)
    # texels at 10, 77, 85 and 89.3 degrees (the rim texels at 89.94 degrees are covered by the <= 1 bound above and
    # by the 2x finer rule in test_quadrature_against_a_twice_finer_rule)
    for idx in [(8, 8), (3, 12), (1, 4), (0, 5)]:
        v = table.views[idx]
        ref = local_projection(brdf, v, 0, 600, 600)[0][0, 0] * np.sqrt(4 * np.pi)  # = int f* ds
        # up to 87 degrees: both quadratures ~1e-5; grazing texels (the lobe cut by the horizon): measured 4.2e-4
        tol = 2e-4 if v[2] > 0.05 else 1e-3
        assert abs(albedo[idx][0] - ref) < tol, idx


def test_quadrature_against_a_twice_finer_rule() -> None:
    # bench/shtable.py measures the same at 128 x 128; here 16 x 16: views up to 85 degrees agree to ~5e-4 of the
    # largest coefficient (measured 3.3e-4 for AS (48, 16), 5.1e-4 for GGX (0.1, 0.4)): 8e-4; the last degrees
    # before the rim, where the horizon's kink cuts through the lobe, to 3e-3.
    for spec in ("ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0", "torrance-sparrow:alpha_u=0.1,alpha_v=0.4"):
        brdf = parse_frame_brdf(spec)
        a = build_table(brdf, resolution=16)
        b = build_table(brdf, resolution=16, refine=2)
        scale = np.abs(b.coefficients).max()
        diff = np.abs(a.coefficients - b.coefficients).max(axis=(2, 3)) / scale
        inner = a.views[..., 2] > np.cos(np.radians(85.0))
        assert diff[inner].max() < 8e-4, spec
        assert diff.max() < 3e-3, spec


def test_isotropic_tables_rotate_exactly_about_z() -> None:
    brdf = parse_frame_brdf("torrance-sparrow:alpha=0.25,distribution=ggx,fresnel=schlick,f0=0.9/0.6/0.3")
    table = build_table(brdf, resolution=16)
    assert table.thetas is not None and table.theta_coefficients is not None
    th = table.thetas[[0, 3, 9]]
    ph = np.array([0.4, -2.0, 2.9])
    v = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    direct = project_views(brdf, v, ORDER)
    expanded = expand_isotropic(table.thetas, table.theta_coefficients, v)
    assert np.abs(direct - expanded).max() < 1e-12 + 1e-9 * np.abs(direct).max()


@pytest.mark.parametrize("spec", ["ashikhmin-shirley:nu=12,nv=4", "torrance-sparrow:alpha_u=0.2,alpha_v=0.5"])
def test_default_layout_has_the_smaller_error_per_byte(spec: str) -> None:
    # Same R x R bytes; the interpolation error against direct projection at random views decides. Measured at
    # R = 32: parabolic RMS 0.6-0.9x the hemi-octahedral one (it has 2x the linear resolution at the rim).
    brdf = parse_frame_brdf(spec)
    rng = np.random.default_rng(2)
    v = rng.normal(size=(300, 3))
    v[:, 2] = np.abs(v[:, 2])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    ref = project_views(brdf, v, ORDER)
    err = {lay: float(np.sqrt(np.mean((build_table(brdf, resolution=32, layout=lay).lookup(v) - ref) ** 2)))
           for lay in ("parabolic", "hemi-octahedral")}
    assert err[DEFAULT_LAYOUT] == min(err.values()), err


def test_view_maps_round_trip_and_rim() -> None:
    from relight.view_maps import view_to_texel

    for lay in ("parabolic", "hemi-octahedral"):
        views, valid = map_views(lay, 8)
        assert np.allclose(np.linalg.norm(views, axis=-1), 1.0) and np.all(views[..., 2] > 0.0)
        x, y = view_to_texel(lay, 8, views[valid])
        jj, ii = np.meshgrid(np.arange(8), np.arange(8))
        assert np.allclose(x, jj[valid], atol=1e-9) and np.allclose(y, ii[valid], atol=1e-9)
    views, valid = map_views("parabolic", 8)
    assert valid.sum() < 64 and np.allclose(views[~valid][:, 2], 1e-3)  # rim texels: the rim direction
    with pytest.raises(InputError, match="layout"):
        map_views("cube", 8)


def test_cap_light_closed_form() -> None:
    d = np.array([0.3, -0.5, 0.8])
    om = 0.7
    c = cap_light(d, om, [2.0, 1.0, 0.5], 6)
    rows = 512
    dirs = latlong_dirs(rows, 2 * rows).reshape(-1, 3)
    w = np.broadcast_to(pixel_solid_angles(rows, 2 * rows)[:, None], (rows, 2 * rows)).reshape(-1)
    inside = (dirs @ (d / np.linalg.norm(d)) >= 1.0 - om / (2 * np.pi)).astype(float)
    from relight.sh_render import sh_frame_dirs

    s = sh_frame_dirs(dirs)
    basis = real_harmonics(6, np.arctan2(np.hypot(s[:, 0], s[:, 1]), s[:, 2]), np.arctan2(s[:, 1], s[:, 0]))
    ref = basis.T @ (inside * w)
    assert np.abs(c[:, 0] / 2.0 - ref).max() < 2e-3  # pixel-edge aliasing of the cap's boundary at 512 rows


def test_windowing_states_its_cost_and_float16_clamping(tmp_path: object) -> None:
    light = band_limited_light()
    hann, cost = window_lighting(light, "hann")
    assert 0.0 < cost < 1.0 and np.allclose(hann[0], light[0])
    assert window_lighting(light, "none")[1] == 0.0
    table = build_table(parse_frame_brdf("lambert"), order=2, resolution=4)
    big = SHTable(coefficients=table.coefficients * 1e6, views=table.views, valid=table.valid, order=2,
                  layout=table.layout, brdf=table.brdf)
    man = write_table(Path(str(tmp_path)) / "t.exr", big)
    assert man["float16_clamped"] == int(np.sum(np.abs(big.coefficients) > 65504.0))
    assert man["float16_clamped"] > 0


@pytest.mark.parametrize(("spec", "tol"), [("ggx:alpha=0.3", 1.5e-2), ("phong:s=8", 1e-2)])
def test_isotropic_tables_agree_with_seed_000_shrm(spec: str, tol: float) -> None:
    # Seed 000's SHRM at F = 4 under the same band-limited light (synthesised at 64 rows, where the SHRM's Fejér
    # projection recovers the F = 4 coefficients exactly) against the F = 4 table render, for normals within 53
    # degrees of the view. The SHRM truncates the view dependence at P (here 16) and interpolates its 64-row maps:
    # measured 0.67 % (GGX 0.3) and 0.35 % (Phong 8) of the largest value; the table is within 1e-3 of the brute
    # force (test_band_limited_light_is_exact), so the difference is the SHRM's.
    from relight.brdf.spec import parse_brdf
    from relight.shrm import create_shrm
    from relight.shrm import shade as shrm_shade

    light = band_limited_light()
    env = sh.synthesize(sh.from_real(light.T, ORDER), ORDER, 64)
    frames = sample_frames()
    frames = frames[frames[:, 2] @ VIEW > 0.6]
    shrm = create_shrm(env, parse_brdf(spec), order=ORDER, p_order=16, size=64)
    ref = shrm_shade(shrm, frames[:, 2], VIEW, clamp=False)  # the band-limited light goes negative: no clamp
    got = shade(build_table(parse_frame_brdf(spec), resolution=64), light, frames, VIEW)
    assert np.abs(got - ref).max() < tol * np.abs(ref).max()


def test_rotating_the_lighting_moves_a_cap_light() -> None:
    # L'(w) = L(R^-1 w): a cap about d turned by the world rotation R is the cap about R d (closed form both ways)
    from scipy.spatial.transform import Rotation

    from relight.sh_render import rotate_lighting

    r = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    d = np.array([0.2, 0.9, -0.4])
    turned = rotate_lighting(cap_light(d, 0.5, [1.0, 2.0, 3.0], 6), r)
    assert np.abs(turned - cap_light(r @ d, 0.5, [1.0, 2.0, 3.0], 6)).max() < 1e-12
