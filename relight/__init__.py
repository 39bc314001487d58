"""relight: frequency-space environment-map prefiltering and Spherical Harmonic Reflection Maps.

Implements Ramamoorthi & Hanrahan, "Frequency Space Environment Map Rendering", SIGGRAPH 2002 ("seed 000").
"""

__version__ = "0.1.0"

#: Bumped whenever a change alters numerical results; part of every cache key.
ALGORITHM_VERSION = "8"

# BLAS libraries loaded from here on use RELIGHT_THREADS threads (relight.settings: one thread setting).
from relight.errors import InputError as _InputError  # noqa: E402

try:
    from relight.settings import pin_blas_environment as _pin_blas
except _InputError:  # a bad RELIGHT_THREADS: reported by name where the core first reads it (relight.sh)
    pass
else:
    _pin_blas()
