"""No NaN or Inf in any output for any accepted input; rejected inputs get a clear ``InputError``.

Accepted inputs: maps with any finite float32 values (what ``relight.envmap`` reads: zeros, subnormals, huge
values, suns, negative texels handed to the core directly), every BRDF and order the API allows. Outputs: maps,
coefficients and reports (serialised as strict JSON, which refuses NaN and Inf).

Some tests here fail on the current core; each says what it expects and why (see the failing assertion).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from relight.brdf.models import KajiyaKay, Microfacet
from relight.brdf.radial import Lambert, Phong
from relight.errors import InputError
from relight.prefilter import prefilter_radial
from relight.reference import reference_radial
from relight.shrm import create_shrm, reflect

from ._hyp import stable

F32_MAX = float(np.finfo(np.float32).max)
SPECIAL = [0.0, 1e-45, 1e-38, 1e-30, 1.0, 1e5, 1e30, F32_MAX / 16, -1e-3, -5.0]


@st.composite
def hard_maps(draw: st.DrawFn) -> np.ndarray:
    """(H, 2H, 3) float32 maps: a background level and a few texels set to extreme finite values."""
    h = draw(st.sampled_from([2, 4, 8, 16]))
    base = draw(st.sampled_from([0.0, 1e-30, 1.0, 1e20]))
    px = np.full((h, 2 * h, 3), base, dtype=np.float32)
    for _ in range(draw(st.integers(0, 4))):
        i, j, c = draw(st.integers(0, h - 1)), draw(st.integers(0, 2 * h - 1)), draw(st.integers(0, 2))
        px[i, j, c] = draw(st.one_of(st.sampled_from(SPECIAL), st.floats(-1e3, F32_MAX, width=32)))
    return px


def strict_json(obj: Any) -> None:
    json.dumps(obj, allow_nan=False)


@stable(40)
@given(px=hard_maps(), lobe=st.sampled_from([Phong(1.0), Phong(64.0), Phong(5000.0), Lambert()]),
       setting=st.sampled_from([{"epsilon": 0.1}, {"epsilon": 1e-4}, {"order": 3}, {"order": 40}]))
def test_prefilter_outputs_are_finite_for_finite_maps(px: np.ndarray, lobe: Any, setting: dict[str, Any]) -> None:
    res = prefilter_radial(px, lobe, size=8, **setting)
    assert np.all(np.isfinite(res.map)) and np.all(np.isfinite(res.coefficients))
    strict_json(res.report.to_json())


@stable(15)
@given(px=hard_maps(), lobe=st.sampled_from([Microfacet(0.5), KajiyaKay(8.0), Phong(16.0)]),
       view=st.sampled_from([(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, -1.0, 1e-9), (1.0, 0.0, -1e-12)]))
def test_shrm_outputs_are_finite_for_finite_maps(px: np.ndarray, lobe: Any, view: tuple[float, ...]) -> None:
    sm = create_shrm(px, lobe, order=4, p_order=2, size=4)
    for comp in sm.components:
        assert np.all(np.isfinite(comp.maps))
    assert np.all(np.isfinite(reflect(sm, view)))
    strict_json(sm.report.to_json())  # type: ignore[attr-defined]  # create_shrm: a relight.reports.ShrmReport


# ------------------------------------------------------------------------------------------------ rejections
BAD_PIXELS = {"nan": np.nan, "inf": np.inf, "-inf": -np.inf}


@pytest.mark.parametrize("call", ["prefilter_radial", "create_shrm", "reference_radial"])
def test_non_finite_pixels_are_rejected(call: str) -> None:
    """A NaN or Inf texel must be an InputError naming the problem, not a map of NaN (``relight.envmap`` rejects
    such files; the core's array API must not turn them into NaN outputs either)."""
    for bad in BAD_PIXELS.values():
        px = np.ones((8, 16, 3))
        px[2, 3, 1] = bad
        fn = {"prefilter_radial": lambda px=px: prefilter_radial(px, Phong(8.0), epsilon=0.01),
              "create_shrm": lambda px=px: create_shrm(px, Microfacet(0.4), epsilon=0.1),
              "reference_radial": lambda px=px: reference_radial(px, Phong(8.0), 4)}[call]
        with pytest.raises(InputError, match="(?i)finite|nan|inf"):
            fn()


def test_huge_float64_values_do_not_give_nan_predictions() -> None:
    """A finite float64 map whose luminance squared overflows (1e200): accepted, so its report must stay finite
    (the energy sums are formed in float64 without scaling and overflow to inf; inf / inf = NaN)."""
    px = np.ones((8, 16, 3))
    px[3, 4] = 1e200
    try:
        res = prefilter_radial(px, Phong(8.0), epsilon=0.01)
    except InputError:
        return  # rejecting such values is fine too
    assert np.all(np.isfinite(res.map))
    strict_json(res.report.to_json())


WRONG_SHAPES = [(np.ones((8, 16)), "(8, 16)"), (np.ones((8, 16, 4)), "(8, 16, 4)"),
                (np.ones((8, 15, 3)), "width = 2 x height"), (np.ones((0, 0, 3)), "empty"), (np.ones(5), "(5,)")]


@pytest.mark.parametrize("call", ["prefilter_radial", "create_shrm"])
def test_wrong_map_shapes_are_input_errors(call: str) -> None:
    """Shapes the prefilter cannot use: an InputError quoting the shape (create_shrm does; prefilter_radial raises a
    bare ValueError, or numpy's matmul error for grey and RGBA maps)."""
    for pixels, fragment in WRONG_SHAPES:
        with pytest.raises(InputError) as info:
            if call == "prefilter_radial":
                prefilter_radial(pixels, Phong(8.0), epsilon=0.01)
            else:
                create_shrm(pixels, Microfacet(0.4), epsilon=0.1)
        assert fragment in str(info.value), (pixels.shape, str(info.value))


@pytest.mark.parametrize(("kwargs", "fragment"), [
    ({"epsilon": 0.0}, "epsilon"), ({"epsilon": 1.0}, "epsilon"), ({"epsilon": float("nan")}, "epsilon"),
    ({"order": -1}, "order"), ({"size": 1}, "size"), ({"epsilon": 0.1, "order": 3}, "not both"),
    ({"window": "bogus"}, "window"),
])
def test_bad_prefilter_parameters_are_input_errors(kwargs: dict[str, Any], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        prefilter_radial(np.ones((8, 16, 3)), Phong(8.0), **kwargs)


def test_orders_beyond_the_map_do_not_cost_beyond_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """An explicit order above what the map resolves is capped at F_B = H - 1; the BRDF coefficients must not be
    computed to the requested order (order = 2000 on an 8-row map took 6.5 s in radial_transfer, 10^6 exhausts
    memory). Checked by recording the orders the coefficient routines are asked for. (An SHRM's view spectrum,
    relight.shrm.view_spectrum, reaches a bounded spectrum_order(H - 1) beyond it for the prediction.)"""
    from relight.brdf import coefficients, lobe_cache, lpq
    from relight.shrm import order_search, view_spectrum
    from relight.shrm.creation import spectrum_order

    asked: list[int] = []
    real_radial = coefficients.radial_transfer
    real_lpq = lpq.brdf_coefficients

    def radial(lobe: Any, lmax: int) -> Any:
        asked.append(lmax)
        return real_radial(lobe, min(lmax, 64))

    def general(lobe: Any, f_order: int, p_order: int, **kw: Any) -> Any:
        asked.append(f_order)
        return real_lpq(lobe, min(f_order, 64), p_order, **kw)

    real_view = view_spectrum.view_spectrum

    def per_view(lobe: Any, f_order: int, p_order: int, **kw: Any) -> Any:
        asked.append(f_order if f_order <= spectrum_order(7, 7) else 10**6)
        return real_view(lobe, min(f_order, 64), p_order, **kw)

    monkeypatch.setattr("relight.prefilter.radial_transfer", radial)
    monkeypatch.setattr(lpq, "brdf_coefficients", general)
    monkeypatch.setattr(order_search, "view_spectrum", per_view)
    lobe_cache.clear()
    px = np.ones((8, 16, 3))
    too_far = {}
    for name, call in (("prefilter_radial", lambda: prefilter_radial(px, Phong(8.0), order=2000, size=8)),
                       ("create_shrm", lambda: create_shrm(px, Microfacet(0.4), order=2000, p_order=1, size=8))):
        asked.clear()
        try:
            call()
        except InputError:
            continue  # rejecting the order is fine too
        if max(asked) > spectrum_order(7, 7):
            too_far[name] = max(asked)
    lobe_cache.clear()
    assert not too_far, f"coefficients computed to these orders for an 8-row map: {too_far}"
