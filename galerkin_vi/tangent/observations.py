"""Observed trajectories and the parameters to fit: checks shared by the fitting tools.

:func:`check_observations` validates observation times and positions,
:func:`parameter_symbols` turns parameter names or symbols into the system's
symbols, and :class:`FitStatus` says how a fit ended (the package's result
convention, :class:`~galerkin_vi.run.status.SolverResult`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..run.status import SolverStatus

__all__ = ["FitStatus", "check_observations", "parameter_symbols"]


class FitStatus(SolverStatus):
    """How a parameter fit or estimate ended: 0 success, negative a failure."""

    CONVERGED = 0
    MAX_EVALUATIONS = -1
    RUN_FAILED = -2
    NOT_IDENTIFIABLE = -3

    @property
    def cause(self) -> str:
        """The cause in words, for messages."""
        return _CAUSES[self]


_CAUSES = {
    FitStatus.CONVERGED: "the least-squares solve converged",
    FitStatus.MAX_EVALUATIONS: "the least-squares solve reached its maximum number of "
    "evaluations without converging",
    FitStatus.RUN_FAILED: "the integration failed at the starting parameters and initial state",
    FitStatus.NOT_IDENTIFIABLE: "the parameters are not identifiable from these data "
    "(the least-squares Jacobian is rank-deficient)",
}


def check_observations(
    t_obs: ArrayLike, q_obs: ArrayLike, n: int, minimum: int = 2
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Observation times ``(m,)``, strictly increasing, and positions ``(m, n)``, finite.

    ``q_obs`` of shape ``(m,)`` is accepted for ``n == 1``.
    """
    t = np.asarray(t_obs, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"t_obs must be one-dimensional, got shape {t.shape}")
    if t.size < minimum:
        raise ValueError(f"t_obs needs at least {minimum} observation times, got {t.size}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t_obs must be finite")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(
            f"t_obs must be strictly increasing: t_obs[{k + 1}] = {t[k + 1]} "
            f"follows t_obs[{k}] = {t[k]}"
        )
    q = np.asarray(q_obs, dtype=float)
    if q.ndim == 1 and n == 1:
        q = q[:, None]
    if q.shape != (t.size, n):
        raise ValueError(f"q_obs must have shape (len(t_obs), n) = ({t.size}, {n}), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q_obs must be finite")
    return t, q


def parameter_symbols(system, names: Iterable[sp.Symbol | str]) -> tuple[sp.Symbol, ...]:
    """The system's parameter symbols for ``names`` (symbols or their names), in order.

    Raises ValueError for an unknown name, a repeated parameter or an empty list.
    """
    if isinstance(names, (str, sp.Symbol)):
        names = [names]
    by_name = {str(s): s for s in system.params}
    symbols = []
    for name in names:
        key = str(name)
        if key not in by_name or (isinstance(name, sp.Symbol) and name not in system.params):
            raise ValueError(
                f"params: {name!r} is not a parameter of the system; its parameters are "
                f"{[str(s) for s in system.params]}"
            )
        symbols.append(by_name[key])
    if not symbols:
        raise ValueError("params: give at least one parameter to fit")
    if len(set(symbols)) != len(symbols):
        raise ValueError(f"params: a parameter is repeated in {[str(s) for s in symbols]}")
    return tuple(symbols)
