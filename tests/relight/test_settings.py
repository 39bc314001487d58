"""``RELIGHT_THREADS`` is the one thread setting of the core (``relight.settings``): ducc0 gets it as ``nthreads``
and every BLAS library NumPy loaded is limited to it once ``relight.sh`` is imported."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from relight.errors import InputError
from relight.settings import CoreSettings

PROBE = ("import json; from relight import sh; from threadpoolctl import threadpool_info; "
         "print(json.dumps({'ducc0': sh.NTHREADS, "
         "'blas': [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']}))")


def _probe(threads: str) -> dict[str, object]:
    # no OPENBLAS_NUM_THREADS / OMP_NUM_THREADS: without relight's limit OpenBLAS starts one thread per core
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env["RELIGHT_THREADS"] = threads
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True).stdout
    result: dict[str, object] = json.loads(out)
    return result


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_ducc0_and_blas_get_the_same_thread_count(threads: int) -> None:
    got = _probe(str(threads))
    assert got["ducc0"] == threads
    assert got["blas"], "NumPy loaded no BLAS library that threadpoolctl can see"
    assert got["blas"] == [threads] * len(got["blas"])  # type: ignore[arg-type]


@pytest.mark.parametrize("raw", ["0", "-2", "two", ""])
def test_a_bad_thread_count_is_refused_by_name(raw: str) -> None:
    with pytest.raises(InputError, match=f"RELIGHT_THREADS must be a positive integer.*{raw!r}"):
        CoreSettings.from_env({"RELIGHT_THREADS": raw})


def test_default_is_one_thread() -> None:
    assert CoreSettings.from_env({}).threads == 1
