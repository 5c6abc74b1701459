"""The settings of an :class:`~galerkin_vi.Integrator`, checked and normalised.

Each function raises the error ``Integrator(...)`` reports for a bad value and returns
the value the integrator stores. The backend is resolved by
:func:`galerkin_vi.reference.resolve_backend` in the constructor itself: its warning
names the caller's line (``stacklevel``).
"""

from __future__ import annotations

import numbers

from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from .loop_choice import hand_over

__all__ = [
    "SPECIALIZE_VALUES",
    "check_fixed_point",
    "check_galerkin",
    "check_iteration",
    "integrator_method",
    "resolve_specialize",
]

#: the values of ``Integrator(specialize=...)`` (see :func:`resolve_specialize`)
SPECIALIZE_VALUES = ("auto", True, False, "system")


def integrator_method(system: object, method: object) -> Galerkin | Composition:
    """The method of ``Integrator(system, method)``: ``Galerkin(2)`` when None.

    Raises
    ------
    TypeError
        If ``system`` is not a :class:`LagrangianSystem`, or ``method`` not a
        :class:`Galerkin` or :class:`Composition`.
    """
    if not isinstance(system, LagrangianSystem):
        raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    method = Galerkin(2) if method is None else method
    if not isinstance(method, (Galerkin, Composition)):
        raise TypeError(
            f"method must be a Galerkin or Composition method, got {type(method).__name__}"
        )
    return method


def check_iteration(tol: object, maxiter: object) -> tuple[float, int]:
    """``(tol, maxiter)`` of the stage iteration, as float and int.

    ``maxiter`` is at most 255: the runs save each step's iteration count in a byte.

    Raises
    ------
    ValueError
        If ``tol`` is not a real number in (0, 1), or ``maxiter`` not an int
        (bool excluded) in [1, 255].
    """
    if not (isinstance(tol, numbers.Real) and 0 < tol < 1):
        raise ValueError(f"tol must be a real number in (0, 1), got {tol!r}")
    if (
        isinstance(maxiter, bool)
        or not isinstance(maxiter, numbers.Integral)
        or not 1 <= maxiter <= 255
    ):
        raise ValueError(f"maxiter must be an int in [1, 255], got {maxiter!r}")
    return float(tol), int(maxiter)


def check_galerkin(system: LagrangianSystem, method: Galerkin) -> None:
    """Whether a Galerkin ``method`` can run ``system``: a constrained system needs
    collocated control and quadrature nodes.

    Raises
    ------
    ValueError
        If ``system`` has constraints and ``method`` is not collocated (the constraints
        are imposed at the control points, which must then be quadrature points).
    """
    if system.m and not method.collocated:
        raise ValueError(
            f"{method!r}: a constrained system needs collocated control and quadrature "
            "nodes, the constraints being imposed at the control points: use "
            f"Galerkin({method.degree}) (Lobatto nodes, gauss_lobatto({method.degree + 1}))"
        )


def resolve_specialize(specialize: object) -> bool | str:
    """The stored value of ``Integrator(specialize=...)``: ``"auto"``, ``"system"``, or a bool.

    The one place the parameter is read from the user; the loops' choice reads the
    stored value (:func:`galerkin_vi.run.loop_choice.loop_path`,
    :func:`galerkin_vi.run.spec.compiled_run_spec`). Values equal to True or False
    (1, 0, NumPy bools) are stored as bools.

    Raises
    ------
    ValueError
        If ``specialize`` is not one of :data:`SPECIALIZE_VALUES`.
    """
    if isinstance(specialize, str):
        if specialize not in ("auto", "system"):
            raise ValueError(
                f'specialize must be "auto", True, False or "system", got {specialize!r}'
            )
        return specialize
    if specialize not in (True, False):
        raise ValueError(f'specialize must be "auto", True, False or "system", got {specialize!r}')
    return bool(specialize)


def check_fixed_point(fixed_point: bool | str) -> bool | str:
    """``fixed_point`` as given, once :func:`~galerkin_vi.run.loop_choice.hand_over`
    accepts it (the rule itself is derived with the run spec, where the system's
    closed-form sweep is known).

    Raises
    ------
    ValueError
        If ``fixed_point`` is not True, False or ``"persistent"``.
    """
    hand_over(fixed_point)
    return fixed_point
