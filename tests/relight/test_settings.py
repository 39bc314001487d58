"""``RELIGHT_THREADS`` is the one thread setting of the core (``relight.settings``): ducc0 gets it as ``nthreads``
and every BLAS library is limited to it: NumPy's and SciPy's (two separate OpenBLAS builds), whether they load
before relight, between ``import relight`` and ``relight.sh``, or after."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from relight.errors import InputError
from relight.settings import CoreSettings

#: Import orders: SciPy's OpenBLAS loads with scipy.special / scipy.linalg, NumPy's with numpy.
ORDERS = {
    "relight first": "from relight import sh; import scipy.special, scipy.linalg",
    "numpy and scipy first": "import numpy, scipy.linalg; from relight import sh",
    "scipy between": "import relight; import scipy.linalg; from relight import sh",
}
PROBE = ("import json; {imports}; from threadpoolctl import threadpool_info; "
         "print(json.dumps({{'ducc0': sh.NTHREADS, "
         "'blas': [[p['filepath'], p['num_threads']] for p in threadpool_info() if p['user_api'] == 'blas']}}))")


def _probe(threads: str, imports: str) -> dict[str, object]:
    # no OPENBLAS_NUM_THREADS / OMP_NUM_THREADS: without relight's limit OpenBLAS starts one thread per core
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env["RELIGHT_THREADS"] = threads
    out = subprocess.run([sys.executable, "-c", PROBE.format(imports=imports)], env=env, capture_output=True,
                         text=True, check=True).stdout
    result: dict[str, object] = json.loads(out)
    return result


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_ducc0_and_blas_get_the_same_thread_count(threads: int, order: str) -> None:
    got = _probe(str(threads), ORDERS[order])
    assert got["ducc0"] == threads
    blas: list[list[object]] = got["blas"]  # type: ignore[assignment]
    libraries = {str(path).split("/")[-2] for path, _ in blas}
    assert {"numpy.libs", "scipy.libs"} <= libraries, blas  # both wheels' own OpenBLAS are loaded and seen
    # OpenBLAS initialised from the environment caps the count at the cores it sees (a setting above them runs
    # one thread per core): never more than the setting, never fewer than the setting or the cores allow
    cores = os.cpu_count() or 1
    assert all(min(threads, cores) <= n <= threads for _, n in blas), blas


@pytest.mark.parametrize("raw", ["0", "-2", "two", ""])
def test_a_bad_thread_count_is_refused_by_name(raw: str) -> None:
    with pytest.raises(InputError, match=f"RELIGHT_THREADS must be a positive integer.*{raw!r}"):
        CoreSettings.from_env({"RELIGHT_THREADS": raw})


def test_default_is_one_thread() -> None:
    assert CoreSettings.from_env({}).threads == 1
