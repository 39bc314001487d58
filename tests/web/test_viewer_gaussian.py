"""The viewer's Gaussian lobes panel (web/src/gaussian_panel.js) in a real browser against a real server: two fits
and one chain through POST /jobs, instant switching between the materials on the one chain (no request), live lobe
editing (the image is linear in each lobe's weight), and the charts of error and parameters against theta_o."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.web.conftest import screenshot
from tests.web.test_viewer_browser import upload_map

pytestmark = [pytest.mark.timeout(600)]


def _fit(page: Any, brdf: str) -> None:
    before = page.evaluate("window.relight.gaussian.materials.size")
    page.fill("#sg-brdf", brdf)
    page.fill("#sg-lobes", "2")
    page.fill("#sg-elevations", "4")
    page.click("#sg-fit")
    page.wait_for_function(f"window.relight.gaussian.materials.size > {before}"
                           " || document.getElementById('sg-error').textContent", timeout=300_000)
    assert page.inner_text("#sg-error") == ""


def _pixels(page: Any) -> np.ndarray:
    return np.asarray(page.evaluate("Array.from(window.relight.gaussian.pixels())"), dtype=np.float64)


def _set(page: Any, slider: str, value: float) -> np.ndarray:
    before = page.evaluate("window.relight.gaussian.draws")
    page.evaluate("([id, v]) => { const el = document.getElementById(id); el.value = v;"
                  " el.dispatchEvent(new Event('input')); }", [slider, value])
    page.wait_for_function(f"window.relight.gaussian.draws > {before}", timeout=60_000)
    return _pixels(page)


def test_gaussian_panel_switches_edits_and_charts(page: Any, tmp_path: Any) -> None:
    upload_map(page, tmp_path, name="gaussian-sky.exr")
    _fit(page, "torrance-sparrow:alpha=0.3,fresnel=none")
    page.click("#sg-chain")
    page.wait_for_function("window.relight.gaussian.chain || document.getElementById('sg-error').textContent",
                           timeout=300_000)
    assert page.inner_text("#sg-error") == ""
    _fit(page, "ggx:alpha=0.15")
    ids = page.evaluate("[...window.relight.gaussian.materials.keys()]")
    assert len(ids) == 2
    # _fit returns once the material is listed; its first draw may still be in flight (pixels() would then be the
    # previous material's image): wait until it is current and draw it
    page.wait_for_function(f"window.relight.gaussian.current === '{ids[1]}'")
    page.evaluate("window.relight.gaussian.redraw()")
    second = _pixels(page)
    assert second.max() > 0

    # ---- switching: the other material on the same chain, with no request at all (two lobe textures change)
    requests = page.evaluate("window.relight.gaussian.requests")
    page.click(f"#sg-materials button[data-id='{ids[0]}']")
    page.wait_for_function(f"window.relight.gaussian.current === '{ids[0]}'")
    page.wait_for_function("window.relight.gaussian.draws > 0")
    page.evaluate("window.relight.gaussian.redraw()")
    first = _pixels(page)
    assert page.evaluate("window.relight.gaussian.requests") == requests
    assert np.abs(first - second).max() > 1e-3 * second.max()  # a rougher material: another image
    page.click(f"#sg-materials button[data-id='{ids[1]}']")
    page.wait_for_function(f"window.relight.gaussian.current === '{ids[1]}'")
    page.evaluate("window.relight.gaussian.redraw()")
    np.testing.assert_array_equal(_pixels(page), second)  # back again: the same image, bit for bit

    # ---- editing: the image is linear in each lobe's weight (eq. 5; interpolation in theta_o is linear in w), so
    # with lobe 1 at the first elevation scaled by 2, 1 and 0 the middle image is the mean of the other two.
    # Tolerance: float16 weights (relative 2^-11) and float32 sums, relative to the brightest pixel.
    page.select_option("#sg-elev", "0")
    page.select_option("#sg-lobe", "0")
    double = _set(page, "sg-weight", 2.0)
    zero = _set(page, "sg-weight", 0.0)
    one = _set(page, "sg-weight", 1.0)
    np.testing.assert_allclose(one, 0.5 * (double + zero), atol=2e-3 * one.max())
    assert np.abs(double - zero).max() > 1e-2 * one.max()  # the lobe matters near normal view
    mu = page.evaluate("Number(document.getElementById('sg-mu').value)")
    _set(page, "sg-mu", mu + 5.0)
    lobe = page.evaluate("""() => { const g = window.relight.gaussian; const m = g.materials.get(g.current);
        const t = 0; return m.shape[t]; }""")
    assert lobe != 0  # mu at theta_o = 0 was 0: the edit moved it (float16 bits of 5 degrees in radians)

    # ---- charts: error vs theta_o (fitted and interpolated mid-elevations), mu, sigma and weight vs theta_o
    n, k = page.evaluate("""() => { const m = window.relight.gaussian.materials.get(window.relight.gaussian.current);
        return [m.elevations.length, m.lobes]; }""")
    charts = page.evaluate("""() => [...document.querySelectorAll('#sg-charts svg')].map(
        (s) => [...s.querySelectorAll('polyline.series')].map((p) => p.getAttribute('points').split(' ').length))""")
    assert len(charts) == 4 and charts[0] == [n, n - 1], charts
    assert all(c == [n] * k for c in charts[1:]), charts  # one series per lobe (K = 2, up to 4 where needed)
    page.evaluate("document.getElementById('gaussian-panel').scrollIntoView()")
    screenshot(page, "viewer-gaussian-panel")
