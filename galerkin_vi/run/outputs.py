"""Rows of a run at requested times (``t_eval``), from its dense output.

Shared by every run driver (fixed steps, adaptive steps): the requested times
are checked against the run's span and direction once, and the rows are the
dense output's positions and the momenta of its velocities there.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .trajectory import Trajectory

__all__ = ["at_times", "requested_times"]


def requested_times(
    t_eval: ArrayLike | None, start: float, end: float | None, direction: float
) -> NDArray[np.float64] | None:
    """``t_eval`` checked: finite, in the span between ``start`` and ``end``, monotone.

    Parameters
    ----------
    t_eval : array_like or None
        The requested times (None: no request, None returned).
    start, end : float
        The run's first and last time (in either order). ``end`` None: not known
        before the run (an adaptive run of a number of steps); only the side of
        ``start`` the times lie on is checked then.
    direction : float
        The sign of the run's direction in time (> 0 forwards, < 0 backwards):
        ``t_eval`` must be sorted that way.

    Returns
    -------
    ndarray or None
        The times, clipped onto the span (a request a few ulps outside it is
        the end itself).
    """
    if t_eval is None:
        return None
    times = np.atleast_1d(np.asarray(t_eval, dtype=float))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise ValueError("t_eval must be a 1-d array of finite times")
    if end is None:
        tiny = 8 * np.finfo(float).eps * max(1.0, abs(start))
        if times.size and np.any((times - start) * direction < -tiny):
            raise ValueError(f"t_eval must lie in the direction of integration from {start}")
        if np.any(np.diff(times) * direction < 0):
            raise ValueError("t_eval must be sorted in the direction of integration")
        return np.maximum(times, start) if direction > 0 else np.minimum(times, start)
    lo, hi = min(start, end), max(start, end)
    tiny = 8 * np.finfo(float).eps * max(1.0, abs(lo), abs(hi))
    if times.size and (times.min() < lo - tiny or times.max() > hi + tiny):
        raise ValueError(f"t_eval must lie in the run's span [{lo}, {hi}]")
    if np.any(np.diff(times) * direction < 0):
        raise ValueError("t_eval must be sorted in the direction of integration")
    return np.clip(times, lo, hi)


def at_times(traj: Trajectory, times: NDArray[np.float64]) -> Trajectory:
    """``traj`` with rows at ``times`` from its dense output (a run cut short: those reached).

    ``traj.sol`` must be set; it keeps every step of the run.
    """
    sol = traj.sol
    reached = times[(times >= sol.t_min) & (times <= sol.t_max)]
    return replace(traj, t=reached, q=sol(reached), p=sol.momentum(reached), q_reduced=None)
