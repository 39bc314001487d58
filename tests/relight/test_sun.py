"""Sun extraction and clamping (relight.sun): a synthetic sun of known direction and size, city.exr's sun against
an independently thresholded centroid, exact energy accounting, and the clamp's removed energy in closed form."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from relight.conventions import LUMINANCE_WEIGHTS, latlong_dirs, pixel_solid_angles
from relight.envmap import read_envmap
from relight.errors import InputError
from relight.sun import apply_sun, clamp_map, extract_sun, parse_sun

REPO = Path(__file__).resolve().parents[2]
CITY = REPO / "data" / "envmaps" / "city.exr"


def _energy(px: np.ndarray) -> np.ndarray:
    h, w = px.shape[:2]
    return np.asarray(np.sum(px * pixel_solid_angles(h, w)[:, None, None], axis=(0, 1)))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def test_synthetic_sun_direction_size_and_energy() -> None:
    h = 512
    d = latlong_dirs(h, 2 * h)
    sun_dir = np.array([0.35, 0.62, -0.70]) / np.linalg.norm([0.35, 0.62, -0.70])
    radius = math.radians(1.0)
    disc = d @ sun_dir >= math.cos(radius)
    sky = (0.4 + 0.3 * np.clip(d[..., 1:2], 0, 1)) * np.array([0.6, 0.8, 1.0])
    s = np.array([9.0e4, 8.5e4, 8.0e4])
    px = sky + disc[..., None] * s
    res = extract_sun(px)
    rep = res.report
    # the disc's pixel centres are symmetric about its centre to within a pixel: well inside 0.5 deg
    assert _angle_deg(np.array(rep["direction"]), sun_dir) < 0.1
    assert rep["pixels"] == int(disc.sum())
    omega = float(np.sum(pixel_solid_angles(h, 2 * h)[:, None] * disc))
    assert rep["solid_angle_sr"] == pytest.approx(omega, rel=1e-12)
    assert rep["angular_radius_deg"] == pytest.approx(1.0, abs=0.1)  # the pixelised disc's equivalent radius
    # the sun is the disc's excess over the sky (sky varies by < 1e-2 across it; S = 9e4)
    np.testing.assert_allclose(rep["irradiance_rgb"], s * omega, rtol=1e-6)
    np.testing.assert_allclose(_energy(res.pixels) + np.array(rep["irradiance_rgb"]), _energy(px), rtol=1e-3)
    assert res.pixels.max() < 2.0  # nothing of the sun is left


def test_city_sun_against_an_independent_centroid() -> None:
    px = np.asarray(read_envmap(CITY).pixels, dtype=np.float64)
    res = extract_sun(px)
    rep = res.report
    # the test's own sun region: pixels at >= half the peak luminance (the core), luminance-weighted
    h, w = px.shape[:2]
    lum = px @ LUMINANCE_WEIGHTS
    core = lum >= 0.5 * lum.max()
    wgt = (lum * pixel_solid_angles(h, w)[:, None])[core]
    centroid = (latlong_dirs(h, w)[core] * wgt[:, None]).sum(axis=0)
    assert _angle_deg(np.array(rep["direction"]), centroid) < 0.5
    # residual + sun = the original, per channel, to 0.1 % (the bound; exact by construction)
    np.testing.assert_allclose(_energy(res.pixels) + np.array(rep["irradiance_rgb"]), _energy(px), rtol=1e-3)
    assert 0.2 < rep["energy_fraction"] < 0.3 and rep["pixels"] >= 3  # the sun holds ~24 % of city.exr
    assert (res.pixels @ LUMINANCE_WEIGHTS).max() < 0.01 * lum.max()


def test_clamp_records_the_removed_energy() -> None:
    px = np.asarray(read_envmap(CITY).pixels, dtype=np.float64)
    v = 50.0
    res = clamp_map(px, v)
    lum = px @ LUMINANCE_WEIGHTS
    h, w = px.shape[:2]
    d_omega = pixel_solid_angles(h, w)[:, None]
    # scaling a pixel to luminance V removes exactly max(0, Y - V) of its luminance
    expect = float(np.sum(np.maximum(lum - v, 0.0) * d_omega) / np.sum(lum * d_omega))
    assert res.report["removed_energy_fraction"] == pytest.approx(expect, rel=1e-9)
    assert (res.pixels @ LUMINANCE_WEIGHTS).max() <= v * (1 + 1e-12)
    hue = px[lum > v] / lum[lum > v, None]
    np.testing.assert_allclose(res.pixels[lum > v] / v, hue, rtol=1e-9)  # colour kept


def test_keep_parse_and_no_sun() -> None:
    px = np.ones((16, 32, 3))
    assert apply_sun(px, "keep").report == {"mode": "keep"}
    assert parse_sun("clamp=3.5") == ("clamp", 3.5)
    for bad in ("clamp=-1", "clamp=x", "remove"):
        with pytest.raises(InputError, match="--sun"):
            parse_sun(bad)
    with pytest.raises(InputError, match="no sun"):
        extract_sun(px)


def test_export_records_the_sun(tmp_path: Path) -> None:
    out = tmp_path / "city.ktx2"
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "export", str(CITY), "--target", "three", "--size",
                           "8", "--sun", "extract", "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((tmp_path / "city.ktx2.json").read_text())
    assert manifest["sun"]["mode"] == "extract" and len(manifest["sun"]["direction"]) == 3
    bad = subprocess.run([sys.executable, "-m", "relight.cli", "export", str(CITY), "--target", "three", "--size",
                          "8", "--sun", "clamp=x", "--out", str(tmp_path / "x.ktx2")],
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and "--sun" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_prefilter_residual_plus_analytic_sun_equals_the_brute_force(tmp_path: Path) -> None:
    """``relight prefilter --sun extract``: the residual's reflection map plus the sun as a directional light
    (``E u(R . s)``) against the angular brute force of the *original* city.exr (``relight.reference``), Phong
    s = 64. The issue's bound is 2 %: the sun's region spans < 1 degree where the lobe's width is ~ 1/sqrt(s) ~ 7
    degrees, so treating it as a point costs ~ (0.5 / 7)^2 s / 8 of its share, well under 1 %; the residual's
    predicted error is below 1e-3 at the tolerance asked."""
    from relight.brdf.models import Phong
    from relight.metrics import relative_rms
    from relight.reference import reference_radial

    out = tmp_path / "phong.exr"
    report = tmp_path / "phong.json"
    cmd = [sys.executable, "-m", "relight.cli", "prefilter", str(CITY), "--brdf", "phong:s=64", "--epsilon", "1e-4",
           "--size", "32", "--out", str(out), "--report", str(report)]
    proc = subprocess.run([*cmd, "--sun", "extract"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(report.read_text())
    sun = rep["input"]["sun"]
    assert sun["mode"] == "extract"
    residual = np.asarray(read_envmap(out).pixels, dtype=np.float64)
    lobe = Phong(64)
    s_dir = np.asarray(sun["direction"])
    dirs = latlong_dirs(residual.shape[0], residual.shape[1])
    with_sun = residual + lobe.u(dirs @ s_dir)[..., :1] * np.asarray(sun["irradiance_rgb"])
    px = np.asarray(read_envmap(CITY).pixels, dtype=np.float64)
    ref = reference_radial(px, lobe, residual.shape[0])
    assert relative_rms(with_sun, ref) < 0.02
    assert relative_rms(residual, ref) > 0.1  # without the sun the map is far off: the test can fail
    # --sun keep is the plain prefilter: its input.sun says so
    keep = subprocess.run([*cmd, "--sun", "keep"], capture_output=True, text=True, timeout=600)
    assert keep.returncode == 0, keep.stderr
    assert json.loads(report.read_text())["input"]["sun"] == {"mode": "keep"}
