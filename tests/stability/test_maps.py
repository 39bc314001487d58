"""Hard environment maps: a sun 1e5 times the mean, single-pixel lights, all-zero maps, negative texels, and values
beyond the float16 range in every half-float writer.

References: the closed form of a single pixel's reflection (Legendre series of the Phong lobe from
``phong_transfer`` and scipy's ``eval_legendre``, with Fejér's first-rule weight written out here from its
formula), the angular reference, linearity, and IEEE binary16 (largest finite value 65504).
"""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.special import eval_legendre

from relight.brdf.coefficients import phong_transfer
from relight.brdf.models import Microfacet
from relight.brdf.radial import Lambert, Phong
from relight.conventions import latlong_dirs
from relight.envmap import HALF_MAX, read_envmap, resample_latlong, to_half_safe, write_exr
from relight.errors import InputError
from relight.metrics import relative_rms
from relight.prefilter import prefilter_radial
from relight.reference import reference_radial

from ._hyp import log_uniform, stable

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"


@cache
def env(name: str = "courtyard", rows: int = 32) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / f"{name}.exr").pixels, rows), dtype=np.float64)


def fejer_pixel_weight(height: int, row: int) -> float:
    """Fejér's first rule on ``theta_k = (2k + 1) pi / (2n)``: ``w_k = 2/n [1 - 2 sum_{j<=n/2} cos(2 j theta_k) /
    (4 j^2 - 1)]`` (integrating over cos theta on [-1, 1]), times 2 pi / W for one pixel of the ring."""
    n = height
    t = (2 * row + 1) * math.pi / (2 * n)
    w = 2.0 / n * (1.0 - 2.0 * sum(math.cos(2 * j * t) / (4 * j * j - 1) for j in range(1, n // 2 + 1)))
    return w * 2.0 * math.pi / (2 * height)


def strict_json(obj: Any) -> None:
    json.dumps(obj, allow_nan=False)  # raises ValueError on NaN / Inf anywhere


# ------------------------------------------------------------------------------------------------ sun and delta
@stable(8)
@given(row=st.one_of(st.sampled_from([0, 31, 15]), st.integers(0, 31)), col=st.integers(0, 63),
       s=log_uniform(1.0, 1000.0), order=st.integers(2, 31))
def test_single_pixel_light_against_the_closed_form(row: int, col: int, s: float, order: int) -> None:
    """One lit pixel k: the order-F prefilter is ``L q_k sum_l (2l + 1)/(4 pi) Lambda_l rho_l P_l(C . w_k)``
    (addition theorem), q_k the pixel's quadrature weight; 1e-10 of the peak (rounding)."""
    h = 32
    px = np.zeros((h, 2 * h, 3))
    px[row, col] = [3.0, 2.0, 1.0]
    res = prefilter_radial(px, Phong(s), order=order, size=16)
    w = latlong_dirs(h, 2 * h)[row, col]
    t = latlong_dirs(16, 32) @ w
    transfer = phong_transfer(s, order)
    kernel = sum((2 * l + 1) / (4 * math.pi) * transfer[l] * eval_legendre(l, t) for l in range(order + 1))
    ref = fejer_pixel_weight(h, row) * kernel[..., None] * px[row, col]
    np.testing.assert_allclose(res.map, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    # the report's ringing bound is attained within the output's sampling of the kernel: a delta light rings
    lower = np.array(res.report.ringing.lower_bound_rgb)
    assert np.all(res.map.reshape(-1, 3).min(axis=0) >= lower - 1e-12 * np.abs(ref).max())


@stable(6)
@given(row=st.one_of(st.sampled_from([0, 31]), st.integers(0, 31)), col=st.integers(0, 63),
       s=st.sampled_from([16.0, 64.0, 512.0]))
def test_sun_1e5_times_the_mean(row: int, col: int, s: float) -> None:
    """A sun of 1e5 x the map's mean: finite, every texel above the ringing bound, and the measured error within
    App. B's bound plus the pixel grid's floor (the F = H - 1 comparison), as for ordinary maps."""
    px = env().copy()
    px[row, col] = 1e5 * px.mean()
    res = prefilter_radial(px, Phong(s), epsilon=1e-3, size=16)
    assert np.all(np.isfinite(res.map))
    strict_json(res.report.to_json())
    lower = np.array(res.report.ringing.lower_bound_rgb)
    assert np.all(res.map.reshape(-1, 3).min(axis=0) >= lower - 1e-9 * np.abs(res.map).max())
    ref = reference_radial(px, Phong(s), 16, epsilon=0.0)
    floor = relative_rms(prefilter_radial(px, Phong(s), order=31, size=16).map, ref)
    assert relative_rms(res.map, ref) <= res.report.orders.rms_appendix_b + floor


def test_sun_in_an_shrm_stays_finite() -> None:
    from relight.shrm import create_shrm, reflect

    px = env("city", 32).copy()
    px[5, 40] = 1e5 * px.mean()
    sm = create_shrm(px, Microfacet(0.1), epsilon=0.01, size=16)
    assert np.all(np.isfinite(sm.components[0].maps))
    assert np.all(np.isfinite(reflect(sm, [0.3, 0.2, 0.9])))
    strict_json(sm.report.to_json())  # type: ignore[attr-defined]  # create_shrm: a relight.reports.ShrmReport


# ------------------------------------------------------------------------------------------------ zeros, negatives
def test_all_zero_maps_give_zero_and_finite_reports(tmp_path: Path) -> None:
    from relight import costmodel, planning, tradeoff
    from relight.shrm import create_shrm, reflect

    px = np.zeros((16, 32, 3))
    for lobe in (Phong(32.0), Lambert()):
        for kw in ({"epsilon": 1e-3}, {"order": 10}):
            res = prefilter_radial(px, lobe, size=8, **kw)  # type: ignore[arg-type]
            assert not res.map.any()
            strict_json(res.report.to_json())
    sm = create_shrm(px, Microfacet(0.3), epsilon=0.05, size=8)
    assert not sm.components[0].maps.any() and not reflect(sm, [0, 0, 1]).any()
    strict_json(sm.report.to_json())  # type: ignore[attr-defined]  # create_shrm: a relight.reports.ShrmReport
    assert not reference_radial(px, Phong(8.0), 8).any()
    with pytest.raises(InputError, match="zero everywhere"):
        tradeoff.sweep(px, Phong(8.0), epsilons=(0.1,), truncations=(0.1,), calibration=costmodel.default_calibration())
    material = "lambert+microfacet:sigma=0.3"
    scene = planning.scene_from_dict({"environment": "zero", "epsilon": 0.01, "size": 8,
                                     "objects": [{"size": 1, "distance": 5, "material": material}]})
    plan = planning.plan_scene(scene, px, calibration=costmodel.default_calibration())
    planning.plan_json(plan)  # strict JSON
    result = planning.run_plan(plan, tmp_path).result
    strict_json(result.to_json())
    assert not read_envmap(tmp_path / "object0.view.exr").pixels.any()


def test_negative_texels_are_clamped_on_reading_and_linear_in_the_core() -> None:
    """Real maps carry small negative texels from lossy compression (docs/facts.md): reading clamps and counts them.
    Arrays handed to the core directly keep them: the prefilter is linear, so f(a - b) = f(a) - f(b)."""
    e = read_envmap(DATA / "forest.exr")
    assert e.negatives_clamped > 0 and e.min_negative < 0 and float(e.pixels.min()) == 0.0
    a = env("forest", 16)
    b = env("studio", 16)
    fa = prefilter_radial(a, Phong(16.0), order=12, size=8).map
    fb = prefilter_radial(b, Phong(16.0), order=12, size=8).map
    fd = prefilter_radial(a - b, Phong(16.0), order=12, size=8)
    assert (a - b).min() < 0 and np.all(np.isfinite(fd.map))
    np.testing.assert_allclose(fd.map, fa - fb, rtol=0, atol=1e-12 * np.abs(fa).max())


# ------------------------------------------------------------------------------------------------ float16
HALF_EDGE = [0.0, 1.0, 65504.0, 65504.5, 65519.0, 65520.0, 1e5, 3.0e38, 6.1e-5, 6e-8, 1e-9]
F32_MAX = float(np.finfo(np.float32).max)


@stable(40)
@given(values=st.lists(st.one_of(st.sampled_from(HALF_EDGE + [-v for v in HALF_EDGE]),
                                 st.floats(-F32_MAX, F32_MAX, width=32)), min_size=1, max_size=64))
def test_to_half_safe_never_overflows(values: list[float]) -> None:
    """Within the range the value rounds as IEEE binary16 does; beyond 65504 (65520 and up would round to inf) it
    is clamped to +-65504 and counted."""
    a = np.array(values, dtype=np.float32)
    half, n = to_half_safe(a)
    assert half.dtype == np.float16 and np.all(np.isfinite(half))
    over = np.abs(a) > HALF_MAX
    assert n == int(over.sum())
    np.testing.assert_array_equal(half[over], np.sign(a[over]) * np.float16(HALF_MAX))
    np.testing.assert_array_equal(half[~over], a[~over].astype(np.float16))


def _bright_shrm() -> Any:
    from relight.shrm import create_shrm

    px = np.asarray(np.random.default_rng(7).random((16, 32, 3)), dtype=np.float64)
    px[4, 9] = 3e7  # reflected radiance far above 65504
    return create_shrm(px, Microfacet(0.4), order=6, p_order=2, size=8)


def test_half_float_files_clamp_instead_of_overflowing(tmp_path: Path) -> None:
    """Every writer of half-float data: SHRM EXR (half), the service's float16 texture, the viewer's background."""
    from relight.gl.views import envmap_texture
    from relight.shrm_io import read_shrm, write_shrm
    from relight.worker.results import Layer, half_layers

    sm = _bright_shrm()
    assert np.abs(sm.components[0].maps).max() > HALF_MAX
    write_shrm(tmp_path / "s.exr", sm, half=True)
    back = read_shrm(tmp_path / "s.exr").components[0].maps
    assert np.all(np.isfinite(back)) and np.abs(back).max() == HALF_MAX

    layers = [Layer(name=f"l{k}", p=0, q=0, pixels=m) for k, m in enumerate(sm.components[0].maps)]
    data, clamped = half_layers(layers)
    h = np.frombuffer(data, dtype="<f2")
    assert clamped > 0 and np.all(np.isfinite(h)) and np.abs(h).max() == HALF_MAX

    sky = np.full((16, 32, 3), 0.5, dtype=np.float32)
    sky[3, 3] = 1e6
    write_exr(tmp_path / "sky.exr", sky)
    tex, rows, cols = envmap_texture(str(tmp_path / "sky.exr"), 16)
    t = np.frombuffer(tex, dtype="<f2")
    assert (rows, cols) == (16, 32) and np.all(np.isfinite(t)) and t.max() == HALF_MAX


class _RecordingContext:
    """A moderngl context that records the bytes of every texture array uploaded (delegates everything else)."""

    def __init__(self, ctx: Any) -> None:
        self._ctx = ctx
        self.uploads: list[tuple[bytes, str]] = []

    def texture_array(self, size: Any, components: int, data: bytes | None = None, **kw: Any) -> Any:
        if data is not None:
            self.uploads.append((bytes(data), str(kw.get("dtype", "f1"))))
        return self._ctx.texture_array(size, components, data, **kw)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ctx, name)


def test_gl_renderer_half_textures_clamp_instead_of_overflowing() -> None:
    """``relight.gl.render.Renderer`` uploads the coefficient layers as float16 (dtype "f2"): values above 65504
    must be clamped like every other half-float writer (``relight.envmap.to_half_safe``), not turned into inf."""
    import relight.gl.layout as gl_layout
    import relight.gl.render as gl_render

    ctx = gl_render.create_context()
    sm = _bright_shrm()
    manifest, stack = gl_layout.layers_from_shrm(sm)
    rec = _RecordingContext(ctx)
    try:
        gl_render.Renderer(gl_layout.from_manifest(manifest), stack, ctx=rec)
        halves = [np.frombuffer(data, dtype="<f2") for data, dtype in rec.uploads if dtype == "f2"]
        assert halves, "no float16 texture was uploaded"
        for h in halves:
            assert np.all(np.isfinite(h)), f"{int((~np.isfinite(h)).sum())} texels overflowed to inf"
    finally:
        ctx.release()
