"""SH9 in engine conventions (relight.sh9): axes and signs pinned with clamped-cosine lights, each engine's own
reconstruction (its constants copied from its source, and three.js itself in node) against closed forms.

The light ``L(d) = max(0, d . a)`` for a = +-X, +-Y, +-Z has, on any orthonormal real basis of band l,
``c_k = 2 pi I_l Y_k(a)`` with ``I_l = int_0^1 t P_l(t) dt = 1/2, 1/3, 1/8`` (Funk–Hecke), and its order-2
irradiance is ``E_2(n) = pi/4 + (pi/3) t + (5 pi / 64)(3 t^2 - 1) / 2``, ``t = n . a`` (``A_l (2l+1)/2 I_l``).
The map is 256 x 512 pixels; its pixel sums of these polynomials are exact to ~1e-5 (the kink of max(0, .) across
pixels), hence the 1e-4 tolerances.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from relight import sh
from relight.conventions import latlong_dirs
from relight.errors import InputError
from relight.sh9 import CONVENTIONS, all_conventions, sh9

REPO = Path(__file__).resolve().parents[2]
THREE = REPO / "web" / "node_modules" / "three" / "build" / "three.module.js"
AXES = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0), "+Z": (0, 0, 1), "-Z": (0, 0, -1)}
I_L = np.array([0.5, 1.0 / 3.0, 0.125])
#: Normals where the reconstructions are compared: the axes and two oblique directions.
NORMALS = np.array([*AXES.values(), (1, 1, 1), (-0.3, 0.8, -0.52)], dtype=np.float64)
NORMALS /= np.linalg.norm(NORMALS, axis=1, keepdims=True)


def clamped_cosine(axis: tuple[int, int, int], h: int = 256) -> np.ndarray:
    d = latlong_dirs(h, 2 * h)
    return np.repeat(np.maximum(d @ np.asarray(axis, dtype=np.float64), 0.0)[..., None], 3, axis=-1)


def irradiance_2(n: np.ndarray, axis: tuple[int, int, int]) -> np.ndarray:
    t = n @ np.asarray(axis, dtype=np.float64)
    return np.pi / 4 + np.pi / 3 * t + 5 * np.pi / 64 * (3 * t * t - 1) / 2


def three_irradiance(c: np.ndarray, n: np.ndarray) -> np.ndarray:
    """three.js r187 ``SphericalHarmonics3.getIrradianceAt`` (its constants as written there)."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    terms = [np.full_like(x, 0.886227), 2 * 0.511664 * y, 2 * 0.511664 * z, 2 * 0.511664 * x,
             2 * 0.429043 * x * y, 2 * 0.429043 * y * z, 0.743125 * z * z - 0.247708, 2 * 0.429043 * x * z,
             0.429043 * (x * x - y * y)]
    return np.stack(terms, axis=-1) @ c


#: Babylon's ``SH3ylmBasisConstants`` (Condon–Shortley signs) and ``SH3ylmBasisTrigonometricTerms``.
_BABYLON_K = [math.sqrt(1 / (4 * math.pi)), -math.sqrt(3 / (4 * math.pi)), math.sqrt(3 / (4 * math.pi)),
              -math.sqrt(3 / (4 * math.pi)), math.sqrt(15 / (4 * math.pi)), -math.sqrt(15 / (4 * math.pi)),
              math.sqrt(5 / (16 * math.pi)), -math.sqrt(15 / (4 * math.pi)), math.sqrt(15 / (16 * math.pi))]
_BABYLON_COS_KERNEL = [math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5


def babylon_lambertian(harmonics: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Babylon: ``preScaleForRendering`` then the shader's ``sum l_k * trig_k(n)`` of Lambertian-radiance SH."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    trig = np.stack([np.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y], axis=-1)
    return (trig * np.asarray(_BABYLON_K)) @ harmonics


def filament_irradiance(f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Filament's ``Irradiance_SphericalHarmonics`` shader: ``sum iblSH[k] * poly_k(n)`` (irradiance / pi)."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    poly = np.stack([np.ones_like(x), y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y], axis=-1)
    return poly @ f


def unity_shader(f: np.ndarray, n_unity: np.ndarray) -> np.ndarray:
    """Unity's ``SHEvalLinearL0L1`` + ``SHEvalLinearL2`` of one channel's ``SphericalHarmonicsL2`` row ``f`` (9)
    packed as Unity packs it (``unity_SHAr = (f3, f1, f2, f0 - f6)``, ``unity_SHBr = (f4, f5, 3 f6, f7)``,
    ``unity_SHC.r = f8``), at Unity-frame normals (N, 3)."""
    sha = np.array([f[3], f[1], f[2], f[0] - f[6]])
    shb = np.array([f[4], f[5], 3 * f[6], f[7]])
    n4 = np.concatenate([n_unity, np.ones((n_unity.shape[0], 1))], axis=1)
    vb = n_unity[:, [0, 1, 2, 2]] * n_unity[:, [1, 2, 2, 0]]  # normal.xyzz * normal.yzzx
    vc = n_unity[:, 0] ** 2 - n_unity[:, 1] ** 2
    return np.asarray(n4 @ sha + vb @ shb + f[8] * vc)


#: relight's world (right-handed, three.js / glTF) to Unity's (left-handed, +Z forward): x -> -x.
TO_UNITY = np.array([-1.0, 1.0, 1.0])


@pytest.mark.parametrize("axis", list(AXES))
def test_every_convention_reconstructs_the_clamped_cosine_irradiance(axis: str) -> None:
    a = AXES[axis]
    px = clamped_cosine(a)
    expect = irradiance_2(NORMALS, a)
    got = {conv: np.asarray(sh9(px, conv)["coefficients"])[:, 0] for conv in CONVENTIONS}
    np.testing.assert_allclose(three_irradiance(got["three"], NORMALS), expect, atol=1e-4)
    # Babylon's own cube-map path: radiance -> x A_l (convertIncidentRadianceToIrradiance) -> / pi
    lam = got["babylon"] * np.asarray(_BABYLON_COS_KERNEL) / math.pi
    np.testing.assert_allclose(babylon_lambertian(lam, NORMALS), expect / math.pi, atol=1e-4)
    # its EXT_lights_image_based loader: irradiance coefficients / pi (convertIrradianceToLambertianRadiance)
    np.testing.assert_allclose(babylon_lambertian(got["gltf"] / math.pi, NORMALS), expect / math.pi, atol=1e-4)
    np.testing.assert_allclose(filament_irradiance(got["filament"], NORMALS), expect / math.pi, atol=1e-4)
    # Unity: its shader at the same normal in Unity's frame; a light on relight's +X lights Unity's -X side
    np.testing.assert_allclose(unity_shader(got["unity"], NORMALS * TO_UNITY), expect / math.pi, atol=1e-4)
    lit = unity_shader(got["unity"], np.asarray([a], dtype=np.float64) * TO_UNITY)[0]
    assert lit > 2 * unity_shader(got["unity"], -np.asarray([a], dtype=np.float64) * TO_UNITY)[0]
    # raw: relight's real SH; its order-2 radiance at d equals three's sum_k c_k K_k P_k(d) (the same function)
    d = NORMALS
    theta, phi = np.arctan2(np.hypot(d[:, 0], d[:, 2]), d[:, 1]), np.arctan2(d[:, 2], d[:, 0])
    alm = sh.from_real(got["raw"][None, :], 2)[0]
    radiance_raw = sh.evaluate(alm, 2, theta, phi)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    k = [0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274]
    poly = np.stack([np.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y], axis=-1)
    np.testing.assert_allclose(radiance_raw, (poly * k) @ got["three"], atol=2e-4)


@pytest.mark.parametrize("axis", ["+X", "-Y", "+Z"])
def test_three_coefficients_are_the_closed_form(axis: str) -> None:
    # c_k = 2 pi I_l K_k P_k(a) with three's K_k and P_k: pins order and sign of every coefficient
    a = np.asarray(AXES[axis], dtype=np.float64)
    x, y, z = a
    k = np.array([0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274])
    poly = np.array([1, y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y])
    expect = 2 * np.pi * I_L[[0, 1, 1, 1, 2, 2, 2, 2, 2]] * k * poly
    got = np.asarray(sh9(clamped_cosine(AXES[axis]), "three")["coefficients"])
    np.testing.assert_allclose(got, np.repeat(expect[:, None], 3, axis=1), atol=2e-5 * 2 * np.pi)


def test_three_js_itself_reads_the_coefficients() -> None:
    # three r187's SphericalHarmonics3 (the LightProbe's) in node: its getIrradianceAt at the normals equals
    # the closed form for a +Z and a -X light.
    node = shutil.which("node")
    assert node is not None and THREE.is_file(), "node and web/node_modules (npm ci --prefix web) are needed"
    script = (
        f"import {{ SphericalHarmonics3, Vector3 }} from '{THREE.as_uri()}';\n"
        "const input = JSON.parse(process.argv[1]);\n"
        "const out = input.sets.map((c) => { const sh = new SphericalHarmonics3();\n"
        "  sh.set(c.map((v) => new Vector3(...v)));\n"
        "  return input.normals.map((n) => sh.getIrradianceAt(new Vector3(...n), new Vector3()).x); });\n"
        "console.log(JSON.stringify(out));\n"
    )
    axes = [(0, 0, 1), (-1, 0, 0)]
    sets = [sh9(clamped_cosine(a, 128), "three")["coefficients"] for a in axes]
    proc = subprocess.run([node, "--input-type=module", "-e", script,
                           json.dumps({"sets": sets, "normals": NORMALS.tolist()})],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    got = np.asarray(json.loads(proc.stdout))
    for row, a in zip(got, axes, strict=True):
        np.testing.assert_allclose(row, irradiance_2(NORMALS, a), atol=3e-4)  # 128 rows: ~1e-4 quadrature


def test_unity_ambient_is_its_add_ambient_light() -> None:
    """Unity's ``SphericalHarmonicsL2.AddAmbientLight(c)`` adds ``c`` to ``sh[rgb, 0]`` (its shader then returns
    ``c`` for every normal): a uniform map of radiance ``c`` has exactly that Unity SH. The pixel sum of a constant
    is exact to rounding; the odd terms vanish by the grid's symmetry; ``3 y^2 - 1`` and ``x^2 - y^2`` (y up) are
    midpoint sums over rows, off by O(row height^2): 7.5e-4 at 32 rows for c = 2, so < 2e-5 at 256 rows."""
    c = np.array([0.7, 1.3, 2.0])
    px = np.broadcast_to(c, (256, 512, 3)).copy()
    got = np.asarray(sh9(px, "unity")["coefficients"])
    np.testing.assert_allclose(got[0], c, rtol=1e-9)
    np.testing.assert_allclose(got[1:], 0.0, atol=1e-4)
    assert sh9(px, "unity")["quantity"] == "irradiance/pi" and "Unity" in sh9(px, "unity")["frame"]


def test_all_conventions_and_bad_names() -> None:
    px = clamped_cosine((0, 1, 0), 32)
    every = all_conventions(px)
    assert set(every) == set(CONVENTIONS)
    for conv in CONVENTIONS:
        np.testing.assert_allclose(every[conv]["coefficients"], sh9(px, conv)["coefficients"], rtol=1e-12)
    with pytest.raises(InputError, match="unity3d"):
        sh9(px, "unity3d")
