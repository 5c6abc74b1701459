r"""Events: zeros of :math:`g(t, q, v)` along a run, located on its dense output.

The conventions are :func:`scipy.integrate.solve_ivp`'s: an event function
with ``terminal`` (True, or a count of occurrences) and ``direction`` (> 0
only upward zero crossings, < 0 only downward, 0 both). An event is a
crossing of the sign of :math:`g` between two consecutive nodes; its time is
the root of :math:`g(t, \tilde q(t), \dot{\tilde q}(t))` on the dense output
:math:`\tilde q` (:mod:`galerkin_vi.run.dense`), found to round-off by the Illinois
variant of regula falsi, bracketed, for all crossings at once. The dense output
has the method's order, so the event times do too (measured in the events
how-to). With ``exact=True`` the time is then refined so that one step of the
method itself, from the node before, cut to the event time, lands on
:math:`g = 0` (a secant iteration on the step's length, started at the
interpolant's root): the event state is then a state of the method.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..model.system import LagrangianSystem
from .dense import DenseOutput
from .status import RunStatus

__all__ = ["Event", "EventRecord", "as_events", "locate_events"]

# Illinois iterations are superlinear; 100 bound a bracket's width to round-off
_ROOT_ITERATIONS = 100
_SECANT_ITERATIONS = 12


@dataclass(frozen=True)
class Event:
    r"""An event: the zeros of a scalar :math:`g(t, q, v)`.

    Parameters
    ----------
    expr : sympy.Expr or callable
        A SymPy expression in the system's ``q``, ``v``, time symbol and
        parameters (evaluated for all nodes at once), or a callable
        ``g(t, q, v)`` of a time and two arrays of shape (n,) returning a
        float (called once per node: slower).
    terminal : bool or int
        True stops the run at the first occurrence, an int k at the k-th.
    direction : float
        > 0 only zeros where g increases, < 0 where it decreases, 0 both.
    exact : bool
        Refine the time with steps of the method cut to it (see the module
        docstring); the default keeps the root of the dense output, which has
        the method's order already.
    """

    expr: sp.Expr | Callable
    terminal: bool | int = False
    direction: float = 0.0
    exact: bool = False

    def __post_init__(self) -> None:
        if not (isinstance(self.expr, sp.Expr) or callable(self.expr)):
            raise TypeError(
                f"an event must be a SymPy expression or a callable g(t, q, v), got {self.expr!r}"
            )
        count = self.terminal
        if not isinstance(count, numbers.Integral) or count < 0:
            raise ValueError(f"terminal must be True, False or a count >= 0, got {count!r}")
        if not isinstance(self.direction, numbers.Real) or not np.isfinite(self.direction):
            raise ValueError(f"direction must be a finite number, got {self.direction!r}")

    @property
    def stop_after(self) -> int:
        """Occurrences after which the run stops (0: never)."""
        return int(self.terminal)


@dataclass
class EventRecord:
    """The occurrences of one event: times and states, in the run's order, and the
    interval k (the event lies in (t_k, t_k+1]) of each."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    interval: NDArray[np.int64]

    @classmethod
    def empty(cls, n: int) -> EventRecord:
        return cls(np.zeros(0), np.zeros((0, n)), np.zeros((0, n)), np.zeros(0, dtype=np.int64))


def as_events(events: object) -> list[Event]:
    """``events`` as a list of :class:`Event` (solve_ivp's forms accepted).

    One event or a sequence; each an :class:`Event`, a SymPy expression, or
    a callable with optional ``terminal`` and ``direction`` attributes.
    """
    if events is None:
        return []
    if isinstance(events, (Event, sp.Expr)) or callable(events):
        events = [events]
    if not isinstance(events, Sequence):
        raise TypeError(
            f"events must be an Event, an expression, a callable or a list, got {events!r}"
        )
    out = []
    for e in events:
        if isinstance(e, Event):
            out.append(e)
        elif isinstance(e, sp.Expr):
            out.append(Event(e))
        elif callable(e):
            out.append(
                Event(
                    e,
                    terminal=getattr(e, "terminal", False),
                    direction=getattr(e, "direction", 0.0),
                )
            )
        else:
            raise TypeError(
                f"events[{len(out)}] must be an Event, an expression or a callable, got {e!r}"
            )
    return out


def event_function(event: Event, system: LagrangianSystem) -> Callable:
    """``g(t, q, v, prm)`` for arrays t (m,), q and v (m, n): values (m,)."""
    expr = event.expr
    if isinstance(expr, sp.Expr):
        declared = set(system.q) | set(system.v) | set(system.params) | {system.time_symbol}
        undeclared = expr.free_symbols - declared
        if undeclared:
            names = ", ".join(sorted(map(str, undeclared)))
            raise ValueError(
                f"the event {expr} contains symbols that are not the system's: {names}"
            )
        # lambdify costs milliseconds: kept with the system (a contact run asks often)
        args = [system.time_symbol, *system.q, *system.v, *system.params]
        fn = system.derived.get(("events", expr), lambda: sp.lambdify(args, expr, modules=[np]))

        def values(t, q, v, prm):
            out = fn(t, *q.T, *v.T, *prm)
            return np.broadcast_to(np.asarray(out, dtype=float), t.shape).copy()

        return values

    def called(t, q, v, prm):
        return np.array([float(expr(ti, qi, vi)) for ti, qi, vi in zip(t, q, v, strict=True)])

    return called


def _crossings(g: NDArray, direction: float, from_start: bool = True) -> NDArray:
    """Intervals k whose sign of g changes in ``direction``.

    A zero at a node counts once, in the interval it ends; a zero at the
    run's first node (``from_start``) counts when g then moves in
    ``direction`` (as in solve_ivp, which reports an event at t0 there).
    """
    before, after = g[:-1], g[1:]
    start = np.zeros(before.shape, dtype=bool)
    start[0] = from_start and before[0] == 0.0
    up = ((before < 0) | start) & (after > 0) | (before < 0) & (after == 0)
    down = ((before > 0) | start) & (after < 0) | (before > 0) & (after == 0)
    mask = up if direction > 0 else down if direction < 0 else up | down
    return np.flatnonzero(mask)


def _roots(
    fun: Callable, a: NDArray, b: NDArray, fa: NDArray, fb: NDArray, relative: float = 0.0
) -> NDArray:
    """Roots in the brackets [a, b] (f(a) f(b) <= 0) by Illinois regula falsi, vectorised.

    To round-off, or until a bracket is ``relative`` times its first width (a start for
    the exact secant, which converges from there in one or two method steps).
    """
    first = np.abs(b - a)
    a, b, fa, fb = a.copy(), b.copy(), fa.copy(), fb.copy()
    root = np.where(fb == 0.0, b, np.where(fa == 0.0, a, np.nan))
    live = np.isnan(root)
    side = np.zeros(a.shape, dtype=np.int8)  # which end moved last (Illinois halving)
    for _ in range(_ROOT_ITERATIONS):
        if not live.any():
            break
        idx = np.flatnonzero(live)
        aa, bb, ffa, ffb = a[idx], b[idx], fa[idx], fb[idx]
        x = bb - ffb * (bb - aa) / (ffb - ffa)
        # a point outside or on the bracket's ends (round-off): bisect
        bad = ~((x > np.minimum(aa, bb)) & (x < np.maximum(aa, bb)))
        x[bad] = 0.5 * (aa[bad] + bb[bad])
        fx = fun(x)
        hit = fx == 0.0
        root[idx[hit]] = x[hit]
        same_a = (np.sign(fx) == np.sign(ffa)) & ~hit
        # x replaces the end of its own sign; halve the other end's value if it stays twice
        ia, ib = idx[same_a], idx[~same_a & ~hit]
        a[ia], fa[ia] = x[same_a], fx[same_a]
        fb[ia] = np.where(side[ia] == 1, 0.5 * fb[ia], fb[ia])
        side[ia] = 1
        mb = ~same_a & ~hit
        b[ib], fb[ib] = x[mb], fx[mb]
        fa[ib] = np.where(side[ib] == -1, 0.5 * fa[ib], fa[ib])
        side[ib] = -1
        width = np.abs(b - a)
        tiny = 4 * np.finfo(float).eps * np.maximum(np.abs(a), np.abs(b)) + 1e-300
        done = live & ((width <= tiny) | (width <= relative * first))
        root[done] = np.where(np.abs(fa[done]) < np.abs(fb[done]), a[done], b[done])
        live = np.isnan(root)
    if live.any():  # not reached in practice: the bracket's better end
        root[live] = np.where(np.abs(fa[live]) < np.abs(fb[live]), a[live], b[live])
    return root


def terminal_stop(events: Sequence[Event], functions: Sequence[Callable], prm: NDArray):
    """``stop(chunk) -> bool`` for a chunked run: whether a terminal event has occurred.

    Counts each terminal event's crossings at the nodes of the chunks seen so
    far (each later chunk starts at the previous one's last node); None when
    no event is terminal. The run then stops after the chunk in which the
    count is reached, not at the end of its span.
    """
    terminal = [(e, g) for e, g in zip(events, functions, strict=True) if e.stop_after]
    if not terminal:
        return None
    counts = [0] * len(terminal)
    first = [True]

    def stop(chunk) -> bool:
        if len(chunk) < 2:
            return False
        v = chunk.velocities()
        reached = False
        for i, (event, g) in enumerate(terminal):
            values = g(chunk.t, chunk.q, v, prm)
            counts[i] += _crossings(values, float(event.direction), first[0]).size
            reached |= counts[i] >= event.stop_after
        first[0] = False
        return reached

    return stop


def locate_events(
    events: Sequence[Event],
    functions: Sequence[Callable],
    sol: DenseOutput,
    prm: NDArray,
    exact_step: Callable | None = None,
    from_start: bool = True,
) -> list[EventRecord]:
    """All occurrences of each event along the run of ``sol``.

    ``exact_step(k, tau)`` returns the state (q, v) one method step of length
    ``tau`` after node k; used for the events with ``exact=True``. With
    ``from_start=False`` a zero at the first node is not an event (``sol`` is
    a later segment of a run, whose first node ends the previous one's search).
    """
    t, q, v = sol.t, sol.q, sol.v
    records = []
    for event, g in zip(events, functions, strict=True):
        values = g(t, q, v, prm)
        k = _crossings(values, float(event.direction), from_start)
        if k.size == 0:
            records.append(EventRecord.empty(q.shape[1]))
            continue

        def on_dense(x, g=g):
            qx, vx = sol.state(x)
            return g(x, qx, vx, prm)

        # an exact event's time is refined by the secant: a start to 1e-8 of the step does
        exact = event.exact and exact_step is not None
        roots = _roots(on_dense, t[k], t[k + 1], values[k], values[k + 1], 1e-8 if exact else 0.0)
        qe, ve = sol.state(roots)
        if exact:
            for i, (kk, r) in enumerate(zip(k, roots, strict=True)):
                roots[i], qe[i], ve[i] = _exact_time(g, prm, exact_step, int(kk), t, r)
        records.append(EventRecord(roots, qe, ve, k))
    return records


def _exact_time(g, prm, exact_step, k, t, guess):
    """The event time where one method step from node k, cut to it, lands on g = 0."""
    tk = t[k]

    def residual(tau):
        qx, vx = exact_step(k, tau)
        return float(g(np.array([tk + tau]), qx[None], vx[None], prm)[0]), qx, vx

    x0 = guess - tk
    x1 = x0 * (1.0 + 1e-6) if x0 != 0.0 else 1e-8 * (t[k + 1] - tk)
    f0, q0, v0 = residual(x0)
    if f0 == 0.0:  # the interpolant's root is one of the method's too
        return tk + x0, q0, v0
    f1, q1, v1 = residual(x1)
    for _ in range(_SECANT_ITERATIONS):
        if f1 == f0 or f1 == 0.0:
            break
        x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
        x0, f0 = x1, f1
        x1 = x2
        f1, q1, v1 = residual(x1)
        if abs(x1 - x0) <= 4 * np.finfo(float).eps * max(abs(tk), abs(tk + x1), 1e-300):
            break
    return tk + x1, q1, v1


def apply_events(traj, events: Sequence[Event], records: Sequence[EventRecord]):
    """``traj`` with ``t_events`` ... ``p_events`` set, cut at the first terminal event.

    A terminal event with count c stops the run at its c-th occurrence: the
    states after it are dropped, the event's state becomes the last row, and
    ``status`` is 1. Occurrences of other events after it are dropped too.
    """
    system = traj.system
    n = traj.q.shape[1]
    if not records:
        records = [EventRecord.empty(n) for _ in events]
    forward = len(traj.t) < 2 or traj.t[-1] >= traj.t[0]
    stop, which = None, None
    for j, (event, rec) in enumerate(zip(events, records, strict=True)):
        c = event.stop_after
        if c and rec.t.size >= c:
            t_stop = rec.t[c - 1]
            if stop is None or (t_stop < stop if forward else t_stop > stop):
                stop, which = t_stop, j
    prm = dict(zip(system.params, traj.params, strict=True))
    kept = []
    for rec in records:
        keep = slice(None)
        if stop is not None:
            before = rec.t <= stop if forward else rec.t >= stop
            keep = before
        kept.append((rec.t[keep], rec.q[keep], rec.v[keep]))
    p_events = [system.legendre(q, v, t, prm) if t.size else np.zeros((0, n)) for t, q, v in kept]
    traj = replace(
        traj,
        t_events=[t for t, _, _ in kept],
        q_events=[q for _, q, _ in kept],
        v_events=[v for _, _, v in kept],
        p_events=p_events,
    )
    if stop is None:
        return traj
    rec = records[which]
    i = events[which].stop_after - 1
    k = int(rec.interval[i])  # the event lies in (t_k, t_k+1]
    q_e, v_e = rec.q[i], rec.v[i]
    p_e = system.legendre(q_e, v_e, stop, prm)
    t = np.append(traj.t[: k + 1], stop)
    q = np.vstack([traj.q[: k + 1], q_e])
    p = np.vstack([traj.p[: k + 1], p_e])
    sol = traj.sol
    if sol is not None:
        v = np.vstack([sol.v[: k + 1], v_e])
        sol = replace(sol, t=t, q=q, v=v)
    message = (
        f"terminal event {which} at t = {stop:.9g} (occurrence {i + 1}); the run's "
        f"states after it are dropped"
    )
    return replace(
        traj,
        t=t,
        q=q,
        p=p,
        q_reduced=None,
        sol=sol,
        status=RunStatus.TERMINATED,
        message=message,
    )
