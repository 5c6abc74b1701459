"""What a failed run does: ``on_failure="warn"`` returns it, ``"raise"`` raises it.

As :func:`scipy.integrate.solve_ivp`, a failed run (a step whose iteration
failed, NaN, explosive growth) returns the states before the failure with a
negative ``status`` and a ``message``, and warns (:class:`RunFailureWarning`);
``on_failure="raise"`` raises :class:`ConvergenceError` with that trajectory
in ``.partial``.
"""

from __future__ import annotations

import warnings

from ..errors import ConvergenceError, RunFailureWarning

__all__ = ["FAILURE_MODES", "check_failure_mode", "failed_run"]

#: what ``integrate(on_failure=...)`` does with a failed run
FAILURE_MODES = ("warn", "raise")


def check_failure_mode(on_failure: object) -> None:
    """Reject an ``on_failure`` that is not one of :data:`FAILURE_MODES`."""
    if on_failure not in FAILURE_MODES:
        raise ValueError(f"on_failure must be one of {FAILURE_MODES}, got {on_failure!r}")


def failed_run(traj, on_failure: str, *, step: int, t: float, residual: float, stacklevel: int = 3):
    """A failed run's trajectory, returned with a warning or raised as ``.partial``.

    ``traj`` carries the failure's ``status`` and ``message`` already.
    """
    if on_failure == "raise":
        raise ConvergenceError(
            f"{traj.message} The trajectory up to the failing step is in .partial.",
            step=step,
            t=t,
            residual=float(residual),
            partial=traj,
        )
    # stacklevel: the user's call (of integrate(), next() of a stream), not the library
    warnings.warn(traj.message, RunFailureWarning, stacklevel=stacklevel)
    return traj
