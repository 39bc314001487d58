"""App. C's whole-lobe order search (relight.brdf.lpq_search): seed 000 Table 5's orders, growth from a small
start, the caps, its cache, and one clear() for every lobe cache."""

from __future__ import annotations

import pytest

from relight.brdf import lobe_cache, lpq, lpq_search
from relight.brdf.spec import parse_brdf
from relight.shrm import order_search


@pytest.mark.parametrize(("sigma", "paper"), [(0.1, (24, 3)), (0.2, (12, 2)), (0.3, (7, 2)), (0.5, (5, 2))])
def test_order_selection_reproduces_table5(sigma: float, paper: tuple[int, int]) -> None:
    sel = lpq_search.select_orders(parse_brdf(f"microfacet:sigma={sigma}"), 0.03)
    assert sel.met
    table = sel.coefficients.epsilon_table()
    f0 = sel.coefficients.F
    # App. C: P is the smallest order meeting the tolerance at the probe F, then F the smallest at that P
    assert table[sel.F, sel.P] <= 0.03
    assert sel.P == 0 or table[f0, sel.P - 1] > 0.03
    assert sel.F == 0 or table[sel.F - 1, sel.P] > 0.03
    # seed 000 Table 5 (F_B, P_B) for epsilon < 0.03, within the spread of a different tabulation
    assert abs(sel.F - paper[0]) <= 2 and paper[1] - 1 <= sel.P <= paper[1]


def test_order_selection_grows_from_a_small_start() -> None:
    lobe = parse_brdf("microfacet:sigma=0.2")
    small = lpq_search.select_orders(lobe, 0.03, start=(4, 1))
    default = lpq_search.select_orders(lobe, 0.03)
    assert len(small.history) > 1 and small.met
    assert abs(small.F - default.F) <= 1 and small.P == default.P
    capped = lpq_search.select_orders(lobe, 1e-9, start=(4, 1), f_cap=8, p_cap=2)
    assert not capped.met and (capped.F, capped.P) == (8, 2)


def test_cache_and_errors() -> None:
    lobe_cache.clear()
    lobe = parse_brdf("microfacet:sigma=0.4")
    s1, h1 = lpq_search.cached_select_orders(lobe, 0.05)
    s2, h2 = lpq_search.cached_select_orders(parse_brdf("microfacet:sigma=0.4"), 0.05)
    assert (h1, h2) == (False, True) and s1 is s2
    with pytest.raises(ValueError, match="epsilon"):
        lpq_search.select_orders(lobe, 1.5)


def test_one_clear_empties_every_lobe_cache() -> None:
    # The calibration and the sweep's points time the tabulations after lobe_cache.clear(): the coefficient cache,
    # App. C's search and the view-band search must all miss afterwards (before, clearing lpq's cache left the
    # view-band search's cache of create_shrm warm).
    lobe = parse_brdf("microfacet:sigma=0.4")
    lpq.cached_coefficients(lobe, 6, 2)
    lpq_search.cached_select_orders(lobe, 0.05)
    order_search.cached_search(lobe, 0.05)
    assert lpq.cached_coefficients(lobe, 6, 2)[1] and lpq_search.cached_select_orders(lobe, 0.05)[1]
    assert order_search.cached_search(lobe, 0.05)[1]
    lobe_cache.clear()
    assert not lpq.cached_coefficients(lobe, 6, 2)[1]
    assert not lpq_search.cached_select_orders(lobe, 0.05)[1]
    assert not order_search.cached_search(lobe, 0.05)[1]
    lobe_cache.clear()
