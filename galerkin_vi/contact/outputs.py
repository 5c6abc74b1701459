r"""The run options of a system with contacts: saved rows, dense output, events, ``t_eval``.

A run with impacts keeps every row it computes: the grid rows
:math:`t_k = t_0 + k h` and, for each impact, two rows at its time (the state
arriving at it, then the state leaving it). The options act on these rows
after the run, on each **smooth segment** between impacts
(:func:`galerkin_vi.run.piecewise.smooth_segments`), never across one:

- ``save_every=k`` keeps the grid rows whose step index is a multiple of k
  and the last row (:func:`saved_every`); the impacts stay in ``traj.impacts``;
- ``dense_output`` is a :class:`~galerkin_vi.run.piecewise.PiecewiseDenseOutput`,
  right-continuous at the impacts;
- events are located on each segment (:func:`with_events`), so that an event
  and an impact in one step come in their time order; a terminal event cuts
  the run there, and the impacts after it are dropped;
- ``t_eval`` samples the dense output.

Terminal events are also watched while the run goes (:class:`Watch`, after
each smooth piece), so that the run stops soon after one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..run.chunks import ProgressBar
from ..run.dense import DenseOutput, stencil_nodes
from ..run.events import (
    Event,
    EventRecord,
    apply_events,
    as_events,
    event_function,
    locate_events,
    terminal_stop,
)
from ..run.outputs import at_times
from ..run.piecewise import PiecewiseDenseOutput, smooth_segments
from ..run.plan import requested_times
from ..run.status import RunStatus

__all__ = ["RunOptions", "Watch", "finish", "run_options", "saved_every", "with_events"]


@dataclass(frozen=True)
class RunOptions:
    """The checked output options of one run with contacts."""

    save_every: int
    dense_output: bool
    events: list[Event]
    functions: list[Callable]
    times: NDArray[np.float64] | None
    progress: bool | None

    @property
    def terminal(self) -> bool:
        """Whether an event may end the run."""
        return any(e.stop_after for e in self.events)


def run_options(system, h, n_steps, t0, save_every, dense_output, events, t_eval, progress):
    """:class:`RunOptions` from ``integrate``'s arguments, checked as a smooth run checks them."""
    if not isinstance(dense_output, bool):
        raise TypeError(f"dense_output must be True or False, got {dense_output!r}")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress must be True, False or None, got {progress!r}")
    event_list = as_events(events)
    functions = [event_function(e, system) for e in event_list]
    times = requested_times(t_eval, t0, t0 + n_steps * h, h)
    dense_output = dense_output or bool(event_list) or times is not None
    if dense_output and save_every != 1:
        what = "events are located" if event_list else "dense_output=True interpolates"
        raise ValueError(
            f"{what} between consecutive steps: it needs save_every=1, got {save_every}"
        )
    return RunOptions(save_every, dense_output, event_list, functions, times, progress)


@dataclass(frozen=True)
class _Nodes:
    """One smooth segment's nodes, as :func:`~galerkin_vi.run.events.terminal_stop` reads them."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.t)

    def velocities(self) -> NDArray[np.float64]:
        return self.v


class Watch:
    """Terminal events and the progress bar, looked at after each piece of a run.

    Parameters
    ----------
    options : RunOptions
    system, prm
        The run's system and parameter vector.
    n_steps : int
        The run's steps (the progress bar's total).
    """

    def __init__(self, options: RunOptions, system, prm, n_steps: int) -> None:
        self.system, self.prm, self.n_steps = system, prm, n_steps
        self.params = dict(zip(system.params, prm, strict=True))
        self.stop = terminal_stop(options.events, options.functions, prm)
        self.bar = ProgressBar(options.progress, n_steps)

    @property
    def terminal(self) -> bool:
        """Whether an event may end the run (else only the progress bar is watched)."""
        return self.stop is not None

    def seen(self, t, q, p, k: int) -> bool:
        """Rows ``(t, q, p)`` added (the first one seen before): whether a terminal event
        has occurred in them; updates the progress bar to grid step k."""
        self.bar.update(k)
        if self.stop is None or len(t) < 2:
            return False
        for rows in smooth_segments(t):
            if rows.stop - rows.start < 2:
                continue
            tt, qq = t[rows], q[rows]
            v = self.system.inverse_legendre(qq, p[rows], tt, self.params)
            if self.stop(_Nodes(tt, qq, v)):
                return True
        return False

    def close(self) -> None:
        self.bar.close()


def saved_every(traj, grid: NDArray[np.bool_], t0: float, h: float, k: int):
    r"""``traj`` with the grid rows of step index a multiple of k, and its last row.

    A row is a grid row when the run reached it at a grid time
    :math:`t_0 + i h` by a step (an impact's two rows are not, except the
    state leaving an impact that falls on a grid time: the run's state there);
    it is kept when :math:`i \equiv 0 \pmod k`. The rows kept are those of the
    ``save_every=1`` run, bit for bit.
    """
    if k == 1:
        return traj
    index = np.round((traj.t - t0) / h).astype(np.int64)
    keep = grid & (index % k == 0)
    keep[-1] = True
    return replace(
        traj,
        t=traj.t[keep],
        q=traj.q[keep],
        p=traj.p[keep],
        q_reduced=None if traj.q_reduced is None else traj.q_reduced[keep],
        variations=None if traj.variations is None else traj.variations.rows(keep),
    )


def with_events(traj, events: list[Event], functions: list[Callable], one_step: Callable):
    """``traj`` with its events located on each smooth segment, cut at a terminal one.

    ``one_step(q, p, tau, t) -> (q, p)`` is a step of the method (for ``exact`` events).
    A terminal event also drops the impacts and contact forces from its time on.
    """
    system, prm = traj.system, traj.params
    params = dict(zip(system.params, prm, strict=True))
    n = traj.q.shape[1]
    found: list[list[EventRecord]] = [[] for _ in events]
    if len(traj) >= 2:
        v = traj.velocities()
        stencil = stencil_nodes(traj.order or 2)
        for rows in smooth_segments(traj.t):
            if rows.stop - rows.start < 2:
                continue
            sol = DenseOutput(
                t=traj.t[rows], q=traj.q[rows], v=v[rows], stencil=stencil, system=system,
                params=prm,
            )  # fmt: skip
            step = _segment_step(traj, rows.start, one_step, params)
            records = locate_events(events, functions, sol, prm, step, rows.start == 0)
            for i, rec in enumerate(records):
                found[i].append(replace(rec, interval=rec.interval + rows.start))
    merged = [_merged(parts, n) for parts in found]
    cut = apply_events(replace(traj, sol=None), events, merged)
    if cut.status != RunStatus.TERMINATED:
        return cut
    return _without_after(cut, float(cut.t[-1]))


def _segment_step(traj, first: int, one_step: Callable, params) -> Callable:
    """``method_step(k, tau) -> (q, v)`` from row ``first + k`` of ``traj``."""
    system = traj.system

    def method_step(k: int, tau: float):
        row = first + k
        t = float(traj.t[row])
        if tau == 0.0:  # the event at the node itself
            q, p = traj.q[row].copy(), traj.p[row].copy()
        else:
            q, p = one_step(traj.q[row], traj.p[row], tau, t)
        return q, system.inverse_legendre(q, p, t + tau, params)

    return method_step


def _merged(parts: list[EventRecord], n: int) -> EventRecord:
    if not parts:
        return EventRecord.empty(n)
    return EventRecord(
        t=np.concatenate([r.t for r in parts]),
        q=np.concatenate([r.q for r in parts]),
        v=np.concatenate([r.v for r in parts]),
        interval=np.concatenate([r.interval for r in parts]),
    )


def _without_after(traj, stop: float):
    """``traj`` without the impacts and contact forces from ``stop`` on (run's direction)."""
    sign = 1.0 if len(traj) < 2 or traj.t[-1] >= traj.t[0] else -1.0
    impacts = traj.impacts
    if impacts is not None:
        impacts = [i for i in impacts if (i.t - stop) * sign < 0.0]
    forces = traj.contact_forces
    if forces is not None:
        keep = (forces.t - stop) * sign < 0.0
        forces = replace(
            forces,
            t=forces.t[keep],
            normal=forces.normal[keep],
            tangential=forces.tangential[keep],
            iterations=forces.iterations[keep],
            complementarity=forces.complementarity[keep],
        )
    return replace(traj, impacts=impacts, contact_forces=forces)


def finish(traj, options: RunOptions, grid: NDArray[np.bool_], t0: float, h: float,
           one_step: Callable, event_row: Callable | None = None):  # fmt: skip
    """``traj`` with the options applied: events, dense output, ``t_eval``, ``save_every``.

    ``event_row(traj)`` gives the variations of the row of a terminal event (runs with
    the tangent map).
    """
    if options.events:
        traj = with_events(traj, options.events, options.functions, one_step)
        if event_row is not None and traj.status == RunStatus.TERMINATED:
            traj = event_row(traj)
    if options.dense_output and len(traj) >= 2:
        sol = PiecewiseDenseOutput.from_rows(
            traj.t, traj.q, traj.velocities(), stencil_nodes(traj.order or 2), traj.system,
            traj.params,
        )  # fmt: skip
        traj = replace(traj, sol=sol)
    if options.times is not None and traj.sol is not None:
        traj = at_times(traj, options.times)
    return saved_every(traj, grid, t0, h, options.save_every)
