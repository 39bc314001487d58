"""The numerical core's settings, read once per process from ``RELIGHT_*`` environment variables.

``RELIGHT_THREADS`` (default 1) is the one channel for the core's thread pools: ducc0's transforms get it as
``nthreads`` (:mod:`relight.sh`) and every BLAS library is limited to it, so a process never runs the two pools at
their own defaults side by side. That matters: OpenBLAS starts a second thread from order 64 on and slows ducc0
with it (docs/facts.md, "do not run two thread pools"; 46 ms against 17.5 ms pinned, issue 11; ``bench/blas_threads.py``
measures it on this machine). NumPy's and SciPy's wheels each bundle their own OpenBLAS, loaded at different times
(SciPy's by ``scipy.special``, ``scipy.linalg``, ``scipy.optimize``, ``scipy.spatial``), so the limit is applied
two ways, both from :data:`SETTINGS`:

* :func:`pin_blas_environment` (called when the ``relight`` package is imported) sets ``OPENBLAS_NUM_THREADS``,
  which OpenBLAS reads when it initialises: every BLAS library loaded later in this process, or in a child process
  (the service's Dask workers), starts with the setting. It overwrites a value set by hand: ``RELIGHT_THREADS`` is
  the channel, not a second one next to it.
* :func:`limit_blas_threads` (called when :mod:`relight.sh` loads) limits the libraries loaded *before* relight
  (NumPy imported first) through threadpoolctl.

``RELIGHT_GRAZING_LIMIT`` (default 0.1) is the smallest N.V at which an SHRM's ``epsilon`` must hold
(``relight.shrm.order_search``; issue 18): views closer to grazing are reported, not enforced.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Final

from relight.errors import InputError

#: Environment variable of :attr:`CoreSettings.threads`.
THREADS_VAR: Final = "RELIGHT_THREADS"
#: Environment variable of :attr:`CoreSettings.grazing_limit`.
GRAZING_VAR: Final = "RELIGHT_GRAZING_LIMIT"
#: Default grazing limit: an SHRM's tolerance holds for every view with N.V >= 0.1 (issue 18; about 84 degrees).
DEFAULT_GRAZING_LIMIT: Final = 0.1


@dataclass(frozen=True)
class CoreSettings:
    """What the core reads from the environment (module docstring)."""

    threads: int = 1
    #: ``--epsilon`` holds in every view band with N.V at least this (``relight.shrm.order_search``).
    grazing_limit: float = DEFAULT_GRAZING_LIMIT

    @classmethod
    def from_env(cls, environ: dict[str, str] | None = None) -> CoreSettings:
        env = os.environ if environ is None else environ
        raw = env.get(THREADS_VAR, "1")
        try:
            threads = int(raw)
        except ValueError:
            threads = 0
        if threads < 1:
            raise InputError(f"{THREADS_VAR} must be a positive integer (threads of ducc0 and BLAS), got {raw!r}")
        raw_g = env.get(GRAZING_VAR, str(DEFAULT_GRAZING_LIMIT))
        try:
            grazing = float(raw_g)
        except ValueError:
            grazing = -1.0
        if not 0.0 <= grazing < 1.0:
            raise InputError(f"{GRAZING_VAR} must be a number in [0, 1) (the smallest N.V the tolerance holds for), "
                             f"got {raw_g!r}")
        return cls(threads=threads, grazing_limit=grazing)


#: This process's settings.
SETTINGS: Final = CoreSettings.from_env()


#: What OpenBLAS reads at initialisation (both wheels' builds, ``libscipy_openblas``, read this name).
BLAS_THREADS_VAR: Final = "OPENBLAS_NUM_THREADS"


def pin_blas_environment(threads: int | None = None) -> None:
    """BLAS libraries loaded from now on (here and in child processes) start with ``threads`` (default
    :data:`SETTINGS`'s) threads."""
    os.environ[BLAS_THREADS_VAR] = str(SETTINGS.threads if threads is None else threads)


def limit_blas_threads(threads: int | None = None) -> None:
    """Limit every BLAS library loaded in this process to ``threads`` (default :data:`SETTINGS`'s), and those
    loaded later (:func:`pin_blas_environment`)."""
    from threadpoolctl import threadpool_limits

    n = SETTINGS.threads if threads is None else threads
    pin_blas_environment(n)
    threadpool_limits(limits=n, user_api="blas")
