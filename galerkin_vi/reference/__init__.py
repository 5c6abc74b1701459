"""Backends that run the time loop: ``"numba"`` (compiled) and ``"numpy"`` (reference)."""

from __future__ import annotations

import warnings

from . import numba as numba_backend

__all__ = ["BACKENDS", "resolve_backend"]

BACKENDS = ("auto", "numba", "numpy")


def resolve_backend(name: str) -> str:
    """Map a backend name to ``"numba"`` or ``"numpy"``.

    ``"auto"`` picks numba when it imports and falls back to NumPy with a
    warning otherwise; asking for ``"numba"`` explicitly when it is missing is
    an error.
    """
    if name not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {name!r}")
    if name == "numpy":
        return "numpy"
    if numba_backend.available():
        return "numba"
    if name == "numba":
        raise ImportError("backend='numba' requested but numba cannot be imported")
    warnings.warn(
        "numba is not available: falling back to the (slow) NumPy backend",
        RuntimeWarning,
        stacklevel=3,
    )
    return "numpy"
