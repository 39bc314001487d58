"""relight: frequency-space environment-map prefiltering and Spherical Harmonic Reflection Maps.

Implements Ramamoorthi & Hanrahan, "Frequency Space Environment Map Rendering", SIGGRAPH 2002 ("seed 000").
"""

__version__ = "0.1.0"

#: Bumped whenever a change alters numerical results; part of every cache key.
ALGORITHM_VERSION = "1"
