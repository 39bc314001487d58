"""The accuracy–time sweep against Mitsuba 3 (``relight.tradeoff``'s ``mitsuba_error``, ``relight.mitsuba_twin``).

What is checked, and against what:

* :func:`relight.mitsuba_twin.twin` maps exactly the models whose BSDF equals Mitsuba's, and the equality itself:
  relight's ``f_r cos(theta_light)`` against Mitsuba's ``BSDF.eval`` in random directions, to 1e-4 relative (Mitsuba
  evaluates in float32: about 1e-6 relative; the tolerance leaves room for its ``tan^2`` and ``sqrt`` near the
  horizon, and a wrong D, G1 or normalisation is off by percents or more).
* The sweep's sphere image of a map (:func:`relight.mitsuba_compare.sphere_from_map`) is
  ``relight.shrm.render_sphere``'s image (to rounding), and the camera written out here from the documented
  convention (image right ``normalize(+Y x V)``, image up ``V x right``) reads an analytic, asymmetric map where
  it should.
* A small sweep (studio map area-averaged to 32 rows, ``TorranceSparrow(0.2, "beckmann", fresnel="none")``, output
  S = 32 = the input rows, a 32 x 32 Mitsuba image at 4096 spp): the angular reference's image agrees with
  Mitsuba's to the noise floor plus stated systematic terms, so each point's ``mitsuba_error`` measures relight's
  error and not the comparison's, and agrees with the same error measured against the angular reference on the same
  blocks (``image_error``); rendering Mitsuba with V mirrored, or its image flipped left to right, makes the
  reference's error many times the floor (the check can fail).
* Materials without a twin, maps Mitsuba cannot be shown exactly, and ``mitsuba=False`` record why nothing was
  computed; ``mitsuba=True`` raises instead. The CLI's ``--mitsuba``.

Tests never assert wall-clock times. Measured numbers are printed (``pytest -s``).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from relight import costmodel, tradeoff
from relight.brdf.models import GGX, KajiyaKay, Microfacet, TorranceSparrow
from relight.brdf.radial import Lambert, Lobe1D, Phong
from relight.envmap import read_envmap, resample_latlong, write_exr
from relight.errors import InputError
from relight.mitsuba_compare import SphereComparison, TwinSettings, block_mean, compare_sphere, sphere_from_map
from relight.mitsuba_twin import VARIANTS, bsdf_eval, twin, unavailable_reason
from relight.reference_view import reference_view
from relight.shrm import create_shrm, reflect, render_sphere
from relight.tradeoff.report import Grid

DATA = Path(__file__).resolve().parents[2] / "data" / "envmaps"
CAL = costmodel.default_calibration()
VIEW = np.array(tradeoff.DEFAULT_VIEW)
ROWS = 32
ALPHA = 0.2
#: The sweep's small Mitsuba image: 8 x 8 blocks of 4 x 4 pixels, 24 of them within radius 0.8.
SETTINGS = TwinSettings(size=32, block=4, spp=4096)
#: Systematic part of the reference's error against Mitsuba on this case (besides the noise): the reference's
#: pixel-centre sum over the 32-row map against Mitsuba's exact integral of the pixels' areas, the bilinear lookup
#: of the S = 32 output grid and the 4 x 4 supersampling of the pixel area. Measured with 32768 spp (noise
#: 1.8e-3): 1.7e-3 to 2.4e-3 (2, 4 and 8 samples per pixel edge); allowed: twice the largest.
SYSTEMATIC = 5e-3

def test_mitsuba_is_available() -> None:
    """Mitsuba 3 is a dev dependency (``make test`` installs it and libllvm19): its absence is a failure."""
    assert unavailable_reason() is None, unavailable_reason()


@cache
def studio(rows: int) -> np.ndarray:
    return np.asarray(resample_latlong(read_envmap(DATA / "studio.exr").pixels, rows), dtype=np.float64)


def beckmann() -> TorranceSparrow:
    return TorranceSparrow(ALPHA, "beckmann", fresnel="none")


# ---------------------------------------------------------------------------------------------------- twins
def test_twin_mapping() -> None:
    """Exactly the models with an equal Mitsuba 3 BSDF have a twin; the dictionaries are plain JSON."""
    assert twin(TorranceSparrow(0.3)) == {"type": "roughconductor", "distribution": "beckmann", "alpha": 0.3,
                                          "material": "none"}
    assert twin(TorranceSparrow(0.3, "ggx")) == {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3,
                                                 "material": "none"}
    assert twin(GGX(0.1)) == twin(TorranceSparrow(0.1, "ggx"))
    assert twin(Lambert(0.5)) == {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
    assert twin(Lambert([0.2, 0.4, 0.6])) == {"type": "diffuse", "reflectance": {"type": "rgb",
                                                                                 "value": [0.2, 0.4, 0.6]}}
    for none in (Phong(16.0), TorranceSparrow(0.3, fresnel="schlick", f0=0.04),
                 TorranceSparrow(0.3, fresnel="conductor", eta=0.2, k=3.0), Microfacet(0.2), KajiyaKay(8.0),
                 Lobe1D([[0.0, 0.0], [1.0, 0.3]], center="N")):
        assert twin(none) is None, none
    json.dumps([twin(GGX(0.1)), twin(Lambert([0.2, 0.4, 0.6]))])


def _directions(rng: np.random.Generator, n: int, spread: float) -> tuple[np.ndarray, np.ndarray]:
    """Views and lights above the local surface (normal +Z); lights around the mirror direction (``spread`` times
    a normal deviate) for glossy lobes, or anywhere for ``spread = inf``."""
    view = rng.normal(size=(n, 3))
    view[:, 2] = np.abs(view[:, 2]) + 0.05
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    if np.isinf(spread):
        light = rng.normal(size=(n, 3))
        light[:, 2] = np.abs(light[:, 2])
    else:
        light = 2.0 * view[:, 2:3] * np.array([0.0, 0.0, 1.0]) - view + spread * rng.normal(size=(n, 3))
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    keep = light[:, 2] > 0.02
    return view[keep], light[keep]


@pytest.mark.parametrize("model", [TorranceSparrow(0.2), TorranceSparrow(0.05, "ggx"), GGX(0.3), GGX(0.7),
                                   Lambert(0.7), Lambert([0.2, 0.5, 0.9])], ids=lambda m: str(m.spec()))
def test_twin_bsdf_equals_mitsuba_eval(model: Any) -> None:
    """Mitsuba's ``BSDF.eval`` (``f_r cos(theta_light)``) = relight's, RGB, in 5000 random direction pairs: for the
    microfacet models ``f(light, view, n) * cos(theta_light)``, for Lambert its lobe ``u(cos theta_light)``, which is
    ``albedo / pi * cos`` (``relight.brdf.radial``), i.e. ``f_r = albedo / pi`` as Mitsuba's ``diffuse``. Values
    below 1e-3 of the largest are left out (their relative error is float32 rounding of near-zero numbers)."""
    rng = np.random.default_rng(7)
    bsdf = twin(model)
    assert bsdf is not None
    glossy = isinstance(model, TorranceSparrow)
    view, light = _directions(rng, 5000, 1.5 * model.alpha if glossy else np.inf)
    normal = np.array([0.0, 0.0, 1.0])
    if glossy:
        want = model.f(light, view, normal) * light[:, 2:3]
    else:
        want = model.u(light[:, 2])
    want = np.broadcast_to(want, (len(view), 3))
    got = bsdf_eval(bsdf, view, light)
    big = want > 1e-3 * want.max()
    assert big.sum() > 3000
    np.testing.assert_allclose(got[big], want[big], rtol=1e-4)


# ------------------------------------------------------------------------------------------- sphere image
def test_sphere_image_is_render_sphere() -> None:
    """For an SHRM seen along a general V, the sweep's image of its eq. 12 map (``reflect``, indexed by R) is
    ``render_sphere``'s image to rounding, and with 4 x 4 supersampling the mean of ``render_sphere`` at 4x the
    resolution; a Lambert SHRM (an N-centred component) likewise, from the same map indexed by N. (Raw radiance:
    both paths clamp negative radiance at 0, one before and one after the lookup's interpolation.)"""
    px = studio(16)
    shrm = create_shrm(px, beckmann(), order=12, p_order=4, size=16)
    n = 24
    raw = reflect(shrm, VIEW, clamp=False)
    np.testing.assert_allclose(sphere_from_map(raw, VIEW, n), render_sphere(shrm, VIEW, n, clamp=False),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sphere_from_map(raw, VIEW, n, supersample=4),
                               block_mean(render_sphere(shrm, VIEW, 4 * n, clamp=False), 4), rtol=1e-12, atol=1e-12)
    lam = create_shrm(px, Lambert(0.6), order=4, size=16)
    (comp,) = lam.components
    assert comp.center == "N"
    np.testing.assert_allclose(sphere_from_map(comp.view_map(VIEW), VIEW, n, center="N"), render_sphere(lam, VIEW, n),
                               rtol=1e-12, atol=1e-12)


def _field(d: np.ndarray) -> np.ndarray:
    """A smooth function of direction with no mirror symmetry (grey, (..., 3))."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    f = 1.0 + 0.5 * x + 0.3 * y + 0.2 * z + 0.25 * x * z - 0.15 * x * y
    return np.repeat(f[..., None], 3, axis=-1)


@pytest.mark.parametrize("center", ["R", "N"])
def test_sphere_image_camera_convention(center: str) -> None:
    """Pixel (i, j) of the image shows the normal ``x right + y up + sqrt(1 - x^2 - y^2) V`` with
    ``x = 2 (j + 1/2) / n - 1``, ``y = 1 - 2 (i + 1/2) / n``, right = ``normalize(+Y x V)``, up = ``V x right``
    (written out here, not taken from relight), and reads the map at R = 2 (N.V) N - V (or N). The map is an analytic
    field sampled on a 64-row grid; bilinear interpolation of it is within 2e-3 (second differences of the field
    over a 0.05 rad pixel); a mirrored axis or a swapped centre is off by up to 1."""
    from relight.conventions import latlong_dirs

    n = 20
    latlong = _field(latlong_dirs(64, 128))
    right = np.cross([0.0, 1.0, 0.0], VIEW)
    right /= np.linalg.norm(right)
    up = np.cross(VIEW, right)
    c = (np.arange(n) + 0.5) * 2.0 / n - 1.0
    x, y = np.meshgrid(c, -c)
    on = x * x + y * y < 1.0
    normal = x[..., None] * right + y[..., None] * up + np.sqrt(np.clip(1 - x * x - y * y, 0, None))[..., None] * VIEW
    refl = 2.0 * (normal @ VIEW)[..., None] * normal - VIEW
    want = np.where(on[..., None], _field(refl if center == "R" else normal), 0.0)
    got = sphere_from_map(latlong, VIEW, n, center=center)
    assert np.max(np.abs(got - want)) < 2e-3
    wrong = np.where(on[..., None], _field(normal if center == "R" else refl), 0.0)
    assert np.max(np.abs(got - wrong)) > 0.3


# ------------------------------------------------------------------------------------------------- the sweep
@cache
def small_sweep() -> tradeoff.Tradeoff:
    return tradeoff.sweep(studio(ROWS), beckmann(), epsilons=(0.5, 0.1), truncations=(0.01,), size=ROWS,
                          calibration=CAL, mitsuba_settings=SETTINGS)


def test_sweep_records_mitsuba_errors() -> None:
    """The reference's image agrees with Mitsuba's to ``3 noise + SYSTEMATIC``. A single render scatters widely about
    the floor, because the few brightest blocks (the studio's lights in the highlight) dominate both sums and their
    Monte Carlo estimates are heavy-tailed: over 12 seeds (with and without the crop window) ``reference_error`` was
    0.5 to 2.2 times the floor (0.0112 = 2.2 floors for the seed used here), so 3 floors. S equals the input rows:
    at the default S = rows / 2 the output grid's bilinear lookup adds 2.6 % here (module docstring of
    ``relight.tradeoff``).

    Per point: ``mitsuba_error`` and ``image_error`` measure the same thing, the point's error on the compared
    blocks, against two independent truths (Mitsuba's Monte Carlo integral of the pixelised map; relight's own
    brute-force sum). By the triangle inequality they differ by at most about ``reference_error``: checked on
    every point within ``3 noise + SYSTEMATIC``, which also checks that each point is compared with its own map.
    Mitsuba resolves the frequency method's coarse error (eps = 0.5 and 0.1, (F_B, P_B) = (11, 4) and (25, 15) on
    this 32-row map with the view-band order search: ``image_error`` 2.5 % and 0.15 %, i.e. 4.9 and 0.3 floors): the
    two frequency points must come out in that order and the coarse one above 3 floors (the truncation error and the
    noise are nearly orthogonal vectors over the blocks, so ``mitsuba_error`` is about
    ``sqrt(image_error^2 + reference_error^2)``, never much below ``image_error``). The sphere-wide
    ``measured_error`` is not comparable with either: it includes grazing views (excluded here, radius 0.8), where
    the SHRM's error is largest (0.20 and 0.05 here)."""
    res = small_sweep()
    m = res.meta.mitsuba
    print("\nmitsuba meta:", {k: v for k, v in m.to_json().items() if k not in ("metric", "bsdf")})
    for p in res.points:
        print(f"{p.method} {p.setting}: measured {p.measured_error:.4g}, image {p.image_error:.4g}, "
              f"mitsuba {p.mitsuba_error:.4g}, predicted {p.predicted_error:.3g}")
    assert m.computed is True and m.variant in VARIANTS
    assert m.bsdf == twin(beckmann()) and m.spp == SETTINGS.spp and m.blocks == 24
    assert m.image == Grid(height=32, width=32) and m.block == 4 and m.radius == 0.8
    assert m.map_center == "R" and m.view is not None and np.allclose(m.view, VIEW / np.linalg.norm(VIEW))
    assert m.seconds is not None and m.seconds > 0
    noise, ref_err = m.noise, m.reference_error
    assert noise is not None and ref_err is not None
    assert 0 < noise < 0.01
    assert ref_err <= 3 * noise + SYSTEMATIC, m
    json.dumps(res.as_dict(), allow_nan=False)
    for p in res.points:
        assert np.isfinite(p.mitsuba_error) and np.isfinite(p.image_error), p
        assert abs(p.mitsuba_error - p.image_error) <= 3 * noise + SYSTEMATIC, p
    coarse, fine = (p for p in res.points if p.method == "frequency")
    assert coarse.setting["epsilon"] == 0.5 and fine.setting["epsilon"] == 0.1
    assert coarse.mitsuba_error > max(fine.mitsuba_error, 3 * noise)


def test_mirrored_view_fails() -> None:
    """The comparison can fail: Mitsuba rendering the sphere seen along V mirrored through the horizontal plane
    (looking at the other side of the room), or its image flipped left to right (a handedness error of the camera:
    with V in the yz plane, the world mirrored in x), puts the reference many floors away (measured: more than 30
    times the floor for both; required: 10 times plus SYSTEMATIC)."""
    px = studio(ROWS)
    v = VIEW / np.linalg.norm(VIEW)
    ref = reference_view(px, beckmann(), v, ROWS, truncation=0.0)
    bsdf = twin(beckmann())
    assert bsdf is not None
    mirrored = compare_sphere(px, bsdf, v * np.array([1.0, 1.0, -1.0]), SETTINGS)
    as_if = SphereComparison(SETTINGS, bsdf, v, mirrored.texels, mirrored.truth, mirrored.sigma, mirrored.render)
    right = compare_sphere(px, bsdf, v, SETTINGS)
    flipped_lum = right.render.luminance[:, ::-1]
    flipped = SphereComparison(SETTINGS, bsdf, v, right.texels, block_mean(flipped_lum, 4)[SETTINGS.mask()],
                               right.sigma, right.render)
    ok, bad_v, bad_x = right.error(ref), as_if.error(ref), flipped.error(ref)
    print(f"\nreference vs Mitsuba: right {ok:.4g}, V mirrored {bad_v:.4g}, image flipped {bad_x:.4g}; "
          f"floor {right.noise:.3g}")
    assert ok <= 3 * right.noise + SYSTEMATIC
    assert bad_v > 10 * right.noise + SYSTEMATIC
    assert bad_x > 10 * right.noise + SYSTEMATIC


# ------------------------------------------------------------------------------------------- not computed
def _tiny_sweep(brdf: Any, px: np.ndarray | None = None, **kwargs: Any) -> tradeoff.Tradeoff:
    return tradeoff.sweep(studio(16) if px is None else px, brdf, epsilons=(0.3,), truncations=(0.1,), size=8,
                          calibration=CAL, mitsuba_settings=TwinSettings(size=16, block=4, spp=16), **kwargs)


def test_no_twin_records_why() -> None:
    """Phong has no Mitsuba 3 plugin: nothing rendered, the reason recorded, every point's errors None."""
    res = _tiny_sweep(Phong(16.0))
    why = res.meta.mitsuba.reason
    assert res.meta.mitsuba.to_json() == {"computed": False, "reason": why}
    assert why is not None and "phong" in why and "twin" in why
    assert all(p.mitsuba_error is None and p.image_error is None for p in res.points)
    with pytest.raises(InputError, match="no Mitsuba 3 twin"):
        _tiny_sweep(Phong(16.0), mitsuba=True)


def test_switched_off() -> None:
    res = _tiny_sweep(beckmann(), mitsuba=False)
    assert res.meta.mitsuba.computed is False and "switched off" in str(res.meta.mitsuba.reason)
    assert all(p.mitsuba_error is None for p in res.points)


def test_map_mitsuba_cannot_show_exactly() -> None:
    """A map with an odd number of rows (W not divisible by 4: relight's +X would fall inside a Mitsuba texel) is
    skipped with the reason in auto mode and refused with ``mitsuba=True``."""
    px = np.asarray(resample_latlong(studio(16), 10), dtype=np.float64)[:9, :18]
    res = _tiny_sweep(beckmann(), px)
    assert res.meta.mitsuba.computed is False and "H even" in str(res.meta.mitsuba.reason)
    with pytest.raises(InputError, match="H even"):
        _tiny_sweep(beckmann(), px, mitsuba=True)


# ------------------------------------------------------------------------------------------------------ CLI
def test_cli_mitsuba_modes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """``--mitsuba auto`` measures a Lambert sphere (N-centred map) and plots it; ``on`` with Phong exits 2 naming the
    missing twin; ``off`` records that it was switched off. A small Mitsuba image keeps it quick."""
    from relight import cli

    monkeypatch.setattr(cli, "COMMAND_PROVIDERS", [*(p for p in cli.COMMAND_PROVIDERS if p != "relight.cli_plan"),
                                                   "relight.cli_plan"])
    monkeypatch.setenv("RELIGHT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(tradeoff.sweeps, "TwinSettings", lambda: TwinSettings(size=32, block=4, spp=256))
    costmodel.forget()
    costmodel.save_calibration(CAL, costmodel.cache_path())  # a cached calibration: the CLI does not calibrate
    src = tmp_path / "studio.exr"
    write_exr(src, studio(32))
    out = tmp_path / "out"
    base = ["tradeoff", str(src), "--out", str(out), "--rows", "16", "--size", "16", "--epsilons", "0.1",
            "--truncations", "0.1"]
    assert cli.main([*base, "--brdf", "lambert:albedo=0.8"]) == 0
    assert "against Mitsuba 3" in capsys.readouterr().out
    meta = json.loads((out / "tradeoff_meta.json").read_text())
    assert meta["mitsuba"]["computed"] is True and meta["mitsuba"]["map_center"] == "N"
    assert meta["mitsuba"]["reference_error"] < 5 * meta["mitsuba"]["noise"] + SYSTEMATIC, meta["mitsuba"]
    points = json.loads((out / "tradeoff.json").read_text())
    assert all(p["mitsuba_error"] is not None for p in points)
    assert (out / "error_vs_time.png").read_bytes()[:4] == b"\x89PNG"
    assert cli.main([*base, "--brdf", "phong:s=16", "--mitsuba", "on"]) == 2
    assert "no Mitsuba 3 twin" in capsys.readouterr().err
    assert cli.main([*base, "--brdf", "torrance-sparrow:alpha=0.3", "--mitsuba", "off"]) == 0
    assert "switched off" in capsys.readouterr().out
    assert json.loads((out / "tradeoff_meta.json").read_text())["mitsuba"]["computed"] is False
    costmodel.forget()
