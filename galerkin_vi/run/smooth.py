"""A run without contacts, stage by stage: plan, start, compiled calls in chunks, trust,
dense output, events, requested times, failure report.

:func:`integrate_smooth` is :meth:`Integrator.integrate` for every model kind
but contacts; the contact driver (:mod:`galerkin_vi.contact.runs`) runs its
smooth pieces through it and cuts steps with :func:`one_step`.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError, RunFailureWarning
from .chunks import run_in_chunks
from .events import apply_events, as_events, event_function, locate_events, terminal_stop
from .failures import check_failure_mode, failed_run
from .outputs import at_times
from .plan import requested_times, run_plan
from .segment import run_once
from .spec import RunSpec, Segment
from .start import initial_state
from .status import RunStatus, loop_status
from .trajectory import Trajectory
from .trust import trusted, warn_if_unstable

__all__ = ["integrate_smooth", "one_step"]


def integrate_smooth(
    spec: RunSpec, q0, v0, p0, *, h, n_steps=None, t0=0.0, params=None, save_every=1,
    project=False, on_failure="warn", dense_output=False, t_span=None, events=None,
    progress=None, t_eval=None, variations=None, stacklevel: int = 4,
) -> Trajectory:  # fmt: skip
    """:meth:`Integrator.integrate` of a system without contacts (its parameters).

    ``variations`` (:class:`~galerkin_vi.run.tangent.VariationRequest`): run with the
    tangent map; ``spec`` is then the general Newton loop's.
    """
    system = spec.system
    check_failure_mode(on_failure)
    plan = run_plan(h, n_steps, t_span, t0, save_every)
    if not isinstance(dense_output, bool):
        raise TypeError(f"dense_output must be True or False, got {dense_output!r}")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress must be True, False or None, got {progress!r}")
    event_list = as_events(events)
    event_functions = [event_function(e, system) for e in event_list]
    times = requested_times(t_eval, plan.t0, plan.t_end, plan.h)
    if variations is not None and times is not None:
        raise ValueError(
            "t_eval cannot be combined with tangent or sensitivity: the tangent map is "
            "the derivative of the step map, defined at the steps; use save_every, or "
            "t_span with a step that lands on the times you need"
        )
    if event_list or times is not None:
        dense_output = True
    if dense_output and plan.save_every != 1:
        what = "events are located" if event_list else "dense_output=True interpolates"
        raise ValueError(
            f"{what} between consecutive steps: it needs save_every=1, got {plan.save_every}"
        )
    prm = system.parameter_vector(params)
    q, p, v = initial_state(spec, q0, v0, p0, plan.t0, prm, project)
    first = Segment(q, p, v, plan.t0, plan.h, plan.n_steps, plan.save_every, prm)

    def restart(q, p, t):
        return initial_state(spec, q, None, p, t, prm)

    run_chunk = lambda segment: run_once(spec, segment)  # noqa: E731
    if variations is not None:
        from .tangent import TangentRunner, initial_sensitivity

        start = None
        if v0 is not None and variations.parameters:
            # the start's momentum depends on the parameters through L_v(q0, v0)
            start = initial_sensitivity(system, variations.parameters, plan.t0, q, v, prm)
        run_chunk = TangentRunner(spec, variations, plan.t0, start)
    traj, result, interrupted = run_in_chunks(
        first, run_chunk, restart, progress,
        terminal_stop(event_list, event_functions, prm),
    )  # fmt: skip
    traj, failure = _reported(traj, result, plan, interrupted)
    traj = trusted(traj, plan.h, failure, lambda row, m: _steps_from(spec, traj, row, plan.h, m))
    if dense_output and len(traj) >= 2:
        traj = replace(traj, sol=traj.dense())
    if event_list:
        traj = _with_events(spec, traj, event_list, event_functions, prm)
        if variations is not None and traj.status == RunStatus.TERMINATED:
            from .tangent import with_event_row

            traj = with_event_row(spec, variations, traj)
    if times is not None and traj.sol is not None:
        traj = at_times(traj, times)
    if traj.status == RunStatus.INTERRUPTED:
        # asked for by the user: returned in either failure mode
        warnings.warn(traj.message, RunFailureWarning, stacklevel=stacklevel - 1)
        return traj
    if not traj.success:
        step = int(round((traj.t[-1] - plan.t0) / plan.h))
        return failed_run(
            traj, on_failure, step=step, t=float(traj.t[-1]), residual=result.last_increment,
            stacklevel=stacklevel,
        )  # fmt: skip
    warn_if_unstable(traj, plan.h, stacklevel=stacklevel)
    return traj


def _reported(traj: Trajectory, result, plan, interrupted: bool):
    """``traj`` with the status and message of an interruption or a failed step, and the
    failure's description (None when the loop completed)."""
    if interrupted:
        message = (
            f"{RunStatus.INTERRUPTED.cause} after step {result.steps} (t = {traj.t[-1]:.6g}); "
            "the states computed so far are kept"
        )
        return replace(traj, status=RunStatus.INTERRUPTED, message=message), None
    if result.status == 0:
        return traj, None
    code = loop_status(result.status)
    t_fail = plan.t0 + result.steps * plan.h
    # the explicit loop has no iteration, hence no increment to report
    increment = result.last_increment
    last = f" (last increment {increment:.3g})" if np.isfinite(increment) else ""
    failure = f"step {result.steps} (t = {t_fail:.6g}, h = {plan.h:.3g}): {code.cause}{last}"
    message = f"{failure}; the states before the failing step are kept. Try a smaller h."
    return replace(traj, status=code, message=message), failure


def _steps_from(spec: RunSpec, traj: Trajectory, row: int, h: float, m: int) -> Trajectory:
    """The m steps from saved row ``row``, every one saved, failures and explosions kept."""
    q0, p0, t0, prm = traj.q[row], traj.p[row], float(traj.t[row]), traj.params
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        q, p, v = initial_state(spec, q0, None, p0, t0, prm)
        return run_once(spec, Segment(q, p, v, t0, h, m, 1, prm))[0]


def one_step(spec: RunSpec, q, p, tau: float, t0: float, prm) -> tuple[NDArray, NDArray]:
    """One step of length ``tau`` from a state a run produced, without argument checks.

    The loop call of :meth:`Integrator.step` (bitwise the same result) at a fraction
    of its Python cost: the exact event secant and the contact cuts take many.
    """
    q0, p0, v0 = initial_state(spec, q, None, p, t0, prm)
    traj, result = run_once(spec, Segment(q0, p0, v0, t0, tau, 1, 1, prm))
    if result.status != 0:
        raise ConvergenceError(
            f"one step of length {tau:.3g} from t = {t0:.6g} failed: "
            f"{loop_status(result.status).cause}",
            step=0, t=t0, residual=float(result.last_increment), partial=traj,
        )  # fmt: skip
    return traj.q[-1].copy(), traj.p[-1].copy()


def _with_events(spec: RunSpec, traj, event_list, functions, prm) -> Trajectory:
    """``traj`` with its events located, cut at the first terminal one."""
    if traj.sol is None:  # fewer than 2 states: no interval to search
        return apply_events(traj, event_list, [])
    system = spec.system
    prm_map = dict(zip(system.params, prm, strict=True))

    def method_step(k: int, tau: float):
        # one step of the method from node k, of length tau (exact event times)
        if tau == 0.0:  # the event at the node itself
            q, p = traj.q[k].copy(), traj.p[k].copy()
        else:
            q, p = one_step(spec, traj.q[k], traj.p[k], tau, float(traj.t[k]), prm)
        v = system.inverse_legendre(q, p, traj.t[k] + tau, prm_map)
        return q, v

    records = locate_events(event_list, functions, traj.sol, prm, method_step)
    return apply_events(traj, event_list, records)
