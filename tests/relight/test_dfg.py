"""The split-sum DFG table (relight.dfg) against adaptive quadrature over l, and against Filament's cmgen.

Reference: ``int D V NoL {1 - Fc, Fc} dl`` by scipy's ``dblquad`` in the angles of l (a different variable from
the table's half-vector CDF, so an error in the substitution, the horizon cut or the weights shows), to 1e-8
relative; the table's Gauss–Legendre rule converged to ~5e-6 there (96 x 48 nodes), hence 2e-5.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import dblquad

from relight.dfg import dfg_table, dfg_terms, v_smith_ggx_correlated
from relight.envmap.exr import read_exr_layers
from relight.errors import InputError


def _reference(nov: float, r: float) -> tuple[float, float]:
    a = r * r
    v = np.array([math.sqrt(1 - nov * nov), 0.0, nov])

    def f(th: float, ph: float, fresnel: bool) -> float:
        lv = np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
        h = (v + lv) / np.linalg.norm(v + lv)
        d = a * a / (math.pi * (h[2] ** 2 * (a * a - 1) + 1) ** 2)
        vis = float(v_smith_ggx_correlated(np.float64(nov), np.float64(lv[2]), np.float64(a)))
        fc = (1.0 - float(v @ h)) ** 5
        return d * vis * lv[2] * (fc if fresnel else 1.0 - fc) * math.sin(th)

    # even in phi: twice the half plane; theta up to the horizon
    out = [2 * dblquad(lambda th, ph, w=w: f(th, ph, w), 0, math.pi, 0, math.pi / 2, epsabs=1e-10,
                       epsrel=1e-8)[0] for w in (False, True)]
    return out[0], out[1]


@pytest.mark.parametrize(("nov", "r"), [(0.5, 0.3), (0.1, 0.6), (0.9, 0.6), (0.2, 1.0), (0.02, 0.5)])
def test_terms_match_adaptive_quadrature_over_l(nov: float, r: float) -> None:
    got = dfg_terms(np.array([nov]), np.array([r]))[0]
    np.testing.assert_allclose(got, _reference(nov, r), atol=2e-5)


def test_table_layout_and_multiscatter() -> None:
    t = dfg_table(8)
    c = (np.arange(8) + 0.5) / 8
    # row i = roughness, column j = NoV
    np.testing.assert_allclose(t[5, 2], dfg_terms(np.array([c[2]]), np.array([c[5]]))[0], rtol=1e-12)
    ms = dfg_table(8, multiscatter=True)
    np.testing.assert_allclose(ms[..., 0], t[..., 1], rtol=1e-12)
    np.testing.assert_allclose(ms[..., 1], t[..., 0] + t[..., 1], rtol=1e-12)
    assert np.all(ms[..., 1] <= 1.0 + 1e-9)  # single scattering never gains energy
    with pytest.raises(InputError, match="size"):
        dfg_table(1)


def test_matches_cmgen_ibl_dfg(tmp_path: Path) -> None:
    # cmgen 1.9.25 writes row y at perceptual roughness min(1, (h - y + 0.5) / h) (its LUT is flipped and one row
    # off the texel centres) and column x at NoV = (x + 0.5) / w, from 1024 Hammersley samples per texel in half
    # floats. Its Monte Carlo noise grows toward grazing (measured: +-0.008 at NoV = 0.13); from NoV = 0.25 on
    # the two agree to 2e-3 RMS, and the median texel to 1e-3 everywhere.
    cmgen = shutil.which("cmgen")
    assert cmgen is not None, "cmgen is needed (Debian libfilament-tools, in the Makefile's SYSTEM_PKGS)"
    out = tmp_path / "dfg.exr"
    proc = subprocess.run([cmgen, f"--ibl-dfg={out}", "--size=64"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    cm = np.asarray(read_exr_layers(out)[0][""], dtype=np.float64)[..., :2]
    h = cm.shape[0]
    r = np.minimum(1.0, (h - np.arange(h) + 0.5) / h)
    nov = (np.arange(h) + 0.5) / h
    rr, nn = np.meshgrid(r, nov, indexing="ij")
    diff = cm - dfg_terms(nn, rr)
    assert np.median(np.abs(diff)) < 1e-3
    assert np.sqrt(np.mean(diff[:, nov >= 0.25] ** 2)) < 2e-3


def test_cli_writes_exr_and_png(tmp_path: Path) -> None:
    exr = tmp_path / "dfg.exr"
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "dfg", "--size", "16", "--out", str(exr)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    img = read_exr_layers(exr)[0][""]
    np.testing.assert_allclose(img[..., :2], dfg_table(16), atol=1e-6)
    png = tmp_path / "dfg.png"
    proc = subprocess.run([sys.executable, "-m", "relight.cli", "dfg", "--size", "16", "--multiscatter", "--out",
                           str(png)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    import imagecodecs

    raw = imagecodecs.png_decode(png.read_bytes())
    assert raw.dtype == np.uint16
    np.testing.assert_allclose(raw[..., :2] / 65535.0, dfg_table(16, multiscatter=True), atol=1.0 / 65535)
    bad = subprocess.run([sys.executable, "-m", "relight.cli", "dfg", "--out", str(tmp_path / "x.bmp")],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and ".exr, .png or .ktx2" in bad.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dfg.exr", "dfg.png"]


KTX_PARSE = Path(__file__).resolve().parents[2] / "web" / "node_modules" / "ktx-parse" / "dist" / "index.mjs"
NODE_READ = """
import { read, write } from %s;
import { readFileSync } from 'node:fs';
const bytes = new Uint8Array(readFileSync(process.argv[process.argv.length - 1]));
const c = read(bytes);
const again = write(c, { keepWriter: true });
const half = new Uint16Array(c.levels[0].levelData.buffer.slice(c.levels[0].levelData.byteOffset,
  c.levels[0].levelData.byteOffset + c.levels[0].levelData.byteLength));
console.log(JSON.stringify({vkFormat: c.vkFormat, faces: c.faceCount, width: c.pixelWidth, height: c.pixelHeight,
  levels: c.levelCount, identical: again.length === bytes.length && again.every((v, i) => v === bytes[i]),
  dfg: JSON.parse(new TextDecoder().decode(c.keyValue['relight.dfg']).replace(/\\0+$/, '')),
  half: Array.from(half)}));
"""


@pytest.mark.parametrize("multiscatter", [False, True])
def test_cli_writes_a_2d_ktx2_that_ktx_parse_reads(tmp_path: Path, multiscatter: bool) -> None:
    """``--out FILE.ktx2``: npm ktx-parse (three's KTX2Loader parser) reads a 2-D RGBA16F texture (faceCount 1,
    one level, 16 x 16) and re-serialises it byte for byte; its half floats decoded here equal the table to the
    float16 quantum (values in [0, 1]: 2^-11 relative, at most 4.9e-4)."""
    out = tmp_path / "dfg.ktx2"
    cmd = [sys.executable, "-m", "relight.cli", "dfg", "--size", "16", "--out", str(out)]
    proc = subprocess.run(cmd + (["--multiscatter"] if multiscatter else []), capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    node = shutil.which("node")
    assert node is not None and KTX_PARSE.is_file(), "node and web/node_modules (npm ci --prefix web) are needed"
    script = tmp_path / "read.mjs"
    script.write_text(NODE_READ % repr(KTX_PARSE.as_uri()))
    res = subprocess.run([node, str(script), str(out)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    import json

    got = json.loads(res.stdout)
    assert (got["vkFormat"], got["faces"], got["width"], got["height"], got["levels"]) == (97, 1, 16, 16, 1)
    assert got["identical"]
    assert got["dfg"]["channels"] == ("(B, A + B)" if multiscatter else "(A, B)")
    texels = np.asarray(got["half"], dtype=np.uint16).view(np.float16).astype(np.float64).reshape(16, 16, 4)
    np.testing.assert_allclose(texels[..., :2], dfg_table(16, multiscatter=multiscatter), atol=4.9e-4)
    np.testing.assert_array_equal(texels[..., 2:], np.broadcast_to([0.0, 1.0], (16, 16, 2)))
