"""The checked lengths of a run: step size, number of steps, start time, saving stride.

Every run option that fixes *how far* and *on which grid* a run goes is
resolved here, once, into a frozen :class:`RunPlan`; the run stages below it
(start, loops, events and dense output, trust) read named fields only.
"""

from __future__ import annotations

import math
import numbers
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "RunPlan",
    "all_finite",
    "requested_times",
    "run_plan",
    "state_vector",
    "step_size",
]


class RunPlan(NamedTuple):
    """The grid of a run: ``t_k = t0 + k h`` for ``k = 0 .. n_steps``, every
    ``save_every``-th state saved (and always the last)."""

    h: float
    n_steps: int
    t0: float
    save_every: int

    @property
    def t_end(self) -> float:
        return self.t0 + self.n_steps * self.h


def all_finite(x: NDArray[np.float64]) -> bool:
    """Whether every entry of the 1-D float array ``x`` is finite.

    The sum of squares is finite only when every entry is (a NaN or an inf makes
    it NaN or inf); when it overflows, the entries decide one by one. A third of
    ``np.isfinite(x).all()``'s time on the short vectors every run starts from.
    """
    return math.isfinite(float(np.dot(x, x))) or bool(np.isfinite(x).all())


def state_vector(name: str, x: ArrayLike, n: int) -> NDArray[np.float64]:
    """``x`` as a finite float array of shape (n,); ``name`` in the error otherwise."""
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers, got {x!r}") from exc
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if not all_finite(arr):
        raise ValueError(f"{name} contains NaN or inf: {arr}")
    return arr


def step_size(h: object) -> float:
    """``h`` checked: a finite nonzero real number."""
    if type(h) is not float and (not isinstance(h, numbers.Real) or isinstance(h, bool)):
        raise TypeError(f"h must be a real number, got {h!r}")
    h = float(h)
    if not math.isfinite(h) or h == 0.0:
        raise ValueError(f"h must be finite and nonzero, got {h}")
    return h


def run_plan(h, n_steps, t_span, t0, save_every) -> RunPlan:
    """The :class:`RunPlan` of ``integrate``'s arguments, ``t_span`` resolved.

    With ``t_span = (t0, t1)`` instead of ``n_steps``, the steps are the
    largest equal steps of at most ``|h|`` that land on ``t1``:
    :math:`h \\leftarrow (t_1 - t_0) / \\lceil |t_1 - t_0| / |h| \\rceil`.
    """
    h = step_size(h)
    h, n_steps, t0 = _span_steps(h, n_steps, t_span, t0)
    if not _whole(n_steps) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")
    if not _whole(save_every) or save_every < 1:
        raise ValueError(f"save_every must be a positive int, got {save_every!r}")
    t0 = float(t0)
    if not math.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0}")
    return RunPlan(h=h, n_steps=int(n_steps), t0=t0, save_every=int(save_every))


def _whole(x: object) -> bool:
    """Whether ``x`` is an integer (a NumPy one too), not a bool."""
    return type(x) is int or (isinstance(x, numbers.Integral) and not isinstance(x, bool))


def _span_steps(h: float, n_steps, t_span, t0) -> tuple[float, object, object]:
    if t_span is None:
        if n_steps is None:
            raise ValueError("give n_steps or t_span")
        return h, n_steps, t0
    if n_steps is not None:
        raise ValueError("give n_steps or t_span, not both")
    try:
        start, end = (float(x) for x in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span must be two numbers (t0, t_end), got {t_span!r}") from None
    if not (np.isfinite(start) and np.isfinite(end)) or start == end:
        raise ValueError(f"t_span must be two different finite times, got {t_span!r}")
    if t0 != 0.0 and t0 != start:
        raise ValueError(f"t0 = {t0} and t_span = {t_span!r} disagree: give t_span only")
    if (end - start) * h < 0:
        raise ValueError(f"h = {h} points away from t_span's end ({start} -> {end})")
    steps = int(np.ceil(abs(end - start) / abs(h) * (1 - 4 * np.finfo(float).eps)))
    return (end - start) / steps, steps, start


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
