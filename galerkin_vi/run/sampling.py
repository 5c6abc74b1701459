"""Requested output times (``t_eval``): checked, and the rows of a run sampled there."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["at_times", "requested_times"]


def requested_times(t_eval: ArrayLike | None, t0: float, h: float, n_steps: int) -> NDArray | None:
    """``t_eval`` checked: finite, in the span, monotone in the run's direction.

    Parameters
    ----------
    t_eval : array_like or None
        The requested times.
    t0, h, n_steps : float, float, int
        The run's start, step (negative backwards) and number of steps: its span is
        :math:`[t_0, t_0 + N h]` (or the reverse).

    Returns
    -------
    ndarray or None
        The times, clipped to the span (round-off outside it is accepted).
    """
    if t_eval is None:
        return None
    times = np.atleast_1d(np.asarray(t_eval, dtype=float))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise ValueError("t_eval must be a 1-d array of finite times")
    end = t0 + n_steps * h
    lo, hi = min(t0, end), max(t0, end)
    tiny = 8 * np.finfo(float).eps * max(1.0, abs(lo), abs(hi))
    if times.size and (times.min() < lo - tiny or times.max() > hi + tiny):
        raise ValueError(f"t_eval must lie in the run's span [{lo}, {hi}]")
    if np.any(np.diff(times) * h < 0):
        raise ValueError("t_eval must be sorted in the direction of integration")
    return np.clip(times, lo, hi)


def at_times(traj, times: NDArray):
    """``traj`` with rows at ``times`` from its dense output (a run cut short: those reached).

    ``traj.sol`` is anything with ``t_min``, ``t_max``, ``__call__`` and ``momentum``
    (:class:`~galerkin_vi.run.dense.DenseOutput`,
    :class:`~galerkin_vi.run.piecewise.PiecewiseDenseOutput`).
    """
    sol = traj.sol
    reached = times[(times >= sol.t_min) & (times <= sol.t_max)]
    return replace(traj, t=reached, q=sol(reached), p=sol.momentum(reached), q_reduced=None)
