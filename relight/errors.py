"""Exceptions raised by the numerical core.

``InputError`` is the one exception for bad user input (files, parameters, specs): its message is a single
clear line that the CLI prints and the service returns as a problem description.
"""

from __future__ import annotations


class RelightError(Exception):
    """Base class of every error the core raises on purpose."""


class InputError(RelightError, ValueError):
    """Invalid input: a file that cannot be decoded, a wrong shape, an out-of-range parameter."""
