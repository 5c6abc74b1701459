"""Compiled backend: the loops of :mod:`galerkin_vi.loops` with point functions from
:mod:`galerkin_vi.codegen.compiled`."""

from __future__ import annotations

from ..codegen.compiled import numba_version

__all__ = ["available", "numba_version"]


def available() -> bool:
    """Whether the compiled backend can be used."""
    return numba_version() is not None
