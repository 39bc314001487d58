"""The numerical core's settings, read once per process from ``RELIGHT_*`` environment variables.

``RELIGHT_THREADS`` (default 1) is the one channel for the core's thread pools: ducc0's transforms get it as
``nthreads`` (:mod:`relight.sh`) and BLAS (OpenBLAS under NumPy) is limited to it through threadpoolctl when
:mod:`relight.sh` loads, so a process never runs the two pools at their own defaults side by side. That matters:
OpenBLAS starts a second thread from order 64 on and slows ducc0 with it (docs/facts.md, "do not run two thread
pools"; 46 ms against 17.5 ms pinned, issue 11). The service's Dask worker processes inherit the server's
environment, so they read the same value. A BLAS library loaded after :mod:`relight.sh` (SciPy's own OpenBLAS,
with ``scipy.linalg``) is limited by calling :func:`limit_blas_threads` again.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Final

from relight.errors import InputError

#: Environment variable of :attr:`CoreSettings.threads`.
THREADS_VAR: Final = "RELIGHT_THREADS"


@dataclass(frozen=True)
class CoreSettings:
    """What the core reads from the environment (module docstring)."""

    threads: int = 1

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
        return cls(threads=threads)


#: This process's settings.
SETTINGS: Final = CoreSettings.from_env()


def limit_blas_threads(threads: int | None = None) -> None:
    """Limit every BLAS library loaded in this process to ``threads`` (default :data:`SETTINGS`'s)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=SETTINGS.threads if threads is None else threads, user_api="blas")
