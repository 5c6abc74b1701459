"""The adaptive integrator: fixed steps in fictitious time of the Poincaré-transformed
system (:mod:`.transform`), reported in physical time (:mod:`.physical`)."""

from __future__ import annotations

import math
import numbers
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..errors import ConvergenceError, RunFailureWarning
from ..integrator import Integrator
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from ..run.chunks import ProgressBar
from ..run.ensemble import Ensemble, member_parameters, member_starts
from ..run.events import apply_events, locate_events, terminal_stop
from ..run.failures import check_failure_mode, failed_run
from ..run.plan import requested_times, state_vector
from ..run.status import RunStatus
from ..run.trajectory import Trajectory
from .physical import (
    OutputRequest,
    fictitious_step,
    fictitious_times,
    physical_span,
    rows_at,
    save_interval,
)
from .rows import ExtendedRows
from .step_function import StepFunction, default_step_function
from .trajectory import AdaptiveTrajectory
from .transform import CLOCK_WEIGHT, ENERGY, PoincareTransform, clock_weight

__all__ = ["AdaptiveIntegrator", "adaptive_block"]

#: steps of the first chunk of a run to a final time, before the rate dt/dtau is known
_FIRST_CHUNK = 256
_MAX_CHUNK = 1_000_000
#: a chunk to a final time covers the predicted steps and this share more: the mean
#: dt/dtau over the run so far misses the steps left by about one orbit's steps times
#: (steps left) / (steps done)
_MARGIN = 0.01
#: largest chunk of a run watched for a terminal event: the steps computed past the event
_WATCHED_CHUNK = 4096
#: secant iterations placing the last step on the final time
_LANDING_ITERATIONS = 20


class AdaptiveIntegrator:
    r"""Time-adaptive symplectic integration by the Poincaré transformation.

    Fixed steps :math:`\Delta\tau` of a Galerkin method on the extended
    Lagrangian of :class:`PoincareTransform`; the physical step is about
    :math:`g(q)\,\Delta\tau`. The energy :math:`E` is set from the initial
    state of each run.

    **The default g.** Without ``g``, the step-size function is read off the
    Lagrangian (:mod:`galerkin_vi.adaptive.step_function`): every term that is
    singular where a distance :math:`r_k(q)` vanishes (an inverse distance
    :math:`1/|q_i - q_j|` or :math:`1/|q - c|`, also through powers and square
    roots) contributes, and

    .. math::

        g(q) = \Big(\sum_k r_k^{-3/2}\Big)^{-1} \approx \min_k r_k^{3/2},

    :func:`encounter_scaling` with :math:`\alpha = 3/2`: near each encounter the
    physical step is proportional to the local orbital time
    :math:`\sqrt{r^3/(Gm)}` (Kepler's third law; Sundman's :math:`\alpha = 1`
    would spend :math:`r^{-1/2}` times more steps per revolution on close passages
    than on distant ones). Every distance between points at which L is singular
    enters (a squared distance that reaches 0 at a point, or a linear form; other singular
    bases are left out with a warning), so an encounter the user did not foresee is
    resolved too. Without any such term,
    :math:`g = 1`. :attr:`step_function` holds the choice and :meth:`describe`
    prints it.

    Parameters
    ----------
    system : LagrangianSystem
        Autonomous, without constraints or forces.
    method : Galerkin, optional
        Default ``Galerkin(2)``. With Gauss quadrature the clock is exactly the
        quadrature of :math:`g` over each step (see the module docstring).
    g : sympy.Expr, optional
        Step-size function of q (and parameters), positive along the orbit;
        :func:`encounter_scaling` builds the usual choice. Default: read off
        the singular terms of L (above).
    **options
        Passed to :class:`Integrator` (``backend``, ``tol``, ``maxiter``,
        ``fixed_point``). ``fixed_point`` defaults to ``"persistent"``: the
        stage velocities' fixed point is kept through the slow sweeps near close
        encounters and hands over to Newton only when it diverges.

    Examples
    --------
    >>> import numpy as np, sympy as sp, galerkin_vi as gvi
    >>> x, y, vx, vy = sp.symbols("x y vx vy")
    >>> r = sp.sqrt(x**2 + y**2)
    >>> kepler = gvi.LagrangianSystem((vx**2 + vy**2) / 2 + 1 / r, [x, y], [vx, vy])
    >>> adaptive = gvi.AdaptiveIntegrator(kepler, gvi.Galerkin(2, gvi.gauss_legendre(2)),
    ...                                   g=gvi.encounter_scaling([r], 1.5))
    >>> traj = adaptive.integrate([0.1, 0.0], [0.0, np.sqrt(19.0)], h=0.05, t_final=2 * np.pi)
    >>> float(traj.t[-1]) == 2 * np.pi
    True
    >>> bool(np.abs(traj.q[-1] - [0.1, 0.0]).max() < 1e-4)  # one period of e = 0.9
    True
    """

    def __init__(
        self,
        system: LagrangianSystem,
        method: Galerkin | None = None,
        *,
        g: sp.Expr | None = None,
        **options,
    ) -> None:
        if not isinstance(system, LagrangianSystem):
            raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
        if isinstance(method, Composition):
            raise ValueError(
                f"AdaptiveIntegrator: {method!r} needs a separable Lagrangian with constant "
                "mass, and the Poincare-transformed Lagrangian g(q) (L + H0) is not one "
                "(its mass matrix is g(q) M); use a Galerkin method"
            )
        #: the step-size function and where it came from (:meth:`describe`)
        chosen = default_step_function(system) if g is None else None
        self.transform = PoincareTransform(system, chosen.g if chosen is not None else g)
        self.step_function = chosen if chosen is not None else StepFunction(self.transform.g)
        self.system = system
        #: the integrator's options, for building it again in an executor's worker
        self.options = {"fixed_point": "persistent", **options}
        self.integrator = Integrator(self.transform.extended, method, **self.options)
        self.method = self.integrator.method

    def describe(self) -> str:
        """The step-size function g in one line, and where it came from."""
        return self.step_function.describe()

    def __repr__(self) -> str:
        return f"AdaptiveIntegrator({self.method!r}, {self.describe()})"

    # ------------------------------------------------------------------ set-up
    def _start(self, q0, v0, p0, t0, params):
        system = self.system
        prm = system.parameter_vector(params)
        q0 = state_vector("q0", q0, system.n)
        if (v0 is None) == (p0 is None):
            raise ValueError("give exactly one of v0 and p0")
        named = dict(zip(system.params, prm, strict=True))
        if p0 is None:
            v0 = state_vector("v0", v0, system.n)
            p0 = system.legendre(q0, v0, 0.0, named)
        p0 = state_vector("p0", p0, system.n)
        if v0 is None:
            v0 = system.inverse_legendre(q0, p0, 0.0, named)
        rate = float(self.transform.rate(q0, prm))
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"g(q0) must be positive and finite, got {rate!r}")
        energy = float(system.hamiltonian(q0, p0, 0.0, named))
        if not math.isfinite(energy):
            raise ValueError(f"the energy at (q0, p0) is not finite: {energy!r}")
        weight = clock_weight(system, q0, np.asarray(v0, dtype=float), prm, rate)
        extended_params = {**named, ENERGY: energy, CLOCK_WEIGHT: weight}
        # p_z = 0: the clock runs at dt/dtau = g
        qh = np.append(q0, float(t0))
        ph = np.append(p0, 0.0)
        return qh, ph, extended_params, prm

    def _trajectory(self, run: Trajectory, prm: NDArray) -> AdaptiveTrajectory:
        n = self.system.n
        q_reduced = None if run.q_reduced is None else run.q_reduced[:, :n].copy()
        return AdaptiveTrajectory(
            t=run.q[:, n].copy(),
            q=run.q[:, :n].copy(),
            p=run.p[:, :n].copy(),
            newton_iterations=run.newton_iterations,
            max_residual=run.max_residual,
            system=self.system,
            params=prm,
            total_newton_iterations=run.total_newton_iterations,
            n_steps=run.n_steps,
            q_reduced=q_reduced,
            tau=run.t.copy(),
            clock_momentum=run.p[:, n].copy(),
            status=run.status,
            message=run.message,
            order=self.method.order,
        )

    # ------------------------------------------------------------------ runs
    def integrate(
        self,
        q0: ArrayLike,
        v0: ArrayLike | None = None,
        p0: ArrayLike | None = None,
        *,
        h: float,
        n_steps: int | None = None,
        t_final: float | None = None,
        t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        save_every: int = 1,
        on_failure: str = "warn",
        dense_output: bool = False,
        t_span: tuple[float, float] | None = None,
        events: object = None,
        progress: bool | None = None,
        t_eval: ArrayLike | None = None,
        project: bool = False,
        tangent: object = None,
        sensitivity: object = None,
    ) -> AdaptiveTrajectory:
        r"""Integrate with fictitious step ``h`` for ``n_steps`` steps or up to ``t_final``.

        The options are those of :meth:`Integrator.integrate`, in physical time.

        Parameters
        ----------
        q0 : array_like, shape (n,)
        v0, p0 : array_like, shape (n,)
            Exactly one: physical velocities or momenta.
        h : float
            The fixed step :math:`\Delta\tau` in fictitious time. Negative ``h``
            runs the Poincaré map backwards: fictitious and physical time
            decrease (:math:`dt/d\tau = g > 0`).
        n_steps : int, optional
            Number of steps; or
        t_final : float, optional
            Physical time to reach (after ``t0`` for ``h > 0``, before it for
            ``h < 0``): the run stops at the first step past it and replaces
            that step by one of the size that lands on ``t_final`` (secant
            iteration on the clock), so that ``traj.t[-1] == t_final``.
        t0 : float
            Physical start time.
        params : mapping, optional
        save_every : int
            Save every ``save_every``-th step (and the last). Dense output,
            events and ``t_eval`` interpolate between consecutive steps and
            need ``save_every=1``.
        on_failure : {"warn", "raise"}
            As for :meth:`Integrator.integrate`: a failed run returns the
            states before the failing step with ``success = False`` and a
            warning, or (``"raise"``) raises.
        dense_output : bool
            Attach ``traj.sol``: positions, velocities and momenta at any
            physical time of the run, the Hermite interpolant through the
            nodes :math:`(t_k, q_k, v_k)` (:mod:`galerkin_vi.run.dense`; the
            nodes are not equally spaced). It has the method's order in the
            fictitious step: measured on Kepler e = 0.7 with Gauss(2) (order
            4), the error between the steps falls 16x when ``h`` halves.
        t_span : (float, float), optional
            ``(t0, t_final)``, instead of ``t0`` and ``t_final``.
        events : Event, expression, callable or a list of them, optional
            Zeros of :math:`g(t, q, v)` in physical time and velocities
            (:mod:`galerkin_vi.run.events`: ``terminal``, ``direction``,
            ``exact``), located on the dense output; ``traj.t_events`` ...
            ``p_events``. A terminal event ends the run at the event with
            ``status`` TERMINATED (the states after it dropped); the run is
            watched in chunks of at most 4096 steps, so it stops soon after
            the event. ``exact=True`` refines the time with a step of the
            method cut (in fictitious time) so that its clock lands on it.
        t_eval : array_like, optional
            Physical times at which to return the states (the dense output
            there; ``tau`` and ``clock_momentum`` interpolated too), in the
            run's span and direction. With ``n_steps`` the span is known only
            after the run: times past its end are an error then.
        progress : bool or None
            A progress bar (tqdm): always, never, or (None) for runs predicted
            to take over 2 s when stderr is a terminal. Ctrl-C ends the run
            with the states computed so far (their dense output and events
            included), ``status`` INTERRUPTED and a warning, whatever
            ``on_failure`` says.
        project : bool
            Accepted for the signature of :meth:`Integrator.integrate`; the
            Poincaré transformation applies to systems without constraints,
            so there is nothing to project onto and ``True`` is an error.
        tangent, sensitivity
            Accepted for the signature of :meth:`Integrator.integrate`; not
            carried by adaptive runs (a ValueError says why).

        Returns
        -------
        AdaptiveTrajectory
            States at the physical times ``t`` (not equally spaced), with
            ``tau`` the fictitious times.

        Raises
        ------
        ConvergenceError
            With ``on_failure="raise"``, when a step's iteration fails: ``.partial`` is the
            :class:`AdaptiveTrajectory` of the states before it, ``.t`` the
            physical time of the last good state, ``.step`` the failing
            fictitious step.
        """
        check_failure_mode(on_failure)
        if tangent is not None or sensitivity is not None:
            raise ValueError(
                "tangent and sensitivity are not carried by adaptive runs: their steps are "
                "equal in fictitious time, and varying the start moves the physical times of "
                "the saved rows; use Integrator.integrate with a fixed step"
            )
        if project:
            raise ValueError(
                "project=True needs a system with constraints; the Poincaré time "
                "transformation applies to systems without them"
            )
        h = fictitious_step(h)
        t0, t_final = physical_span(t_span, t0, t_final, n_steps, h)
        save_every = save_interval(save_every)
        if progress is not None and not isinstance(progress, bool):
            raise TypeError(f"progress must be True, False or None, got {progress!r}")
        outputs = OutputRequest.of(self.system, dense_output, events, t_eval, t0, t_final, h)
        if outputs.dense and save_every != 1:
            what = "events are located" if outputs.events else "dense output interpolates"
            raise ValueError(
                f"{what} between consecutive steps: it needs save_every=1, got {save_every}"
            )
        qh, ph, extended_params, prm = self._start(q0, v0, p0, t0, params)
        terminal = terminal_stop(outputs.events, outputs.functions, prm)
        stop = None if terminal is None else (lambda run: terminal(self._physical(run, prm)))
        try:
            run, interrupted = self._drive(
                qh, ph, h, n_steps, t_final, extended_params, save_every, stop, progress
            )
        except ConvergenceError as exc:
            return self._failed(exc, prm, outputs, on_failure, extended_params)
        traj = self._trajectory(run, prm)
        if interrupted:
            message = (
                f"{RunStatus.INTERRUPTED.cause} at t = {traj.t[-1]:.6g} (fictitious step "
                f"{traj.n_steps}); the states computed so far are kept"
            )
            traj = replace(traj, status=RunStatus.INTERRUPTED, message=message)
        traj = self._with_outputs(traj, outputs, extended_params)
        if interrupted:
            warnings.warn(traj.message, RunFailureWarning, stacklevel=2)
        return traj

    def integrate_many(
        self,
        q0s: ArrayLike,
        v0s: ArrayLike | None = None,
        p0s: ArrayLike | None = None,
        *,
        params=None,
        executor: Executor | None = None,
        workers: int | None = None,
        **run,
    ) -> Ensemble:
        """:meth:`integrate` for many initial states and/or parameter sets.

        One :meth:`integrate` call per member: each member's energy :math:`E`
        is its own, so the members are different extended systems' runs.

        Parameters
        ----------
        q0s : array_like, shape (m, n)
        v0s, p0s : array_like, shape (m, n) or (n,)
            Exactly one; a single row is used for every member (and a single
            ``q0s`` row likewise).
        params : mapping or sequence of mappings, optional
            As for :meth:`Integrator.integrate_many`.
        executor : concurrent.futures.Executor, optional
            Default: threads in this process (``workers``, default all cores).
            A process pool or Dask's ``Client.get_executor()`` receives blocks
            of members (system, method, g, options, starts, parameters); each
            block builds the integrator once and runs its members.
        workers : int, optional
            Threads of the default executor; with ``executor``, the members
            go in ``4 * workers`` blocks.
        **run
            As for :meth:`integrate` (``h``, ``n_steps`` or ``t_final``,
            ``events``, ``t_eval``, ``on_failure``, ...).

        Returns
        -------
        Ensemble
            The members' :class:`AdaptiveTrajectory` in order; ``.q`` and ``.p``
            stacked when all saved the same physical times (``t_final`` runs
            without ``t_eval`` generally do not: their steps follow g).
        """
        q, name, x = member_starts(q0s, v0s, p0s, self.system.n)
        m = q.shape[0]
        members = member_parameters(params, m)
        run.setdefault("progress", False)
        workers = workers or os.cpu_count() or 1
        if executor is None:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                futures = [
                    pool.submit(self.integrate, q[i], **{name: x[i]}, params=members[i], **run)
                    for i in range(m)
                ]
                return Ensemble.of([f.result() for f in futures])
        spec = (self.system, self.method, self.transform.g, self.options)
        edges = np.linspace(0, m, max(1, min(m, 4 * workers)) + 1).round().astype(int)
        futures = [
            executor.submit(adaptive_block, spec, q[a:b], name, x[a:b], members[a:b], run)
            for a, b in zip(edges[:-1], edges[1:], strict=True)
            if b > a
        ]
        return Ensemble.of([tr for f in futures for tr in f.result()])

    def stream(
        self,
        q0: ArrayLike,
        v0: ArrayLike | None = None,
        p0: ArrayLike | None = None,
        *,
        h: float,
        n_steps: int,
        chunk_steps: int = 100_000,
        t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        save_every: int = 1,
        on_failure: str = "warn",
    ) -> Iterator[AdaptiveTrajectory]:
        r""":meth:`integrate` of ``n_steps`` fictitious steps in chunks, yielded one by one.

        Memory stays bounded by one chunk however long the run. The chunks are
        those of :meth:`Integrator.stream` on the extended system (the first
        starts with the initial state, every later one after its first step;
        the energy :math:`E` of :math:`K = g\,(H - E)` is the run's throughout),
        each in physical time and coordinates.

        Parameters
        ----------
        chunk_steps : int
            Steps per chunk, a positive multiple of ``save_every``.
        Other parameters
            As for :meth:`integrate`.

        Yields
        ------
        AdaptiveTrajectory
            The chunks; after a failure (``on_failure="warn"``) the last one
            holds the failing chunk's states before the failing step.

        Raises
        ------
        ConvergenceError
            With ``on_failure="raise"``, with ``.partial`` in physical time.
        """
        check_failure_mode(on_failure)
        h = fictitious_step(h)
        qh, ph, extended_params, prm = self._start(q0, v0, p0, t0, params)
        chunks = self.integrator.stream(
            qh, p0=ph, h=h, n_steps=n_steps, chunk_steps=chunk_steps, params=extended_params,
            save_every=save_every, on_failure=on_failure,
        )  # fmt: skip
        return self._physical_chunks(chunks, prm)

    def _physical_chunks(self, chunks, prm) -> Iterator[AdaptiveTrajectory]:
        try:
            for chunk in chunks:
                yield self._trajectory(chunk, prm)
        except ConvergenceError as exc:
            raise self._physical_failure(exc, prm) from exc

    def step(
        self,
        q0: ArrayLike,
        p0: ArrayLike,
        h: float,
        t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        *,
        energy: float | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        r"""One step of the Poincaré map, ``(q_k, p_k, t_k) -> (q_{k+1}, p_{k+1}, t_{k+1})``.

        Parameters
        ----------
        q0, p0 : array_like, shape (n,)
            Position and (physical) momentum at physical time ``t0``.
        h : float
            The fictitious step (negative: backwards).
        energy : float, optional
            The energy :math:`E` of :math:`K = g\,(H - E)`; default
            :math:`H(q_0, p_0)`. Steps of one run keep the run's :math:`E`
            (:meth:`integrate` sets it once): give it to repeated calls.

        Returns
        -------
        q, p : ndarray, shape (n,)
        t : float
            The physical time after the step.
        """
        h = fictitious_step(h)
        qh, ph, extended_params, _ = self._start(q0, None, p0, t0, params)
        if energy is not None:
            if not (isinstance(energy, numbers.Real) and math.isfinite(energy)):
                raise ValueError(f"energy must be a finite real number, got {energy!r}")
            extended_params[ENERGY] = float(energy)
        q, p = self.integrator.step(qh, ph, h, 0.0, extended_params)
        n = self.system.n
        return q[:n].copy(), p[:n].copy(), float(q[n])

    # ------------------------------------------------------------ the run's stages
    def _drive(
        self, qh, ph, h, n_steps, t_final, params, save_every, stop, progress
    ) -> tuple[Trajectory, bool]:
        """The run of the extended system, and whether Ctrl-C ended it.

        A number of steps without a terminal event to watch is one call of the
        integrator (its own chunks, progress bar and Ctrl-C); runs to a physical
        time, or watched for a terminal event, go in chunks here.
        """
        if n_steps is not None and stop is None:
            run = self.integrator.integrate(
                qh, p0=ph, h=h, n_steps=n_steps, params=params, save_every=save_every,
                on_failure="raise", progress=progress,
            )  # fmt: skip
            return run, run.status == RunStatus.INTERRUPTED
        rows, interrupted = self._run_chunks(
            qh, ph, h, n_steps, t_final, params, save_every, stop, progress
        )
        return rows.trajectory(self.transform.extended, save_every), interrupted

    def _run_chunks(
        self, qh, ph, h, n_steps, t_final, params, save_every, stop, progress
    ) -> tuple[ExtendedRows, bool]:
        """Chunks of steps until ``n_steps``, a terminal event, or the clock passes
        ``t_final`` (then a landing step); the rows, and whether Ctrl-C ended the run.

        Steps past ``t_final`` in the last chunk are computed and dropped (their
        iterations still count in ``total_newton_iterations``: they were work).
        """
        rows = ExtendedRows.start(qh, ph)
        direction = 1.0 if h > 0 else -1.0
        largest = _MAX_CHUNK if stop is None else _WATCHED_CHUNK
        chunk = _FIRST_CHUNK if n_steps is None else min(_FIRST_CHUNK, n_steps)
        bar = ProgressBar(
            progress,
            abs(t_final - float(qh[-1])) if n_steps is None else n_steps,
            "step" if n_steps is not None else "time",
        )
        interrupted = False
        crossing = None  # the clocks around the step that passes t_final
        try:
            while chunk > 0:
                run = self._chunk(rows, h, chunk, params, save_every)
                clock = run.q[:, -1]
                past = np.zeros(0, dtype=np.int64)
                if t_final is not None:
                    past = np.flatnonzero((clock[1:] - t_final) * direction >= 0)
                # steps that stay before t_final (an interrupted chunk has fewer)
                before = rows.last_clock_before()
                rows.extend(run, int(past[0]) if past.size else len(run) - 1)
                if past.size:
                    j = int(past[0])
                    crossing = (float(clock[j - 1]) if j > 0 else before, float(clock[j + 1]))
                    break
                if run.status == RunStatus.INTERRUPTED:
                    interrupted = True
                    break
                if stop is not None and stop(run):
                    break
                bar.update(rows.steps if n_steps is not None else abs(clock[-1] - rows.first_clock))
                chunk = self._next_chunk(rows, h, n_steps, t_final, largest)
            if crossing is not None:
                self._land(rows, h, t_final, params, crossing)
            bar.update(rows.steps if n_steps is not None else abs(t_final - rows.first_clock))
        except KeyboardInterrupt:
            interrupted = True
        finally:
            bar.close()
        return rows, interrupted

    def _chunk(
        self, rows: ExtendedRows, h: float, steps: int, params, save_every: int
    ) -> Trajectory:
        """``steps`` steps from the last row; a failure raised with the rows so far as
        its ``.partial`` (the failing chunk's good steps included)."""
        try:
            run = self.integrator.integrate(
                rows.last_q, p0=rows.last_p, h=h, n_steps=steps, t0=rows.last_tau,
                params=params, on_failure="raise", progress=False,
            )  # fmt: skip
        except ConvergenceError as exc:
            before = rows.steps
            if exc.partial is not None:
                rows.extend(exc.partial, len(exc.partial) - 1)
            exc.step += before
            failed = exc.partial
            exc.partial = replace(
                rows.trajectory(self.transform.extended, save_every),
                status=failed.status if failed is not None else RunStatus.NO_CONVERGENCE,
                message=failed.message if failed is not None else str(exc),
            )
            raise
        rows.work += run.total_newton_iterations
        rows.worst = max(rows.worst, run.max_residual)
        return run

    @staticmethod
    def _next_chunk(rows: ExtendedRows, h: float, n_steps, t_final, largest: int) -> int:
        """Steps of the next chunk: what is left of ``n_steps``, or a prediction of the
        steps to ``t_final`` from the run's mean dt/dtau.

        The mean of the whole run so far, not of the last chunk, which may have
        ended at a close encounter (dt/dtau = g small) and would overestimate the
        steps still needed by up to the ratio of g's extremes. A chunk covers the
        prediction and ``_MARGIN`` of it more, so that most runs end in the chunk
        after the first (each chunk is a call of about 50 µs, and a restart of the
        extrapolated stages); it grows at most 4x, so a prediction from a short,
        unrepresentative start overshoots by at most 4x the steps done.
        """
        done = rows.steps
        if n_steps is not None:
            return min(n_steps - done, largest, 4 * done)
        rate = (float(rows.last_q[-1]) - rows.first_clock) / rows.last_tau
        need = (t_final - float(rows.last_q[-1])) / (rate * h) if rate > 0 else _FIRST_CHUNK
        return int(min(largest, 4 * done, max(_FIRST_CHUNK, (1 + _MARGIN) * need + 16)))

    def _land(self, rows: ExtendedRows, h: float, t_final: float, params, crossing: tuple) -> None:
        """Append one step of size in (0, h] whose clock lands on ``t_final``.

        ``crossing`` holds the clocks one step before the last row (None at the
        run's start) and one step after it, past ``t_final``: computed already,
        they start the secant iteration without a step.
        """
        before, after = crossing
        run, work = self._landing(
            rows.last_q, rows.last_p, rows.last_tau, h, t_final, params, known=(before, after)
        )
        rows.work += work
        rows.extend(run, 1)
        rows.last_q[-1] = t_final  # within a few ulps; exact for the caller

    def _landing(
        self, q, p, tau, h, target, params, known: tuple | None = None
    ) -> tuple[Trajectory, int]:
        r"""The step of size in (0, h] (or [h, 0)) from (q, p) whose clock lands on ``target``,
        and the iterations spent finding it.

        The clock after a step is monotone in its size (dt/dtau = g > 0); the
        secant method on it, safeguarded by bisection, takes 2-6 single steps.
        ``known = (t_{-1}, t_1)``: the clocks a step of ``-h`` before (None if
        unknown) and a step of ``h`` after (past ``target``). Then the step of
        ``h`` is not taken again, and the first size is the inverse quadratic
        interpolation through :math:`(t_{-1}, -h), (t_0, 0), (t_1, h)`, whose
        error is :math:`O(h^3)` against the linear one's :math:`O(h^2)`.
        """
        integ = self.integrator
        tiny = 4 * np.finfo(float).eps * max(1.0, abs(target))
        work = 0

        def miss(dtau: float) -> tuple[float, Trajectory]:
            nonlocal work
            run = integ.integrate(
                q, p0=p, h=dtau, n_steps=1, t0=tau, params=params, on_failure="raise"
            )
            work += run.total_newton_iterations
            return float(run.q[-1, -1]) - target, run

        lo, f_lo = 0.0, float(q[-1]) - target  # short of the target
        hi = h
        best = None
        if known is None:
            f_hi, best = miss(hi)  # at or past the target
            first = None
        else:
            f_hi = known[1] - target
            first = landing_guess(known[0], float(q[-1]), known[1], h, target)
        a, f_a, b, f_b = lo, f_lo, hi, f_hi
        for _ in range(_LANDING_ITERATIONS):
            if abs(f_b) <= tiny and best is not None:
                break
            if first is not None:
                guess, first = first, None
            elif f_b != f_a:
                guess = b - f_b * (b - a) / (f_b - f_a)
            else:
                guess = 0.5 * (lo + hi)
            if not min(lo, hi) < guess < max(lo, hi):
                guess = 0.5 * (lo + hi) if abs(f_b) > tiny else b
            f_guess, run = miss(guess)
            a, f_a, b, f_b = b, f_b, guess, f_guess
            best = run
            if f_guess * f_lo > 0:
                lo = guess
            else:
                hi = guess
        return best, work

    def _physical(self, run: Trajectory, prm: NDArray) -> Trajectory:
        """The states of an extended run as a plain physical :class:`Trajectory`."""
        n = self.system.n
        return Trajectory(
            t=run.q[:, n], q=run.q[:, :n], p=run.p[:, :n], newton_iterations=run.newton_iterations,
            max_residual=run.max_residual, system=self.system, params=prm,
        )  # fmt: skip

    def _failed(self, exc, prm, outputs, on_failure, params) -> AdaptiveTrajectory:
        """A failed run: its partial states in physical time with their outputs, returned
        with a warning or raised (a terminal event before the failure: returned)."""
        physical = self._physical_failure(exc, prm)
        if physical.partial is None:
            raise physical from exc
        partial = self._with_outputs(physical.partial, outputs, params)
        if partial.success:
            return partial
        if on_failure == "raise":
            physical.partial = partial
            raise physical from exc
        return failed_run(
            partial, on_failure, step=physical.step, t=physical.t, residual=physical.residual,
            stacklevel=4,
        )  # fmt: skip

    # ------------------------------------------------------------ outputs
    def _with_outputs(
        self, traj: AdaptiveTrajectory, outputs: OutputRequest, params
    ) -> AdaptiveTrajectory:
        """``traj`` with its dense output, events and rows at ``t_eval``, as asked."""
        if not outputs.dense:
            return traj
        if len(traj) < 2:
            return apply_events(traj, outputs.events, []) if outputs.events else traj
        full = replace(traj, sol=traj.dense())
        traj = full
        if outputs.events:
            traj = self._with_events(full, outputs, params)
        if outputs.times is not None:
            times = outputs.times
            if outputs.t_final is None and traj.status == RunStatus.COMPLETED:
                # a run of n_steps: its span is known now
                times = requested_times(times, float(traj.t[0]), float(traj.t[-1]), outputs.h)
            traj = rows_at(traj, full, times, self.transform.rate(full.q, full.params))
        return traj

    def _with_events(self, traj: AdaptiveTrajectory, outputs: OutputRequest, params):
        """``traj`` with its events located in physical time, cut at the first terminal one."""
        system, prm = self.system, traj.params
        prm_map = dict(zip(system.params, prm, strict=True))
        n = system.n

        def method_step(k: int, dt: float):
            # a step of the method from node k whose clock lands on t_k + dt (exact events)
            if dt == 0.0:
                q, p = traj.q[k], traj.p[k]
            else:
                qh = np.append(traj.q[k], traj.t[k])
                ph = np.append(traj.p[k], traj.clock_momentum[k])
                target = float(traj.t[k] + dt)
                run, _ = self._landing(qh, ph, float(traj.tau[k]), outputs.h, target, params)
                q, p = run.q[-1, :n], run.p[-1, :n]
            return q.copy(), system.inverse_legendre(q, p, traj.t[k] + dt, prm_map)

        records = locate_events(outputs.events, outputs.functions, traj.sol, prm, method_step)
        cut = apply_events(traj, outputs.events, records)
        if cut.status != RunStatus.TERMINATED or traj.status == RunStatus.TERMINATED:
            return cut
        k = len(cut.t) - 2  # the event lies in (t_k, t_k+1] of traj
        rates = self.transform.rate(traj.q[k : k + 2], prm)
        tau_event = fictitious_times(traj.t[k : k + 2], traj.tau[k : k + 2], rates, cut.t[-1:])
        return replace(
            cut,
            tau=np.append(traj.tau[: k + 1], tau_event),
            clock_momentum=np.append(traj.clock_momentum[: k + 1], traj.clock_momentum[k]),
        )

    def _physical_failure(self, exc: ConvergenceError, prm: NDArray) -> ConvergenceError:
        """``exc`` of the extended system, its partial run in physical time and coordinates."""
        partial = None if exc.partial is None else self._trajectory(exc.partial, prm)
        t = exc.t if partial is None else float(partial.t[-1])
        cause = exc if partial is None else exc.partial.message
        message = (
            f"in fictitious time tau: {cause} The failing step starts at physical time "
            f"t = {t:.6g}. A smaller h, or a g that is smaller where the motion is fast, may help."
        )
        if partial is not None:
            partial = replace(partial, message=message)
        return ConvergenceError(
            f"{message} .partial holds the states before it in physical time.",
            step=exc.step, t=t, residual=exc.residual, partial=partial,
        )  # fmt: skip


def landing_guess(t_before: float | None, t_0: float, t_after: float, h: float,
                  target: float) -> float:  # fmt: skip
    r"""The fictitious size :math:`\sigma \in (0, h)` at which the clock reaches ``target``.

    Inverse quadratic interpolation of :math:`\tau(t)` through
    :math:`(t_{-1}, -h), (t_0, 0), (t_1, h)` (the clocks of three consecutive steps),

    .. math::

        \sigma = -h\,\frac{(T - t_0)(T - t_1)}{(t_{-1} - t_0)(t_{-1} - t_1)}
                 + h\,\frac{(T - t_{-1})(T - t_0)}{(t_1 - t_{-1})(t_1 - t_0)},

    or the linear one through the last two when ``t_before`` is None or the
    three clocks are not strictly monotone; clipped into the open bracket.
    """
    linear = h * (target - t_0) / (t_after - t_0)
    if t_before is None or not (t_before - t_0) * (t_0 - t_after) > 0:
        return linear
    back = (target - t_0) * (target - t_after) / ((t_before - t_0) * (t_before - t_after))
    ahead = (target - t_before) * (target - t_0) / ((t_after - t_before) * (t_after - t_0))
    sigma = h * (ahead - back)
    return sigma if 0 < sigma / h < 1 else linear


def adaptive_block(spec: tuple, q0s, name: str, x, params: Sequence, run: dict) -> list:
    """Members of :meth:`AdaptiveIntegrator.integrate_many` in an executor's worker.

    ``spec`` = (system, method, g, options) builds the integrator once per block
    (its point functions loaded from the disk cache).
    """
    system, method, g, options = spec
    adaptive = AdaptiveIntegrator(system, method, g=g, **options)
    return [
        adaptive.integrate(q, **{name: xi}, params=prm, **run)
        for q, xi, prm in zip(q0s, x, params, strict=True)
    ]
