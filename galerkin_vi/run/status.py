"""How a solve ended: the result convention and the status codes of a run.

Every result (:class:`~galerkin_vi.Trajectory`, ``AdaptiveTrajectory``,
``BoundaryValueResult``, ``PeriodicOrbit``, ``OptimalControl``) is a
:class:`SolverResult`: it has ``status``, a member of a :class:`SolverStatus`
enum, ``message``, the status in words, and ``success``, derived from the
status. The codes follow :func:`scipy.integrate.solve_ivp`: 0 the solve
reached its end, positive it stopped where the user asked (a terminal event),
negative a failure; so ``success == (status >= 0)``. solve_ivp has one failure
code (-1); here each cause has its own, so that a caller can tell a step size
past the stability limit from an interrupted run without parsing the message.
"""

from __future__ import annotations

from enum import IntEnum

from ..loops.abi import STATUS_NEWTON_FAILED, STATUS_NONFINITE, STATUS_OK, STATUS_SINGULAR

__all__ = ["RunStatus", "SolverResult", "SolverStatus", "loop_status"]


class SolverStatus(IntEnum):
    """Base of every status enum: 0 done, > 0 stopped on the user's request, < 0 failed."""


class SolverResult:
    """The convention of every result, as scipy's: ``status``, ``message``, ``success``.

    A subclass (a dataclass) defines the fields ``status`` (a :class:`SolverStatus`
    member) and ``message`` (a non-empty str); ``success`` follows from the status.
    """

    status: SolverStatus
    message: str

    @property
    def success(self) -> bool:
        """True unless the solve failed (``status < 0``); a terminal event is a success."""
        return self.status >= 0


class RunStatus(SolverStatus):
    """Why a run stopped (``Trajectory.status``); ``success`` is ``status >= 0``."""

    COMPLETED = 0
    TERMINATED = 1
    NO_CONVERGENCE = -1
    SINGULAR_JACOBIAN = -2
    NON_FINITE = -3
    UNSTABLE = -4
    INTERRUPTED = -5
    CONTACT_PERSISTS = -6

    @property
    def cause(self) -> str:
        """The cause in words, for messages."""
        return _CAUSES[self]


_CAUSES = {
    RunStatus.COMPLETED: "the run reached its last step",
    RunStatus.TERMINATED: "a terminal event occurred",
    RunStatus.NO_CONVERGENCE: "the iteration of the stage equations did not converge",
    RunStatus.SINGULAR_JACOBIAN: "the Jacobian of the stage equations is singular",
    RunStatus.NON_FINITE: "non-finite values (NaN or inf) appeared",
    RunStatus.UNSTABLE: "the solution grew explosively: the step size is past the "
    "method's stability limit",
    RunStatus.INTERRUPTED: "the run was interrupted (KeyboardInterrupt)",
    RunStatus.CONTACT_PERSISTS: "a contact persists or its impacts accumulate (a body "
    "coming to rest or sliding on it), which isolated impacts cannot continue",
}

# the codes of the compiled loops and the NumPy backends (galerkin_vi.loops.abi)
_LOOP_CODES = {
    STATUS_OK: RunStatus.COMPLETED,
    STATUS_NEWTON_FAILED: RunStatus.NO_CONVERGENCE,
    STATUS_SINGULAR: RunStatus.SINGULAR_JACOBIAN,
    STATUS_NONFINITE: RunStatus.NON_FINITE,
}


def loop_status(code: int) -> RunStatus:
    """The :class:`RunStatus` of a loop's return code."""
    try:
        return _LOOP_CODES[int(code)]
    except KeyError:
        raise ValueError(f"unknown loop status code {code!r}") from None
