"""Exceptions and warnings raised by galerkin_vi."""

from __future__ import annotations

from typing import Any

__all__ = [
    "ConditioningWarning",
    "ConvergenceError",
    "DegenerateLagrangianError",
    "InstabilityWarning",
    "OrderReductionWarning",
    "RunFailureWarning",
]


class DegenerateLagrangianError(ValueError):
    r"""The Hessian :math:`\partial^2 L / \partial v^2` is singular where it must be inverted.

    A Galerkin variational integrator needs a regular Lagrangian: the Legendre
    transform :math:`p = \partial L/\partial v` must be invertible for the
    momentum-matching equations to have a unique solution.
    """


class ConvergenceError(RuntimeError):
    """The Newton solve of a step's stage equations failed.

    Everything computed before the failing step is kept.

    Attributes
    ----------
    step : int
        Index ``k`` of the step ``t_k -> t_{k+1}`` that failed.
    t : float
        Time ``t_k`` at the start of the failing step.
    residual : float
        Max-norm of the last Newton increment or residual seen.
    partial : Trajectory or None
        The saved states before the failing step plus the last good state
        :math:`(t_k, q_k, p_k)`, whether or not it was due for saving.
    """

    def __init__(
        self,
        message: str,
        *,
        step: int,
        t: float,
        residual: float,
        partial: Any = None,  # a Trajectory: errors import nothing of the package
        **extra: Any,
    ) -> None:
        super().__init__(message)
        self.step = step
        self.t = t
        self.residual = residual
        self.partial = partial
        self.extra = extra


class RunFailureWarning(RuntimeWarning):
    """A run failed and returned the states before the failing step.

    The trajectory says why (``status``, ``message``); pass
    ``on_failure="raise"`` to get :class:`ConvergenceError` instead.
    """


class OrderReductionWarning(UserWarning):
    """The quadrature order is below ``2 * degree``: the method loses order."""


class ConditioningWarning(UserWarning):
    """A choice that is known to make the stage equations ill-conditioned."""


class InstabilityWarning(RuntimeWarning):
    r"""The momenta grew by orders of magnitude during a run.

    The usual cause is a step size past the method's linear stability limit
    (for Störmer–Verlet :math:`h\omega < 2`), where the discrete solution
    grows exponentially. Runs that overflow raise :class:`ConvergenceError`
    instead; NaN is never returned silently.
    """
