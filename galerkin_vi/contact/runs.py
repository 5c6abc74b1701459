r"""Runs of a system with contacts: isolated impacts and persistent contact, switched between.

**Isolated impacts.** Between impacts the run is the ordinary Galerkin
integration on the grid :math:`t_k = t_0 + k h`. When the gap of a contact
closes during step k, the step is cut where it closes, as in the variational
collision integrators of Fetecau, Marsden, Ortiz and West (2003): a step of
the same discrete Lagrangian of length :math:`\alpha h` from :math:`(q_k, p_k)`
whose end lies on :math:`\varphi = 0`, with :math:`\alpha` the unknown (a secant
iteration started at the root of the dense output, :mod:`galerkin_vi.run.events`
with ``exact=True``). There the impact law (:mod:`.impact`) maps :math:`p^-` to
:math:`p^+`, and a second step of length :math:`(1 - \alpha) h` lands back on
:math:`t_{k+1}` (cut again if another impact falls inside it). The grid never
shifts, the impact time has the method's nodal accuracy, and so, with finitely
many impacts, has the whole run: its order is the method's (measured in the
tests and the contact how-to). With e = 1 and no friction the impact keeps
:math:`H(q, p)`.

**Persistent contact.** Isolated impacts cannot continue a contact that
persists: a body coming to rest on the floor (impacts accumulating, infinitely
many before the Zeno time), one pressed against it after a plastic impact, or
sliding. ``contact_mode="auto"`` switches there to a complementarity problem
per step (:mod:`.time_stepping`), still cutting out of its steps the impacts
of contacts that were open, and back to isolated impacts when every contact
has released for two steps; ``"event"`` stops there with status
:attr:`~galerkin_vi.RunStatus.CONTACT_PERSISTS`, every state before it kept;
``"time-stepping"`` takes every step as a complementarity problem.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError, RunFailureWarning
from ..run.events import Event
from ..run.failures import check_failure_mode, failed_run
from ..run.plan import run_plan, state_vector
from ..run.smooth import integrate_smooth, one_step
from ..run.start import initial_state
from ..run.status import RunStatus
from .impact import (
    ContactFunctions,
    Impact,
    impulse,
    inverse_impulse,
    irreversible_contacts,
    simultaneous_impulse,
    stop_slip,
)
from .outputs import Watch, finish, run_options

__all__ = ["MAX_IMPACTS_PER_STEP", "PENETRATION", "integrate_with_contacts"]

#: more impacts than this within one step: they accumulate (a body coming to rest)
MAX_IMPACTS_PER_STEP = 64
#: a node with a gap below -PENETRATION * max(1, |q|) was not reached by an impact
PENETRATION = 1e-12
#: steps of the first smooth piece; pieces double while no impact occurs
FIRST_PIECE = 128
LONGEST_PIECE = 65536


#: a gap above OPEN_GAP * max(1, |q|) at a step's start: the contact is open there
OPEN_GAP = 1e-9

#: halvings of a complementarity step at most when its iteration fails
HALVINGS = 2

#: contacts closed at an impact and approaching faster than this fraction of the hit
#: contact's speed are hit with it (a face landing flat); slower ones rest
TOGETHER = 1e-8
#: contacts approaching an impact whose gap their speed closes within this fraction of a
#: step are hit with it (a face landing flat on a face tilted by round-off)
SIMULTANEOUS = 1e-6
#: the modes of ``integrate(contact_mode=...)``
CONTACT_MODES = ("auto", "event", "time-stepping")
#: normal impulses (force times step) below this leave a contact released
RELEASED_IMPULSE = 1e-12
#: whether the compiled loop keeps apart the contacts whose gap cannot close within a step
#: (off: on a resting cube 246 -> 181 us per step, but on the box toss 9.7 -> 17.5
#: interior-point iterations per step, docs/design-notes.md)
BROAD_PHASE = False
#: what is left of a step after an impact at its very end, relative to h, below which it
#: is a drift, not a complementarity step (whose equations degenerate as tau -> 0)
REMAINDER = 1e-9
#: a gap whose gradient where it closes is this many times smaller than at the run's
#: start has no normal there (y**3 at y = 0): the run stops and says so
NORMAL_VANISHES = 1e-8


def compiled_step_addresses(integrator):
    """The addresses of the point functions the compiled contact step calls, or None
    where the step runs in NumPy (the NumPy backend; second derivatives stored banded)."""
    from .time_stepping import COMPILED_POINTS

    if integrator.backend != "numba" or integrator.uses_banded_storage:
        return None
    system = integrator.system
    names = tuple(
        name
        for name in COMPILED_POINTS
        if (system.m or "constraint" not in name)
        and (name != "point_slip" or any(contact.slip for contact in system.contacts))
    )
    return integrator.compiled_point_functions(names)[0]


def integrate_with_contacts(
    integrator, q0, v0, p0, *, h, n_steps, t0, params, save_every, project, on_failure,
    dense_output, t_span, events, progress, t_eval, contact_mode, variations=None,
):  # fmt: skip
    """:meth:`Integrator.integrate` of a system with contacts (the module's method).

    Every option of a smooth run applies (:mod:`.outputs`): ``save_every``,
    ``dense_output`` (piecewise between impacts), ``events``, ``t_eval``,
    ``project`` (constrained systems), ``progress``, Ctrl-C, ``on_failure``,
    ``t_span``; ``variations`` (the tangent map: :mod:`.tangent`, impacts by their
    saltation matrices). A negative ``h`` runs backwards in time with the inverse impact
    law (:func:`.impact.inverse_impulse`): frictionless contacts with e > 0
    only, isolated impacts only (``contact_mode="auto"`` stops where a contact
    persists, as ``"event"`` does).
    """
    if contact_mode not in CONTACT_MODES:
        raise ValueError(f"contact_mode must be one of {CONTACT_MODES}, got {contact_mode!r}")
    check_failure_mode(on_failure)
    system = integrator.system
    h, n_steps, t0, save_every = run_plan(h, n_steps, t_span, t0, save_every)
    if h < 0:
        _check_backward(system, contact_mode)
    options = run_options(
        system, h, n_steps, t0, save_every, dense_output, events, t_eval, progress
    )
    if variations is not None:
        from .tangent import check_contact_variations

        check_contact_variations(system, variations, contact_mode, h)
        if t_eval is not None:
            raise ValueError(
                "t_eval cannot be combined with tangent: the tangent map is defined at the "
                "steps; use save_every"
            )
    prm = system.parameter_vector(params)
    # lambdified once per system (milliseconds each): kept with it, like event functions
    functions = system.derived.get(("contact", "functions"), lambda: ContactFunctions(system))
    q = state_vector("q0", q0, system.n)
    _check_initial_gaps(system, functions, t0, q, prm)
    q, p, _ = initial_state(integrator.run_spec, q, v0, p0, t0, prm, project)
    if project:  # the projected q0 must be outside the contacts too
        _check_initial_gaps(system, functions, t0, q, prm)
    run = _Run(integrator, functions, prm, h)
    if options.terminal or options.progress is not False:
        run.watch = Watch(options, system, prm, n_steps)
        if options.terminal:
            run.longest_piece = FIRST_PIECE  # so that the run stops soon after the event
    run.rows(t0, q, p)
    # the size of each gap's gradient at the start: where one closes with a gradient
    # NORMAL_VANISHES times smaller, it has no normal
    run.normal_scale = np.array(
        [np.linalg.norm(functions.gradient(j, t0, q, prm)) for j in range(len(system.contacts))]
    )
    stop = _drive(run, t0, n_steps, contact_mode)
    completed = (RunStatus.COMPLETED, RunStatus.COMPLETED.cause)
    traj = run.trajectory(*(stop.outcome if stop is not None else completed))

    def cut_step(q, p, tau, t):
        return one_step(integrator.run_spec, q, p, tau, t, prm)

    event_row = None
    if variations is not None:
        traj, event_row = _with_variations(integrator, run, traj, variations, functions, h)
    traj = finish(traj, options, run.grid()[: len(traj)], t0, h, cut_step, event_row)
    return run.outcome(traj, stop, on_failure)


def _with_variations(integrator, run: _Run, traj, request, functions, h: float):
    """``traj`` with the tangent at every row, and the tangent of a terminal event's row."""
    from ..run.tangent import with_event_row
    from .tangent import contact_variations

    if run.forces:
        raise ValueError(
            f"tangent with contacts: the run took complementarity steps from t = "
            f"{run.forces[0][0]:.6g} (a persisting contact), whose tangent map is not built; "
            "contact_mode='event' stops there instead"
        )
    traj = replace(traj, variations=contact_variations(integrator, traj, request, functions, h))
    spec = integrator.tangent_run_spec
    return traj, lambda cut: with_event_row(spec, request, cut)


def _drive(run: _Run, t0: float, n_steps: int, contact_mode: str) -> _Stop | None:
    """The run from its first row to grid step ``n_steps``; how it stopped (None: completed)."""
    k = 0  # grid index of the current state (or of the step it lies in)
    stepping = contact_mode == "time-stepping"
    try:
        while k < n_steps:
            if stepping:
                k, released = run.time_steps(k, t0, n_steps, until_release=contact_mode == "auto")
                stepping = not released
                continue
            try:
                k = run.event_driven(k, t0, n_steps)
            except _Stop as stop:
                if stop.status != RunStatus.CONTACT_PERSISTS or contact_mode != "auto":
                    raise
                if run.h < 0:
                    raise  # no complementarity steps backwards in time
                # from the last state kept on: a complementarity problem per step
                t_last = float(run.last()[0])
                k = int(np.floor((t_last - t0) / run.h * (1 + 4 * np.finfo(float).eps)))
                stepping = True
    except _Stop as stop:
        return stop
    except _Terminal:
        return None  # the events' pass after the run cuts it at the event
    except KeyboardInterrupt:
        run.settle()
        t_last = float(run.last()[0])
        step = int(round((t_last - t0) / run.h))
        message = (
            f"{RunStatus.INTERRUPTED.cause} after step {step} (t = {t_last:.6g}); the states "
            "computed so far are kept"
        )
        return _Stop(RunStatus.INTERRUPTED, message, step, t_last)
    finally:
        if run.watch is not None:
            run.watch.close()
    return None


def _check_backward(system, contact_mode: str) -> None:
    """A run backwards in time needs the inverse impact law of every contact."""
    if contact_mode == "time-stepping":
        raise ValueError(
            "h < 0: contact_mode='time-stepping' does not run backwards in time (its "
            "contact forces dissipate); use contact_mode='event' or 'auto'"
        )
    reasons = irreversible_contacts(system)
    if reasons:
        raise ValueError(
            "h < 0 (backwards in time) needs the inverse impact law, which "
            + "; ".join(reasons)
            + " does not have"
        )


class _Terminal(Exception):
    """A terminal event has occurred: the run stops after the current piece."""


class _Stop(Exception):
    """The run cannot go on: a failed step or a persisting contact."""

    def __init__(self, status: RunStatus, message: str, step: int, t: float, residual=np.nan):
        super().__init__(message)
        self.status, self.message, self.step, self.t, self.residual = (
            status, message, step, t, residual,
        )  # fmt: skip

    @property
    def outcome(self) -> tuple[RunStatus, str]:
        return self.status, self.message


class _Run:
    """The rows and impacts of a run with contacts, as they are computed."""

    def __init__(self, integrator, functions: ContactFunctions, prm, h: float) -> None:
        self.integrator, self.functions, self.prm, self.h = integrator, functions, prm, h
        self.system = integrator.system
        self.params = dict(zip(self.system.params, prm, strict=True))
        self.events = [
            Event(c.gap, terminal=True, direction=-1.0, exact=True) for c in self.system.contacts
        ]
        self._t: list = []
        self._q: list = []
        self._p: list = []
        self._grid: list = []  # per row: reached at a grid time by a step
        self._watched = 1  # chunks of rows the watch has seen (the first row: none to see)
        #: terminal events and progress, looked at after each piece (None: nothing to watch)
        self.watch: Watch | None = None
        #: a bound on the smooth pieces' steps (None: none; a terminal event sets one)
        self.longest_piece: int | None = None
        self.sign = 1.0 if h > 0 else -1.0
        self.impacts: list[Impact] = []
        self.iterations = 0
        self.forces: list[tuple[float, NDArray, NDArray, int, float]] = []
        self._stepper = None
        #: each gap's gradient's size at the run's start (:meth:`check_normal`)
        self.normal_scale = np.zeros(len(self.system.contacts))
        self._duals = None
        self._has_duals = False

    def last(self):
        """(t, q, p) of the last row."""
        return self._t[-1][-1], self._q[-1][-1], self._p[-1][-1]

    def event_driven(self, k: int, t0: float, n_steps: int) -> int:
        """Isolated impacts from grid node k to the run's end; returns the end's index."""
        h = self.h
        _, q, p = self.last()
        piece = FIRST_PIECE
        while k < n_steps:
            steps = min(piece, n_steps - k)
            if self.longest_piece is not None:
                steps = min(steps, self.longest_piece)
            end = self.smooth(q, p, t0 + k * h, h, steps)
            if end.status != RunStatus.TERMINATED:
                self.rows(t0 + (k + np.arange(1, steps + 1)) * h, end.q[1:], end.p[1:])
                self.check_penetration(end.q[1:], t0 + (k + 1) * h, k + 1)
                q, p, k = end.q[-1], end.p[-1], k + steps
                piece = min(2 * piece, LONGEST_PIECE)
                self.watched(k)
                continue
            # an impact in step k + j: the rows of its nodes, then through the step
            j = len(end.t) - 2
            self.rows(t0 + (k + np.arange(1, j + 1)) * h, end.q[1 : j + 1], end.p[1 : j + 1])
            self.check_penetration(end.q[1 : j + 1], t0 + (k + 1) * h, k + 1)
            start = (t0 + (k + j) * h, end.q[j], end.p[j])
            q, p = self.through_step(start, t0 + (k + j + 1) * h, end, k + j)
            k += j + 1
            piece = max(FIRST_PIECE, 2 * j)
            self.watched(k)
        return k

    def time_steps(self, k: int, t0: float, n_steps: int, until_release: bool):
        """Steps with contact forces from the last row to grid node k + 1 and on.

        Returns (grid index reached, whether the contacts released): with
        ``until_release``, the steps end after two in a row without contact force.
        """
        from .time_stepping import ContactStepper

        if self._stepper is None:
            # one per run, not kept with the system: it holds the run's parameters, and
            # ensemble members run in threads at once
            tables = self.integrator.method.tables
            self._stepper = ContactStepper(
                self.functions, tables, self.prm, compiled_step_addresses(self.integrator)
            )
            self._duals = np.ones(self._stepper.size)
            # the compiled loop starts its first step from the cones' centres, as
            # _attempt's second try (ones are not an interior point of a cone)
            self._has_duals = False
        h = self.h
        t, q, p = self.last()
        free = 0
        piece = FIRST_PIECE
        while k < n_steps:
            if self._compiled_run_applies(t, t0 + k * h):
                # in pieces, as the event-driven steps: the watch looks at each
                count = min(piece, n_steps - k)
                if self.longest_piece is not None:
                    count = min(count, self.longest_piece)
                piece = min(2 * piece, LONGEST_PIECE)
                k, status, free = self._compiled_steps(k, t0, count, until_release, free)
                if status == "released":
                    return k, True
                if k >= n_steps:
                    break
                t, q, p = self.last()
                if status == "finished":
                    continue
                # handed back: the next step is Python's
            t_next = t0 + (k + 1) * h
            q, p, result, tau = self._through_stepping(t, q, p, t_next, k)
            self.rows(t_next, q, p)
            t, k = t_next, k + 1
            self.watched(k)
            free = free + 1 if np.all(result.normal * tau <= RELEASED_IMPULSE) else 0
            if until_release and free >= 2:
                return k, True
        return k, False

    def _compiled_run_applies(self, t: float, t_grid: float) -> bool:
        """Whether the steps from ``t`` go through the compiled loop: a compiled stepper
        and ``t`` on the grid (not an impact's time)."""
        return self._stepper.addresses is not None and t == t_grid and self.sign > 0

    def _compiled_steps(self, k: int, t0: float, count: int, until_release: bool, free: int):
        """At most ``count`` steps from grid node k by
        :func:`galerkin_vi.loops.contact_run.contact_steps`; returns (grid index reached,
        "released", "finished" or "handed back", free steps).

        Their rows, forces and impacts are those :meth:`_through_stepping` records step by
        step (the first touches cut out of the steps in the loop too)."""
        from ..loops.contact_run import FINISHED, RELEASED, contact_steps

        stepper, system = self._stepper, self.system
        n, nc = system.n, len(system.contacts)
        _, q, p = self.last()
        q, p = np.array(q, dtype=float), np.array(p, dtype=float)
        duals = np.array(self._duals, dtype=float)
        room = 2 * count + 2 * MAX_IMPACTS_PER_STEP + 1
        row_t, row_grid = np.zeros(room), np.zeros(room, dtype=np.bool_)
        row_q, row_p = np.zeros((room, n)), np.zeros((room, n))
        force_t, normal_out = np.zeros(room), np.zeros((room, nc))
        tangential_out = np.zeros((room, nc, 2))
        iterations_out, complementarity_out = np.zeros(room), np.zeros(room)
        impact_data = np.zeros((count + MAX_IMPACTS_PER_STEP, 8))
        stats = np.zeros(7)
        contact_steps(
            stepper.addresses, float(t0), k, float(self.h), count, q, p, duals,
            self._has_duals, *stepper.compiled_layout(),
            bool(system.structure.quadratic_in_v), bool(until_release), int(free),
            OPEN_GAP, RELEASED_IMPULSE, BROAD_PHASE, REMAINDER, MAX_IMPACTS_PER_STEP,
            TOGETHER, NORMAL_VANISHES * self.normal_scale, row_t, row_q, row_p, row_grid, force_t,
            normal_out, tangential_out, iterations_out, complementarity_out, impact_data, stats,
        )  # fmt: skip
        taken, status, free = int(stats[0]), int(stats[1]), int(stats[2])
        rows, forces, impacts = int(stats[4]), int(stats[5]), int(stats[6])
        self._rows_in_order(row_t[:rows], row_q[:rows], row_p[:rows], row_grid[:rows])
        width = stepper.tangential_size
        for i in range(forces):
            self.forces.append(
                (force_t[i], normal_out[i], tangential_out[i, :, :width],
                 int(iterations_out[i]), float(complementarity_out[i]))
            )  # fmt: skip
        for record in impact_data[:impacts]:
            self.impacts.append(self._impact(record, row_t, row_q, row_p))
        if forces:
            self._duals, self._has_duals = duals, True
        self.watched(k + taken)
        outcome = {RELEASED: "released", FINISHED: "finished"}.get(status, "handed back")
        return k + taken, outcome, free

    def _rows_in_order(self, t, q, p, grid) -> None:
        """Rows of the compiled loop: runs of grid rows and impacts' pairs, in order."""
        start = 0
        for end in range(1, t.size + 1):
            if end == t.size or grid[end] != grid[start]:
                self.rows(t[start:end], q[start:end], p[start:end], grid=bool(grid[start]))
                start = end

    def _impact(self, record, row_t, row_q, row_p) -> Impact:
        """The :class:`Impact` of a row of the compiled loop's ``impact_data``."""
        row, j, mode = int(record[0]), int(record[1]), int(record[2])
        layout = self._stepper.layout[j]
        slips = 0 if layout.cone is None else layout.cone.stop - layout.cone.start - 1
        q = row_q[row]
        H = self.system.hamiltonian(
            np.vstack([q, q]), np.vstack([row_p[row], row_p[row + 1]]), row_t[row], self.params
        )
        return Impact(
            t=float(row_t[row]),
            contact=j,
            normal_impulse=float(record[3]),
            tangential_impulse=np.array(record[4 : 4 + slips], dtype=float),
            mode=("frictionless", "stick", "slide")[mode],
            normal_velocity=(float(record[6]), float(record[7])),
            energy_lost=float(H[0] - H[1]),
        )

    def _stepping(self, t: float, q, p, tau: float, k: int, excluded: Sequence[int] = ()):
        """One complementarity step of length tau (contacts ``excluded`` kept apart)."""
        result = self._attempt(t, q, p, tau, excluded, HALVINGS)
        if not result.converged:
            self._check_geometry(t, q, k)
            raise _Stop(
                RunStatus.NO_CONVERGENCE,
                f"step {k} (t = {t:.6g}): the contact step's interior-point iteration did not "
                f"converge in {result.iterations} iterations (complementarity "
                f"{result.complementarity:.3g}), nor from the cones' centres, nor in halves; "
                "the states before are kept",
                k, t,
            )  # fmt: skip
        return result

    def _check_geometry(self, t: float, q, k: int) -> None:
        """A failed step's cause in the contacts at its start, if there: a gap that is
        not finite, or a closed contact without a normal (:meth:`check_normal`)."""
        scale = max(1.0, float(np.max(np.abs(q))))
        for j in range(len(self.system.contacts)):
            gap = self.functions.gap(j, t, q, self.prm)
            if not np.isfinite(gap):
                raise self._geometry(j, t, q, k, f"its gap is {gap}", RunStatus.NON_FINITE)
            if gap <= OPEN_GAP * scale:
                self.check_normal(j, t, q)

    def _attempt(self, t: float, q, p, tau: float, excluded: Sequence[int], halvings: int):
        """A step of length tau from the last step's forces; failing that, from the
        cones' centres (the last forces may start it far from this one's: a contact
        that just took the load); failing that, as two steps of tau / 2 (a shorter
        step moves the contacts less), ``halvings`` times at most."""
        from .time_stepping import StepResult

        stepper = self._stepper
        guess = self._guess(q, p, t, tau)
        result = stepper.step(t, tau, q, p, guess, self._duals, excluded)
        if not result.converged:
            result = stepper.step(t, tau, q, p, guess, None, excluded)
        if result.converged or halvings == 0:
            return result
        first = self._attempt(t, q, p, tau / 2, excluded, halvings - 1)
        if not first.converged:
            return first
        second = self._attempt(t + tau / 2, first.q, first.p, tau / 2, excluded, halvings - 1)
        # constant forces over each half: their means carry the impulses over tau
        return StepResult(
            q=second.q,
            p=second.p,
            C=second.C,
            normal=(first.normal + second.normal) / 2,
            tangential=(first.tangential + second.tangential) / 2,
            duals=second.duals,
            sticking=second.sticking,
            iterations=first.iterations + second.iterations,
            complementarity=max(first.complementarity, second.complementarity),
            converged=second.converged,
        )

    def _through_stepping(self, t: float, q, p, t_next: float, k: int):
        """Complementarity steps from t to the grid time t_next, impacts cut out.

        A contact open at the step's start that pushes during it was hit inside
        the step: the step is cut where its gap closes (found on steps with
        the open contacts kept apart, by regula falsi on their length), the impact
        law applied there, and the rest of the step taken again, as in the
        event-driven mode. Returns (q, p, the last step's result, its length) at t_next.
        """
        for _ in range(MAX_IMPACTS_PER_STEP):
            tau = t_next - t
            if abs(tau) <= REMAINDER * abs(self.h):
                result = self._drift(t, q, p, tau)
                break
            try:
                result, failure = self._stepping(t, q, p, tau, k), None
            except _Stop as stop:  # a hard impact inside the step can defeat the iteration
                result, failure = None, stop
            opened = [
                j
                for j in range(len(self.system.contacts))
                if self.functions.gap(j, t, q, self.prm) > OPEN_GAP * max(1.0, np.abs(q).max())
                and (result is None or result.normal[j] * tau > RELEASED_IMPULSE)
            ]
            cut = self._first_touch(t, q, p, tau, k, opened) if opened else None
            if cut is None:
                if failure is not None:
                    raise failure
                break
            alpha, j, touching = cut
            t_hit = t + alpha
            self.forces.append(
                (t, touching.normal, touching.tangential, touching.iterations,
                 touching.complementarity)
            )  # fmt: skip
            q_hit, p_minus = touching.q, touching.p
            self.check_normal(j, t_hit, q_hit)
            v_hit = self.system.inverse_legendre(q_hit, p_minus, t_hit, self.params)
            if self.functions.gradient(j, t_hit, q_hit, self.prm) @ v_hit >= 0.0:
                # grazed, not hit: the gap closes at the cut while it opens already (the
                # other contacts' forces turned it); the step goes on from there
                t, q, p = t_hit, q_hit, p_minus
                continue
            together = self._hit_together(j, t_hit, q_hit, v_hit)
            if len(together) > 1:
                # a face landing flat: Newton's law of one contact at a time would turn it
                p_plus, impacts = self._simultaneous(together, t_hit, q_hit, p_minus, k)
            else:
                p_plus, impact = impulse(
                    self.system, self.functions, j, t_hit, q_hit, p_minus, self.prm
                )
                impacts = [impact]
            self.impacts.extend(impacts)
            self.rows([t_hit, t_hit], [q_hit, q_hit], [p_minus, p_plus], grid=False)
            t, q, p = t_hit, q_hit, p_plus
        else:
            raise self._persists(j, t, k, f"more than {MAX_IMPACTS_PER_STEP} impacts in one step")
        self._duals, self._has_duals = result.duals, True
        self.forces.append(
            (t, result.normal, result.tangential, result.iterations, result.complementarity)
        )
        p_end = self._velocity_law(t_next, result.q, result.p, result.normal * tau, result.sticking)
        return result.q, p_end, result, tau

    def _drift(self, t: float, q, p, tau: float):
        r"""The remainder of a step after an impact at its very end, :math:`|\tau| \le`
        REMAINDER h: :math:`q + \tau v`, :math:`p + \tau (L_q + f)` (projected onto the
        hidden constraint), no contact force. Its error, of order :math:`\tau^2`, is far
        below the round-off of a step; the interior point's equations, scaled by
        :math:`1/\tau`, fail there (a tumbling cube's corner closing 1.6e-13 s before the
        grid time, measured)."""
        from .time_stepping import StepResult

        system = self.system
        v = system.inverse_legendre(q, p, t, self.params)
        force = system.evaluate("gradient", t, q, v, self.prm)[: system.n]
        q_end, p_end = q + tau * v, p + tau * force
        if system.m:
            p_end = self._stepper._projected(t + tau, q_end, p_end)
        contacts = len(system.contacts)
        return StepResult(
            q=q_end, p=p_end, C=np.zeros((2, system.n)), normal=np.zeros(contacts),
            tangential=np.zeros((contacts, self._stepper.tangential_size)),
            duals=self._duals, sticking=np.zeros(contacts, dtype=bool), iterations=0,
            complementarity=0.0, converged=True,
        )  # fmt: skip

    def _first_touch(self, t: float, q, p, tau: float, k: int, opened: list[int]):
        """(alpha, contact, step result) of the earliest closing of an open contact, or None.

        For each contact in ``opened``: the step length alpha in (0, tau) at whose
        end its gap is zero, on steps that keep every contact in ``opened`` apart
        (Illinois regula falsi): the earliest touch is on a step on which none of
        them has touched yet, and contacts that touch together (a face landing
        flat) touch at the same alpha. None when the closing is at the step's start
        (a resting contact).
        """
        best = None
        scale = max(1.0, float(np.abs(q).max()))
        for j in opened:
            g0 = self.functions.gap(j, t, q, self.prm)
            whole = self._stepping(t, q, p, tau, k, excluded=opened)
            g1 = self.functions.gap(j, t + tau, whole.q, self.prm)
            if not g1 < 0.0:
                continue  # it would not have closed without its force: no impact
            a, b, fa, fb, side = 0.0, tau, g0, g1, 0
            result = whole
            for _ in range(60):
                alpha = (a * fb - b * fa) / (fb - fa)
                result = self._stepping(t, q, p, alpha, k, excluded=opened)
                f = self.functions.gap(j, t + alpha, result.q, self.prm)
                if abs(f) <= 4 * np.finfo(float).eps * scale or b - a <= 4e-16 * tau:
                    break
                if f > 0:
                    a, fa = alpha, f
                    fb = fb / 2 if side == 1 else fb
                    side = 1
                else:
                    b, fb = alpha, f
                    fa = fa / 2 if side == -1 else fa
                    side = -1
            if alpha <= 1e-12 * tau:
                return None
            if best is None or alpha < best[0]:
                best = (alpha, j, result)
        return best

    def _simultaneous(self, together: list[int], t: float, q, p, k: int) -> tuple:
        """:func:`.impact.simultaneous_impulse`; the run stops where its sweeps do not
        settle, the states before kept."""
        try:
            return simultaneous_impulse(self.system, self.functions, together, t, q, p, self.prm)
        except ConvergenceError as exc:
            raise _Stop(
                RunStatus.NO_CONVERGENCE, f"step {k} (t = {t:.6g}): {exc}; the states "
                "before are kept", k, t, exc.residual,
            ) from None  # fmt: skip

    def _hit_together(self, hit: int, t: float, q, v) -> list[int]:
        """Contact ``hit`` and the others hit at (t, q) with it: gap closed to OPEN_GAP
        or to what its speed covers in SIMULTANEOUS h, and approaching at ``v`` faster
        than TOGETHER times ``hit``, or, when ``hit`` is plastic, plastic and resting (a
        box landing on one that rests on the floor pushes through it). An elastic hit
        leaves resting contacts to the impacts that follow at once (Newton's cradle)."""
        contacts = self.system.contacts
        gaps = self.functions.at(self.functions.gaps, t, q, v, self.prm)
        speeds = self.functions.at(self.functions.gradients, t, q, v, self.prm) @ v
        # closed to OPEN_GAP, or touching within SIMULTANEOUS h at its speed
        closed = np.maximum(
            OPEN_GAP * max(1.0, float(np.abs(q).max())), -speeds * SIMULTANEOUS * abs(self.h)
        )
        plastic = contacts[hit].restitution == 0.0
        return [hit] + [
            j
            for j in range(len(gaps))
            if j != hit
            and gaps[j] <= closed[j]
            and (speeds[j] < TOGETHER * speeds[hit] or (plastic and contacts[j].restitution == 0.0))
        ]

    def _velocity_law(self, t: float, q, p, impulses, sticking) -> NDArray[np.float64]:
        r"""The impact law at the velocity level for the contacts that pushed in this step
        and are closed at its end.

        A position-level step leaves the normal velocity of a contact that
        closed during it unchanged in size (it reverses: p_{k+1} = -p_k for a
        ball resting on the floor); Newton's law :math:`u^+ = -e\,u^-` applied
        at the step's end, where :math:`u < 0`, damps it as the contact's
        restitution says (Moreau's sweeping process with restitution). Likewise
        the slip of a contact that stuck during the step (its mean slip zero) is
        stopped at the end (:func:`.impact.stop_slip`).
        """
        gaps = self.functions.at(self.functions.gaps, t, q, np.zeros_like(q), self.prm)
        closed = OPEN_GAP * max(1.0, float(np.abs(q).max()))
        for j, impulse_j in enumerate(impulses):
            if impulse_j <= RELEASED_IMPULSE or gaps[j] > closed:
                continue  # released, or open at the end: its force was the barrier's
            self.check_normal(j, t, q)
            v = self.system.inverse_legendre(q, p, t, self.params)
            if self.functions.gradient(j, t, q, self.prm) @ v < 0.0:
                # part of the persistent contact, not an impact of its own: not listed
                p, _ = impulse(self.system, self.functions, j, t, q, p, self.prm)
            if sticking[j]:  # also after a round-off approach speed was damped
                p = stop_slip(self.system, self.functions, j, t, q, p, self.prm)
        return p

    def _guess(self, q, p, t, tau):
        """Control points of a straight motion at the current velocity."""
        v = self.system.inverse_legendre(q, p, t, self.params)
        d = self.integrator.method.tables.d
        return d[:, None] * (tau * v)[None, :]

    def rows(self, t, q, p, grid: bool = True) -> None:
        """Append rows: states reached at grid times by steps (``grid``), or an impact's."""
        if np.size(t) == 0:
            return
        t = np.atleast_1d(np.asarray(t, dtype=float))
        self._grid.append(np.full(t.size, grid))
        self._t.append(t)
        self._q.append(np.atleast_2d(q))
        self._p.append(np.atleast_2d(p))

    def settle(self) -> None:
        """The rows and impacts made consistent after Ctrl-C, which may fall between appends."""
        chunks = min(len(self._t), len(self._q), len(self._p), len(self._grid))
        del self._t[chunks:], self._q[chunks:], self._p[chunks:], self._grid[chunks:]
        t_last = self._t[-1][-1]
        self.impacts = [i for i in self.impacts if (i.t - t_last) * self.sign <= 0.0]

    def grid(self) -> NDArray[np.bool_]:
        """Per row: whether it is a grid row (:func:`.outputs.saved_every`)."""
        return np.concatenate(self._grid)

    def watched(self, k: int) -> None:
        """Show the rows added since the last call to the watch (k: the grid step reached).

        Raises
        ------
        _Terminal
            When a terminal event has occurred in them.
        """
        if self.watch is None:
            return
        if not self.watch.terminal:
            self.watch.seen((), (), (), k)  # the progress bar only
            return
        seen = self._watched - 1  # the last chunk seen: its last row starts the new ones
        new = slice(seen, len(self._t))
        t, q, p = (np.concatenate(rows[new]) for rows in (self._t, self._q, self._p))
        first = len(self._t[seen]) - 1
        self._watched = len(self._t)
        if self.watch.seen(t[first:], q[first:], p[first:], k):
            raise _Terminal

    def smooth(self, q, p, t_start: float, h: float, steps: int, events: bool = True):
        """``steps`` Galerkin steps of size h from (q, p); stops at a closing gap."""
        try:
            traj = integrate_smooth(
                self.integrator.run_spec, q, None, p, h=h, n_steps=steps, t0=t_start,
                params=self.params, on_failure="raise",
                events=self.events if events else None, progress=False,
            )  # fmt: skip
        except ConvergenceError as exc:
            partial = exc.partial
            if len(partial) > 1:
                self.rows(partial.t[1:], partial.q[1:], partial.p[1:])
            raise _Stop(partial.status, partial.message, exc.step, exc.t, exc.residual) from None
        self.iterations += traj.total_newton_iterations
        return traj

    def through_step(self, start, t_end: float, end, step: int):
        """From the node before an impact to the grid time ``t_end``, impacts applied.

        ``end`` is the smooth run that stopped at the impact. Returns (q, p) at ``t_end``.
        """
        t_s, q_s, p_s = start
        t_hit = float(end.t[-1])
        for _ in range(MAX_IMPACTS_PER_STEP):
            j = self._which(end)
            # a gap closing at once: another contact touching already (Newton's cradle), hit
            # at the same instant if it approaches, else a contact that persists
            at_once = abs(t_hit - t_s) <= 4 * np.finfo(float).eps * max(1.0, abs(t_hit))
            if at_once:
                q_hit, p_minus = q_s, p_s
            else:
                q_hit, p_minus = one_step(
                    self.integrator.run_spec, q_s, p_s, t_hit - t_s, t_s, self.prm
                )
            try:
                p_plus, impacts = self.jump(j, t_hit, q_hit, p_minus)
            except ValueError:
                if at_once:
                    raise self._persists(j, t_hit, step, "the gap closes again at once") from None
                # grazing: the gap closed with a normal velocity of round-off size
                p_plus, impacts = p_minus, []
            impact = impacts[0] if impacts else None
            if impacts:
                self.impacts.extend(impacts)
                self.rows([t_hit, t_hit], [q_hit, q_hit], [p_minus, p_plus], grid=False)
            t_s, q_s, p_s = t_hit, q_hit, p_plus
            if (t_end - t_s) * self.sign <= 4 * np.finfo(float).eps * max(1.0, abs(t_end)):
                if impact is not None:
                    self._grid[-1][-1] = True  # the state leaving it is the grid time's
                return q_s, p_s  # the impact fell on the grid time
            end = self.smooth(q_s, p_s, t_s, t_end - t_s, 1, events=impact is not None)
            if end.status != RunStatus.TERMINATED:
                self.rows(t_end, end.q[-1], end.p[-1])
                self.check_penetration(end.q[-1:], t_end, step + 1, trusted=t_s)
                return end.q[-1], end.p[-1]
            t_hit = float(end.t[-1])
        raise self._persists(
            self._which(end), t_hit, step, f"more than {MAX_IMPACTS_PER_STEP} impacts in one step"
        )

    def jump(self, j: int, t: float, q, p) -> tuple:
        """(momentum leaving, its :class:`.impact.Impact` list) of contact j's impact, met
        with p.

        Forward in time the impact law, of all the contacts hit with j at once
        (:func:`.impact.simultaneous_impulse`: a face landing flat); backwards the
        inverse of j's (the run meets the post-impact state first).
        """
        self.check_normal(j, t, q)
        if self.sign < 0:
            p_minus, impact = inverse_impulse(self.system, self.functions, j, t, q, p, self.prm)
            return p_minus, [impact]
        v = self.system.inverse_legendre(q, p, t, self.params)
        together = self._hit_together(j, t, q, v)
        if len(together) > 1 and self.functions.gradient(j, t, q, self.prm) @ v < 0.0:
            step = int(np.floor((t - self._t[0][0]) / self.h))
            return self._simultaneous(together, t, q, p, step)
        p_plus, impact = impulse(self.system, self.functions, j, t, q, p, self.prm)
        return p_plus, [impact]

    def check_penetration(
        self, q, t_first: float, step_first: int, trusted: float | None = None
    ) -> None:
        """Stop where a node lies inside a contact that no impact reached; the rows
        after the node before it are dropped, or after ``trusted`` (an impact's time:
        the rest of its step went inside)."""
        q = np.atleast_2d(q)
        t = t_first + self.h * np.arange(len(q))
        bound = -PENETRATION * np.maximum(1.0, np.abs(q).max(axis=1))
        for j in range(len(self.system.contacts)):
            gaps = self.functions.gaps_at(j, t, q, self.prm)
            broken = np.flatnonzero(~np.isfinite(gaps))
            if broken.size:
                r = int(broken[0])
                self._drop_after(t[r] - self.h)
                raise self._geometry(
                    j, t[r], q[r], step_first + r - 1, f"its gap is {gaps[r]}",
                    RunStatus.NON_FINITE,
                )  # fmt: skip
            inside = np.flatnonzero(gaps < bound)
            if inside.size:
                r = int(inside[0])
                gap = self.functions.gap(j, t[r], q[r], self.prm)
                # the rows from this node on are not trusted: drop them
                last = t[r] - self.h if trusted is None or r > 0 else trusted
                self._drop_after(last)
                raise self._persists(j, last, step_first + r - 1, f"gap {gap:.3g}")

    def _drop_after(self, t: float) -> None:
        t_all = np.concatenate(self._t)
        keep = int(np.searchsorted(t_all * self.sign, t * self.sign, side="right"))
        q_all, p_all = np.concatenate(self._q), np.concatenate(self._p)
        self._t, self._q, self._p = [t_all[:keep]], [q_all[:keep]], [p_all[:keep]]
        self._grid = [np.concatenate(self._grid)[:keep]]
        self._watched = min(self._watched, 1)
        # the impacts of the dropped rows go with them (their step is taken again)
        self.impacts = [i for i in self.impacts if (i.t - t) * self.sign <= 0.0]

    def _which(self, end) -> int:
        """The contact whose event stopped the smooth run ``end``."""
        stop = end.t[-1]
        return next(j for j, te in enumerate(end.t_events) if te.size and te[-1] == stop)

    def _geometry(self, j: int, t: float, q, step: int, detail: str, status: RunStatus) -> _Stop:
        """The stop where contact j's gap or its gradient cannot be used at (t, q)."""
        contact = self.system.contacts[j]
        where = np.array2string(np.asarray(q, dtype=float), precision=6)
        message = (
            f"step {step} (t = {t:.6g}): contacts[{j}] (gap {contact.gap}) at q = {where}: "
            f"{detail}; the states before are kept"
        )
        return _Stop(status, message, step, t)

    def check_normal(self, j: int, t: float, q) -> None:
        """Stop the run where contact j closes without a normal: its gap's gradient is
        not finite there, or NORMAL_VANISHES times smaller than at the run's start, so its
        force and its impact law have no direction."""
        g = self.functions.gradient(j, t, q, self.prm)
        if np.all(np.isfinite(g)) and np.linalg.norm(g) > NORMAL_VANISHES * self.normal_scale[j]:
            return
        step = int(np.floor((t - self._t[0][0]) / self.h * (1 + 4 * np.finfo(float).eps)))
        raise self._geometry(
            j, t, q, step,
            f"its gap's gradient is {g} where it closes: the contact has no normal there "
            "(write the gap so that its gradient is finite and nonzero on the surface)",
            RunStatus.SINGULAR_JACOBIAN,
        )  # fmt: skip

    def _persists(self, j: int, t: float, step: int, detail: str) -> _Stop:
        contact = self.system.contacts[j]
        message = (
            f"step {step} (t = {t:.6g}): contact {j} (gap {contact.gap}): "
            f"{RunStatus.CONTACT_PERSISTS.cause} ({detail}); the states before are kept"
        )
        return _Stop(RunStatus.CONTACT_PERSISTS, message, step, t)

    def trajectory(self, status: RunStatus, message: str):
        from ..run.trajectory import Trajectory

        t, q, p = np.concatenate(self._t), np.concatenate(self._q), np.concatenate(self._p)
        return Trajectory(
            t=t,
            q=q,
            p=p,
            newton_iterations=np.zeros(0, dtype=np.uint8),
            total_newton_iterations=self.iterations,
            n_steps=int(np.round((t[-1] - t[0]) / self.h)),
            max_residual=0.0,
            system=self.system,
            params=self.prm,
            order=self.integrator.method.order,
            status=status,
            message=message,
            impacts=list(self.impacts),
            contact_forces=self._contact_forces(),
        )

    def _contact_forces(self):
        if not self.forces:
            return None
        from .time_stepping import ContactForces

        t, normal, tangential, iterations, complementarity = zip(*self.forces, strict=True)
        return ContactForces(
            t=np.array(t),
            normal=np.array(normal),
            tangential=np.array(tangential),
            iterations=np.array(iterations),
            complementarity=np.array(complementarity),
        )

    def outcome(self, traj, stop: _Stop | None, on_failure: str):
        """The run's result ``traj``: warned or raised as ``stop`` and ``on_failure`` say."""
        if stop is None or traj.status == RunStatus.TERMINATED:
            return traj
        if stop.status == RunStatus.INTERRUPTED:
            # asked for by the user: returned in either failure mode
            warnings.warn(stop.message, RunFailureWarning, stacklevel=4)
            return traj
        if stop.status == RunStatus.CONTACT_PERSISTS:
            # the model's limit here, not a numerical failure: warned, never raised
            warnings.warn(stop.message, RunFailureWarning, stacklevel=4)
            return traj
        return failed_run(
            traj, on_failure, step=stop.step, t=stop.t, residual=stop.residual,
            stacklevel=5,
        )  # fmt: skip


def _check_initial_gaps(system, functions: ContactFunctions, t0: float, q, prm) -> None:
    scale = max(1.0, float(np.max(np.abs(q))))
    for j, contact in enumerate(system.contacts):
        gap = functions.gap(j, t0, q, prm)
        if not np.isfinite(gap):
            raise ValueError(f"contacts[{j}] (gap {contact.gap}): the gap at q0 is {gap}")
        if gap < -PENETRATION * scale:
            raise ValueError(
                f"contacts[{j}] (gap {contact.gap}): q0 = {q} penetrates the contact "
                f"(gap {gap:.3g} < 0)"
            )
