"""A system's generated point functions, as an :class:`~galerkin_vi.Integrator` reads them.

The kernel spec (:func:`galerkin_vi.codegen.kernel_spec`) is SymPy work of up to
seconds; the summary the loops need of it is kept with the system's analysis cache and
the compiled functions with its derived data, so every function here takes the spec as
a callable, called only when neither cache holds what is asked for.
"""

from __future__ import annotations

from collections.abc import Callable

from .. import codegen
from ..model.system import LagrangianSystem
from .spec import loop_traits

__all__ = ["point_addresses", "point_functions", "point_source", "spec_summary"]

#: a system's kernel spec, built on first call (cached by the integrator)
SpecOf = Callable[[], codegen.KernelSpec]


def spec_summary(system: LagrangianSystem, spec: SpecOf) -> codegen.SpecSummary:
    """What the loops need of the system's kernel spec, kept with its analysis cache.

    A system seen by an earlier process then derives no spec and hashes no expressions
    (for a 60-mass chain, 0.3 s of SymPy printing). A summary made by another numba or
    another version of the generator is made again.

    Parameters
    ----------
    system : LagrangianSystem
    spec : callable
        Returns the system's :class:`~galerkin_vi.codegen.KernelSpec`.

    Returns
    -------
    SpecSummary
    """
    from ..codegen.compiled import generator_fingerprint, numba_version, point_key

    made_by = (numba_version(), generator_fingerprint())
    stored = system.recalled("point_summary")
    if stored is not None and stored[0] == made_by:
        return stored[1]
    built = spec()
    summary = codegen.summarize(built, point_key(built))
    system.remember("point_summary", (made_by, summary))
    return summary


def point_functions(system: LagrangianSystem, key: str, spec: SpecOf):
    """The system's point functions of cache key ``key`` (the summary's): loaded from the
    disk cache, or generated, once per process and system.

    Returns
    -------
    galerkin_vi.codegen.compiled.PointFunctions
    """
    from ..codegen.compiled import load_point_functions

    return system.derived.get(("points", key), lambda: load_point_functions(spec, key))


def point_source(spec: codegen.KernelSpec) -> str:
    """Source of the point functions of ``spec`` as the NumPy backend would generate it
    (no numba key: the compiled backend reads its cache entry instead)."""
    key = codegen.signature(spec, "source", "")
    return codegen.render_module(spec, key)


def point_addresses(
    backend: str,
    points: Callable[[], object],
    summary: Callable[[], codegen.SpecSummary],
    names: tuple[str, ...],
) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(addresses, traits) of the compiled point functions ``names``, for compiled solvers
    outside the time loops (``Integrator.compiled_point_functions``).

    Parameters
    ----------
    backend : str
        The integrator's resolved backend.
    points, summary : callable
        Return the system's :func:`point_functions` and :func:`spec_summary`; called
        only on the numba backend (they compile or load).
    names : tuple of str
        Point functions to compile; the other slots of
        :mod:`galerkin_vi.loops.point` hold 0 unless compiled before.

    Raises
    ------
    ValueError
        On the NumPy backend.
    """
    if backend != "numba":
        raise ValueError("compiled point functions need the numba backend")
    fn = tuple(int(address) for address in points().addresses(names))
    return fn, loop_traits(summary())
