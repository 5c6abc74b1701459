"""The physical-time side of an adaptive run: its arguments checked, and what it returns
besides its states (dense output, events, rows at ``t_eval``) mapped between the
fictitious time :math:`\tau` and the physical time :math:`t`."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..run.dense import hermite
from ..run.events import Event, as_events, event_function
from ..run.outputs import at_times
from ..run.plan import requested_times

__all__ = [
    "OutputRequest",
    "fictitious_step",
    "fictitious_times",
    "intervals",
    "physical_span",
    "rows_at",
    "save_interval",
]


# ---------------------------------------------------------------- run arguments and outputs
def fictitious_step(h: object) -> float:
    """``h`` checked: a finite nonzero real number (negative runs backwards)."""
    if isinstance(h, bool) or not (isinstance(h, numbers.Real) and math.isfinite(h) and h != 0):
        raise ValueError(f"h must be a finite, nonzero fictitious step, got {h!r}")
    return float(h)


def save_interval(save_every: object) -> int:
    if isinstance(save_every, bool) or not isinstance(save_every, numbers.Integral):
        raise ValueError(f"save_every must be a positive int, got {save_every!r}")
    if save_every < 1:
        raise ValueError(f"save_every must be a positive int, got {save_every!r}")
    return int(save_every)


def physical_span(t_span, t0, t_final, n_steps, h: float) -> tuple[float, float | None]:
    """(t0, t_final) of a run, ``t_span`` resolved and checked against the direction of h."""
    if t_span is not None:
        if t_final is not None or n_steps is not None:
            raise ValueError("give t_span, or one of n_steps and t_final, not both")
        try:
            start, end = (float(x) for x in t_span)
        except (TypeError, ValueError):
            raise ValueError(f"t_span must be two numbers (t0, t_final), got {t_span!r}") from None
        if t0 != 0.0 and t0 != start:
            raise ValueError(f"t0 = {t0} and t_span = {t_span!r} disagree: give t_span only")
        t0, t_final = start, end
    if (n_steps is None) == (t_final is None):
        raise ValueError("give exactly one of n_steps and t_final (or t_span)")
    if not (isinstance(t0, numbers.Real) and math.isfinite(t0)):
        raise ValueError(f"t0 must be a finite real number, got {t0!r}")
    if t_final is None:
        return float(t0), None
    if not (isinstance(t_final, numbers.Real) and math.isfinite(t_final)):
        raise ValueError(f"t_final must be a finite real number, got {t_final!r}")
    if h > 0 and t_final <= t0:
        raise ValueError(
            f"t_final must be after t0 = {t0} for h > 0 (physical time runs with the "
            f"fictitious one), got {t_final!r}; a negative h runs backwards"
        )
    if h < 0 and t_final >= t0:
        raise ValueError(
            f"t_final must be before t0 = {t0} for h < 0 (the run goes backwards in "
            f"physical time), got {t_final!r}"
        )
    return float(t0), float(t_final)


@dataclass(frozen=True)
class OutputRequest:
    """What a run returns besides its states: dense output, events, rows at ``t_eval``."""

    dense: bool
    events: list[Event]
    functions: list[Callable]
    times: NDArray[np.float64] | None
    t_final: float | None
    h: float

    @classmethod
    def of(cls, system, dense_output, events, t_eval, t0, t_final, h) -> OutputRequest:
        if not isinstance(dense_output, bool):
            raise TypeError(f"dense_output must be True or False, got {dense_output!r}")
        event_list = as_events(events)
        functions = [event_function(e, system) for e in event_list]
        times = requested_times(t_eval, t0, t_final, h)
        dense = dense_output or bool(event_list) or times is not None
        return cls(dense, event_list, functions, times, t_final, h)


def intervals(t: NDArray, times: NDArray) -> NDArray[np.int64]:
    """The interval k of the run's nodes ``t`` (forwards or backwards) holding each time:
    ``times`` between ``t[k]`` and ``t[k + 1]``."""
    forward = t[-1] >= t[0]
    nodes = t if forward else t[::-1]
    k = np.clip(np.searchsorted(nodes, times, side="right") - 1, 0, len(t) - 2)
    return k if forward else len(t) - 2 - k


def fictitious_times(t: NDArray, tau: NDArray, rates: NDArray, times: NDArray) -> NDArray:
    r""":math:`\tau` at physical ``times``: cubic Hermite in the interval of each, through
    :math:`(t_k, \tau_k)` with slopes :math:`d\tau/dt = 1/g(q_k)`."""
    pair = intervals(t, times)[:, None] + np.arange(2)
    value, _ = hermite(t[pair], tau[pair][..., None], (1.0 / rates)[pair][..., None], times)
    return value[:, 0]


def rows_at(traj, full, times: NDArray, rates: NDArray):
    """``traj`` at ``times`` from ``full``'s dense output (``tau`` interpolated too)."""
    rows = at_times(traj, times)
    tau = fictitious_times(full.t, full.tau, rates, rows.t)
    # p_z is constant to round-off: the value at the interval's first node
    momentum = full.clock_momentum[intervals(full.t, rows.t)]
    return replace(rows, tau=tau, clock_momentum=momentum)
