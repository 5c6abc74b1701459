"""Compiled backend: the loops of :mod:`galerkin_vi.loops` with point functions from
:mod:`galerkin_vi.codegen.compiled`."""

from __future__ import annotations

__all__ = ["available", "numba_version"]


def numba_version() -> str | None:
    """The installed numba version, or None when numba cannot be imported."""
    try:
        import numba
    except Exception:  # noqa: BLE001 - any import failure means "not available"
        return None
    return numba.__version__


def available() -> bool:
    """Whether the compiled backend can be used."""
    return numba_version() is not None
