"""Golden outputs (issue 11 item 7): the numbers of a fixed set of computations (``tests/golden/regen.py``: radial
prefilters, an SHRM and its view, a BRDF's SHRM coefficients, scene and job plan orders) are pinned by digest
together with the ``relight.ALGORITHM_VERSION`` they were made with. Any change of the numbers fails this test until
the version is bumped (it is part of every job's and cache's key) and the digests regenerated.

The digests round every array to ``DIGITS`` significant digits relative to its scale, so BLAS and FFT reordering
between machines does not trip them (``tests/golden/regen.py`` explains the rounding and its flip rate).
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import relight

REGEN = "python -m tests.golden.regen"


def _regen_module() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "golden" / "regen.py"
    spec = importlib.util.spec_from_file_location("relight_golden_regen", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


GOLDEN = _regen_module()


def test_golden_outputs_match_the_algorithm_version() -> None:
    stored = json.loads(GOLDEN.GOLDEN.read_text(encoding="utf-8"))
    if stored["algorithm_version"] != relight.ALGORITHM_VERSION:
        pytest.fail(f"relight.ALGORITHM_VERSION is {relight.ALGORITHM_VERSION!r} but tests/golden/golden.json was "
                    f"made with {stored['algorithm_version']!r}: regenerate it with `{REGEN}` (from the repository "
                    "root) and commit it with the version bump")
    assert stored["digits"] == GOLDEN.DIGITS, f"the rounding changed: regenerate with `{REGEN}`"
    now = GOLDEN.compute()
    assert set(now) == set(stored["computations"]), f"the golden set changed: regenerate with `{REGEN}`"
    changed = {name: {"scales now": now[name]["scales"], "scales stored": stored["computations"][name]["scales"]}
               for name in now if now[name]["sha256"] != stored["computations"][name]["sha256"]}
    assert not changed, (
        f"numerical output changed without an ALGORITHM_VERSION bump: {sorted(changed)} ({changed}). If the change "
        f"is intended, bump relight.ALGORITHM_VERSION (relight/__init__.py; it keys every cached job and result) and "
        f"regenerate the golden digests with `{REGEN}`; otherwise find what moved the numbers.")


def test_digest_ignores_noise_below_the_rounding_and_sees_a_change_above_it() -> None:
    """The rounding at work: a relative perturbation of 1e-13 (BLAS/FFT reordering between machines) keeps the
    digest (for values away from a rounding boundary: these are centred in their quanta), a change of one unit in
    the last kept digit changes it, and an exact zero computed as 1e-17 beside values of order 1 is noise."""
    d = GOLDEN.DIGITS
    base = (np.arange(1, 50) + 0.25) * 10.0 ** -d * 1e6  # values of order 1e-2..0.5, off the rounding boundaries
    ref = GOLDEN.digest({"x": base, "n": [3, 4]})
    assert GOLDEN.digest({"x": base * (1 + 1e-13), "n": [3, 4]}) == ref
    assert GOLDEN.digest({"x": np.append(base, 0.0), "n": [3, 4]}) == GOLDEN.digest(
        {"x": np.append(base, 1e-17), "n": [3, 4]})
    bumped = base.copy()
    bumped[7] += 10.0 ** (np.ceil(np.log10(base.max())) - d)
    assert GOLDEN.digest({"x": bumped, "n": [3, 4]}) != ref
    assert GOLDEN.digest({"x": base, "n": [3, 5]}) != ref  # orders are exact
    z = base + 1j * base[::-1]
    assert GOLDEN.digest({"z": z}) != GOLDEN.digest({"z": z.conj()})  # complex parts both count
