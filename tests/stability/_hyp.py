"""Shared hypothesis settings and strategies of the stability suite.

Every property test is derandomized (the same examples on every run, no example database) with a bounded number of
examples, so the suite is deterministic and its run time fixed; deadlines are off because shared CI machines are
noisy, and each test states its own budget through ``max_examples``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st


def stable(max_examples: int) -> Callable[[Any], Any]:
    """``@settings`` for the suite: derandomized, no database, no deadline, ``max_examples`` examples."""
    return settings(max_examples=max_examples, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def near(base: float) -> st.SearchStrategy[float]:
    """``base`` itself or ``base +- m 10^-k`` (k = 1..14), clipped to [0, pi]: at and next to a special angle."""
    offset = st.builds(lambda k, sign, mant: sign * mant * 10.0 ** (-k), st.integers(1, 14), st.sampled_from([-1, 1]),
                       st.floats(1.0, 9.99))
    return st.one_of(st.just(base), st.builds(lambda o: float(min(max(base + o, 0.0), math.pi)), offset))


#: Polar angles at and next to the poles and the equator, and anywhere in between.
HARD_ANGLES: st.SearchStrategy[float] = st.one_of(near(0.0), near(math.pi / 2), near(math.pi),
                                                   st.floats(0.0, math.pi, allow_nan=False))


def m_near_l_over_e(l: int) -> st.SearchStrategy[int]:
    """m near l / e (where sin^m theta underflows a naive recursion), or 0, l, or any m in 0..l."""
    centre = int(round(l / math.e))
    return st.one_of(st.integers(max(0, centre - 3), min(l, centre + 3)), st.sampled_from([0, l]),
                     st.integers(0, l))


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    """A float spread evenly in log between lo and hi (inclusive)."""
    return st.floats(math.log(lo), math.log(hi)).map(lambda x: float(min(max(math.exp(x), lo), hi)))


def rng(seed: int = 42) -> np.random.Generator:
    return np.random.default_rng(seed)
