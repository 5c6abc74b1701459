r"""The integrator: a system, a method and a backend, run over many steps."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from functools import cached_property

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from . import codegen
from .method.composition import Composition
from .method.galerkin import Galerkin
from .model.system import LagrangianSystem
from .reference import resolve_backend
from .run import options
from .run.dispatch import integrate_run, position_step, run_spec_for, tangent_spec_for
from .run.ensemble import integrate_many
from .run.loop_choice import check_composition, loop_path
from .run.points import point_addresses, point_functions, point_source, spec_summary
from .run.spec import RunSpec
from .run.stream import checked_stream
from .run.trajectory import Trajectory

__all__ = ["Integrator"]


class Integrator:
    r"""Galerkin variational integrator of a :class:`LagrangianSystem`.

    Parameters
    ----------
    system : LagrangianSystem
    method : Galerkin or Composition, optional
        Defaults to ``Galerkin(2)`` (order 4). A :class:`~galerkin_vi.Composition`
        (explicit kick–drift splittings and compositions of Störmer–Verlet, orders
        2–10) needs a separable Lagrangian with constant mass matrix, no
        constraints, contacts or velocity-dependent forces, and the numba backend;
        a splitting also a term :math:`a\cdot v` constant in time.
    backend : {"auto", "numba", "numpy"}
        ``"numba"`` runs the whole time loop in compiled code (the loops
        compiled once per machine, the system's point functions once per system,
        both cached on disk); ``"numpy"`` is the slow,
        independent reference. ``"auto"`` picks numba when available.
    tol : float
        Relative Newton increment tolerance; below it the iteration continues
        until the increment is zero (below eps**2 times the size of q) or stops
        decreasing (no round-off drift).
    maxiter : int
        Newton iteration cap per step (at most 255).
    specialize : "auto", bool or "system"
        Let the structure of the problem pick a cheaper time loop (see
        :attr:`kernel_path`); ``False`` forces the general Newton loop. ``"auto"``
        (default): ``True``, and ``"system"``'s loops where compiled already (in this
        process or on disk), compiled in the background, never waited for, once a
        system is run again or for 1e5 steps (:mod:`galerkin_vi.run.generated_choice`;
        the trajectory's ``kernel_path`` says which loop ran).
        ``"system"`` also runs the stage-form loop (``"separable"`` path) of a small
        system with a diagonal constant mass as a loop generated for that system and
        method (:mod:`galerkin_vi.codegen.method_steps`: its coordinates, stage values
        and tables as scalars, its force inline; the same steps bit for bit up to a
        step that needs Newton, in half to two thirds of the time where a step is a
        few sweeps of a cheap force), at the price of compiling it: 0.7–3.5 s once per
        system, method and machine, cached on disk. Past 24 stage unknowns (implicit
        points times coordinates) the loop is generated for the system alone
        (:mod:`galerkin_vi.codegen.stage_steps`, 1.5–4 s once per system). With a
        mass matrix that varies and a closed-form velocity, ``"system"`` runs the
        ``"varying_mass"`` sweep as a loop generated for the system and method
        (:mod:`galerkin_vi.codegen.velocity_steps`; 1.6–3.2 s, 0.63–0.73 of the
        time), and with a force that is a pair potential alone (repeated terms, at
        most 24 coordinates) the explicit path as a loop with the pairs unrolled,
        their square roots and divisions four pairs at a time
        (:mod:`galerkin_vi.codegen.lanes`; about 3 s, 0.6 of the time). With either
        true value the explicit path (compositions, Störmer–Verlet) of a system
        without repeated terms runs the loop generated for the system, which
        compiles in a fraction of a second;
        ``False`` keeps the shared loops (compositions still take the explicit path).
        Every generated loop takes the shared loop's steps bit for bit (up to the sign
        of an exact zero).
    fixed_point : bool or "persistent"
        With a mass matrix that varies, iterate the stage velocities by fixed
        point (the ``"varying_mass"`` loop; default) rather than by Newton. The
        fixed point wins at every step the double pendulum converges at (s = 3-6)
        and at the small fictitious steps of :class:`AdaptiveIntegrator`, where
        Newton's factors carried across steps stop short of round-off. With
        ``True`` it hands the rest of the run (or chunk) over to Newton when a
        sweep contracts by less than 0.3 or the sweeps per step average over 7
        more than the stages; with ``"persistent"`` (the adaptive integrator's
        default) only when the sweeps diverge or would exceed ``maxiter``
        (:class:`galerkin_vi.run.loop_choice.HandOver`). Where the sweep solves the
        momentum equations in closed form (L quadratic in v with M diagonal or
        n <= 2: a sweep costs a quarter to a third of a Newton iteration), ``True``
        keeps the fixed point as ``"persistent"`` does.

    Notes
    -----
    One step of the position–momentum map :math:`(q_k, p_k) \mapsto (q_{k+1},
    p_{k+1})` solves, for the control points :math:`q^1..q^s`,

    .. math::

        p_k + \frac{\partial L_d}{\partial q^0} = 0, \qquad
        \frac{\partial L_d}{\partial q^\nu} = 0 \ (0 < \nu < s), \qquad
        p_{k+1} = \frac{\partial L_d}{\partial q^s},

    by Newton's method with the exact Jacobian, started from the previous
    step's polynomial extrapolated.
    """

    def __init__(
        self,
        system: LagrangianSystem,
        method: Galerkin | None = None,
        backend: str = "auto",
        tol: float = 1e-14,
        maxiter: int = 30,
        specialize: bool | str = "auto",
        fixed_point: bool | str = True,
    ) -> None:
        # checked in the order of the arguments; the backend is resolved here, not in
        # run.options, so that its fallback warning names the caller's line
        method = options.integrator_method(system, method)
        tol, maxiter = options.check_iteration(tol, maxiter)
        if isinstance(method, Composition):
            check_composition(system, method, resolve_backend(backend))
        else:
            options.check_galerkin(system, method)
        self.system = system
        self.method = method
        self.backend = resolve_backend(backend)
        self.tol = tol
        self.maxiter = maxiter
        self.specialize = options.resolve_specialize(specialize)
        self.fixed_point = options.check_fixed_point(fixed_point)

    @property
    def kernel_path(self) -> str:
        """Which time loop runs: constrained, explicit, linear, separable, varying_mass or
        newton (:func:`galerkin_vi.run.loop_choice.loop_path` says when each)."""
        return loop_path(
            self.system, self.method, self.backend, self.specialize, self.fixed_point,
            lambda: self._summary.banded,
        )  # fmt: skip

    @property
    def uses_constant_mass(self) -> bool:
        r"""Whether the stage-form loop starts each step with the constant-mass iteration.

        True on the ``"separable"`` path (constant :math:`M`). The iteration
        matrix is then :math:`I \otimes M`, the Jacobian without its
        :math:`h^2 L_{qq}` terms: fixed-point iteration, one gradient per implicit
        point and one solve with :math:`M` (a division when :math:`M` is diagonal)
        per sweep, no Hessian and no LU. It contracts by
        :math:`O(h^2\|M^{-1}L_{qq}\|)`; when an increment is not at least
        ``min(0.01 u n, 0.2)`` times the one before, full Newton takes over for
        the rest of the step and the next 64 steps. A sweep costs less than a
        Newton iteration at any size, and with the first iterate from the
        previous step's extrapolated forces the sweeps per step equal the
        hand-written fixed-point kernels' (docs/performance.md).
        """
        return self.kernel_path == "separable"

    def __repr__(self) -> str:
        return f"Integrator({self.system!r}, {self.method!r}, backend={self.backend!r})"

    def __getstate__(self) -> dict:
        # the run specs hold addresses of compiled code, valid in this process only;
        # a copy derives them again on first use
        state = self.__dict__.copy()
        for name in ("_spec", "_summary", "run_spec", "tangent_run_spec"):
            state.pop(name, None)
        return state

    @cached_property
    def _spec(self) -> codegen.KernelSpec:
        return codegen.kernel_spec(self.system)

    @cached_property
    def _summary(self) -> codegen.SpecSummary:
        """What the loops need of the spec, kept with the system's analysis cache."""
        return spec_summary(self.system, lambda: self._spec)

    @property
    def _points(self):
        return point_functions(self.system, self._summary.key, lambda: self._spec)

    @property
    def source(self) -> str:
        """Source of the system's generated point functions (what is compiled per system).

        The time loops are not generated: they are the modules of
        :mod:`galerkin_vi.loops`, the same for every system.
        """
        return self._points.source if self.backend == "numba" else point_source(self._spec)

    @cached_property
    def run_spec(self) -> RunSpec:
        """The frozen description of this integrator's runs (:mod:`galerkin_vi.run.spec`).

        Built on the first run and kept: the point functions' addresses cost about
        0.2 ms to look up, which many short runs (adaptive landing steps,
        ensembles, ``step``, event and contact cuts) would pay every time.
        """
        return run_spec_for(
            self.system, self.method, self.backend, self.kernel_path, self.tol, self.maxiter,
            summary=lambda: self._summary, points=lambda: self._points,
            constant_mass=self.uses_constant_mass, fixed_point=self.fixed_point,
            specialize=self.specialize,
        )  # fmt: skip

    @cached_property
    def tangent_run_spec(self) -> RunSpec:
        """The run spec of the loop that carries the tangent map: the explicit loop's (with
        the point Hessian) for a :class:`~galerkin_vi.Composition`, the general Newton
        loop's (or the constrained loop's) for a Galerkin method."""
        return tangent_spec_for(
            self.system, self.method, self.backend, self.tol, self.maxiter,
            summary=lambda: self._summary, points=lambda: self._points,
            constant_mass=self.uses_constant_mass, run_spec=lambda: self.run_spec,
        )  # fmt: skip

    def compiled_point_functions(self, names: tuple[str, ...]) -> tuple[tuple[int, ...], tuple]:
        """(addresses, traits) of the system's compiled point functions ``names``.

        For compiled solvers outside the time loops (:mod:`galerkin_vi.action`):
        the addresses fill the slots of :mod:`galerkin_vi.loops.point` (0 where
        not asked for), the traits are the loops' (:mod:`galerkin_vi.loops.traits`).
        Numba backend only; the points are compiled (or loaded) on first use.
        """
        return point_addresses(self.backend, lambda: self._points, lambda: self._summary, names)

    @property
    def uses_banded_storage(self) -> bool:
        """Whether the point functions write second derivatives in banded (pattern) storage."""
        return bool(self._summary.banded)

    # ------------------------------------------------------------------- run
    def integrate(
        self, q0: ArrayLike, v0: ArrayLike | None = None, p0: ArrayLike | None = None, *,
        h: float, n_steps: int | None = None, t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        save_every: int = 1, project: bool = False, on_failure: str = "warn",
        dense_output: bool = False, t_span: tuple[float, float] | None = None,
        events: object = None, progress: bool | None = None, t_eval: ArrayLike | None = None,
        contact_mode: str = "auto", tangent: bool | ArrayLike | None = None,
        sensitivity: Sequence[sp.Symbol | str] | None = None, renormalize_every: int = 0,
    ) -> Trajectory:  # fmt: skip
        """Integrate ``n_steps`` steps of size ``h`` from ``q0`` and ``v0`` or ``p0``.

        Parameters
        ----------
        q0 : array_like, shape (n,)
        v0, p0 : array_like, shape (n,)
            Exactly one: initial velocities (mapped by the continuous Legendre
            transform) or momenta.
        h : float
            Step size (negative integrates backwards). With ``t_span``, the
            largest size of equal steps that land on its end: ``h`` is reduced
            to ``(t1 - t0) / ceil((t1 - t0) / h)``.
        n_steps : int
            Number of steps; or give ``t_span``.
        t0 : float
        params : mapping, optional
            Parameter values overriding the system's defaults (symbols or names).
        save_every : int
            Save every ``save_every``-th state (and always the last).
        project : bool
            Constrained systems only: move ``q0`` to a nearby point of the
            constraint manifold (Gauss–Newton) and the momentum onto the
            hidden constraint. Without it, initial data that violate either by
            more than :data:`galerkin_vi.model.constraints.INITIAL_TOLERANCE` are
            rejected; within it, ``q0`` is kept and only the momentum is
            projected (exactly, a change of the size of the violation).
        on_failure : {"warn", "raise"}
            What a failed run does (the stage equations do not converge, their
            Jacobian is singular, NaN or inf appear). ``"warn"`` (default, as
            :func:`scipy.integrate.solve_ivp`): return the states computed before
            the failing step with ``success = False``, a negative ``status`` and a
            ``message`` naming the step, time and cause, and emit a
            :class:`~galerkin_vi.RunFailureWarning`. ``"raise"``: raise
            :class:`~galerkin_vi.ConvergenceError` with that trajectory as
            ``.partial``.
        dense_output : bool
            Attach ``Trajectory.sol``, positions, velocities and momenta at any
            time of the run, from Hermite interpolation of the nodal data at
            the method's order (:mod:`galerkin_vi.run.dense`). Needs every step
            saved (``save_every=1``).
        t_span : (float, float), optional
            Integrate from ``t_span[0]`` (instead of ``t0``) to ``t_span[1]``
            with equal steps of at most ``|h|``; instead of ``n_steps``.
        events : Event, expression, callable or a list of them, optional
            Zeros of :math:`g(t, q, v)` to locate (:mod:`galerkin_vi.run.events`,
            solve_ivp's conventions: ``terminal``, ``direction``). Their times
            and states are in ``Trajectory.t_events``, ``q_events``,
            ``v_events``, ``p_events``, one array per event; a terminal event
            ends the trajectory at the event, ``status`` 1. Needs
            ``save_every=1``; the dense output is attached.
        t_eval : array_like, optional
            Times at which to return the states, in the run's span and in the
            direction of integration: the rows of the result are the dense
            output there (positions, and the momenta of its velocities);
            ``Trajectory.sol`` keeps every step. Needs ``save_every=1``.
        progress : bool or None
            A progress bar (tqdm): always, never, or (None, default) for runs
            predicted to take over 2 s when stderr is a terminal. Runs over
            5040 steps go in chunks whose size depends on the system only
            (:mod:`galerkin_vi.run.chunks`); Ctrl-C between them ends the run
            with the states computed so far (their dense output and events
            included), ``status`` :attr:`RunStatus.INTERRUPTED` and a warning,
            whatever ``on_failure`` says.
        contact_mode : {"auto", "event", "time-stepping"}
            Systems with contacts (:mod:`galerkin_vi.contact`): isolated impacts
            located and applied at the method's order, switching to a
            complementarity problem per step where a contact persists or its
            impacts accumulate and back where it releases (``"auto"``,
            default); isolated impacts only, stopping with status
            ``CONTACT_PERSISTS`` where they cannot go on (``"event"``); or a
            complementarity problem in every step, impacts still cut out of
            the steps exactly (``"time-stepping"``).
        tangent : True or array_like of shape (2n, r), optional
            Carry the tangent map :math:`\\Phi_k = \\partial(q_k, p_k)/\\partial(q_0, p_0)`
            (``True``) or its action on r directions V: ``Trajectory.tangent``,
            shape (rows, 2n, r). Implicit function theorem on each step's stage
            equations with their exact Jacobian at the solution
            (:mod:`galerkin_vi.loops.tangent`): one solve per direction and step;
            a :class:`~galerkin_vi.Composition` differentiates its explicit sub-steps
            exactly (:mod:`galerkin_vi.loops.explicit_tangent`: the states bit for bit
            those of the run without it).
            The row of a terminal event holds the derivative at the event time
            held fixed. With ``v0`` the start's momentum is :math:`L_v(q_0, v_0)`:
            the tangent is still with respect to :math:`(q_0, p_0)`, the
            sensitivity at fixed :math:`v_0`.
        sensitivity : sequence of parameter symbols or names, optional
            Carry :math:`\\partial(q_k, p_k)/\\partial\\theta`: ``Trajectory.sensitivity``,
            shape (rows, 2n, P). A Composition refuses parameters of the mass matrix.
        renormalize_every : int
            With ``tangent``: orthonormalise the frame every so many steps
            (Benettin's method) and keep the log-growths and MEGNO
            (``Trajectory.variations``; :func:`galerkin_vi.lyapunov_spectrum`).

        Returns
        -------
        Trajectory
            ``status`` 0 and ``success`` True when all steps were taken.

        Raises
        ------
        ConvergenceError
            With ``on_failure="raise"``, if a step fails; ``.partial`` holds every
            saved state before the failing step and the last good state.
        ValueError
            For bad arguments, and for constrained systems when the initial data
            are inconsistent (see ``project``) or the constraints are redundant.

        Warns
        -----
        InstabilityWarning
            When the momenta over the last tenth of the saved states exceed
            those over the first tenth by more than ``INSTABILITY_GROWTH``
            (``1e6``; at least 10 saved states, autonomous unforced systems):
            the exponential growth of a step size past the stability limit.

        Notes
        -----
        A system with ``contacts`` runs through :mod:`galerkin_vi.contact`
        (impacts located and applied; ``Trajectory.impacts``).
        """
        return integrate_run(
            self, q0, v0, p0, h=h, n_steps=n_steps, t0=t0, params=params, save_every=save_every,
            project=project, on_failure=on_failure, dense_output=dense_output, t_span=t_span,
            events=events, progress=progress, t_eval=t_eval, contact_mode=contact_mode,
            tangent=tangent, sensitivity=sensitivity, renormalize_every=renormalize_every,
        )  # fmt: skip

    def stream(
        self, q0: ArrayLike, v0: ArrayLike | None = None, p0: ArrayLike | None = None, *,
        h: float, n_steps: int, chunk_steps: int = 100_000, t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        save_every: int = 1, project: bool = False, on_failure: str = "warn",
        tangent: bool | ArrayLike | None = None,
        sensitivity: Sequence[sp.Symbol | str] | None = None,
    ) -> Iterator[Trajectory]:  # fmt: skip
        """:meth:`integrate` in chunks of ``chunk_steps`` steps, yielding each chunk.

        Memory stays bounded by one chunk however long the run: process each
        chunk (energy, plots, a file) and drop it. The first chunk starts with
        the initial state; every later chunk starts after its first step, so
        that the chunks together hold exactly the rows one :meth:`integrate`
        call would save. Each chunk continues from the state the previous one
        ended in (angles from their reduced value, ``Trajectory.q_reduced``),
        so the result equals one long run up to round-off at the joins (each
        chunk starts Newton afresh, from a linear guess instead of the previous
        step's polynomial, and without the compensation bits of the summed
        positions: near the edge of convergence a chunked run may fail at a
        slightly different step than one run).

        Parameters
        ----------
        chunk_steps : int
            Steps per chunk, a positive multiple of ``save_every``.
        tangent, sensitivity
            As for :meth:`integrate`, carried across the chunks (chaos
            indicators' ``renormalize_every`` is for :meth:`integrate`, whose
            chunks carry their sums).
        Other parameters
            As for :meth:`integrate`.

        Yields
        ------
        Trajectory
            The chunks. After a failure (``on_failure="warn"``) the last one
            holds the failing chunk's states before the failing step, with the
            failure's ``status`` and ``message`` (steps counted from the start
            of the run), and the stream ends.

        Raises
        ------
        ConvergenceError
            With ``on_failure="raise"``, as :meth:`integrate`, with ``.step``
            counted from the start of the run; ``.partial`` holds the failing
            chunk's states after the last yielded one (earlier chunks were
            already yielded).
        ValueError
            For bad arguments, when ``stream`` is called.
        """
        return checked_stream(
            self.integrate, self.system, q0, v0, p0, h=h, n_steps=n_steps,
            chunk_steps=chunk_steps, t0=t0, params=params, save_every=save_every,
            project=project, on_failure=on_failure, tangent=tangent, sensitivity=sensitivity,
        )  # fmt: skip

    def integrate_many(
        self, q0s: ArrayLike, v0s: ArrayLike | None = None, p0s: ArrayLike | None = None, *,
        params=None, executor=None, workers: int | None = None, **run,
    ):  # fmt: skip
        """:meth:`integrate` for many initial states and/or parameter sets at once.

        Runs of one compiled call (at most
        :data:`~galerkin_vi.run.chunks.FIRST_CHUNK` steps) without events, dense
        output or ``t_eval`` go through the compiled member loop
        (:mod:`galerkin_vi.run.ensemble`): a few microseconds per member besides
        its steps. Others are one :meth:`integrate` call per member.

        Parameters
        ----------
        q0s : array_like, shape (m, n)
        v0s, p0s : array_like, shape (m, n) or (n,)
            Exactly one; a single row is used for every member (and a single
            ``q0s`` row likewise).
        params : mapping or sequence of mappings, optional
            Parameter values: each a number or an array of m values (a sweep),
            or one mapping per member. Never compiles anything.
        executor : concurrent.futures.Executor, optional
            Where the members run. Default: threads (``workers``, default all
            cores) in this process; the compiled loops release the GIL. A
            process pool or Dask's ``Client.get_executor()`` receives blocks of
            members (system, method, starts, parameters); each worker process
            builds the integrator once from the cache and returns arrays.
        workers : int, optional
            Threads of the default executor (default: all cores); with
            ``executor``, the members are sent in ``4 * workers`` blocks.
        **run
            As for :meth:`integrate` (``h``, ``n_steps`` or ``t_span``,
            ``save_every``, ``events``, ``on_failure``, ...).

        Returns
        -------
        Ensemble
            ``.trajectories`` in the members' order, each bitwise the one-by-one
            run's; ``.q``, ``.p`` stacked (m, N, n) when the saved times agree;
            ``.success`` and ``.status`` per member.
        """
        return integrate_many(
            self, q0s, v0s, p0s, params=params, executor=executor, workers=workers, **run
        )

    def step(
        self, q0: ArrayLike, p0: ArrayLike, h: float, t0: float = 0.0, params=None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One step ``(q_k, p_k) -> (q_{k+1}, p_{k+1})``, the impacts inside it applied."""
        traj = self.integrate(q0, p0=p0, h=h, n_steps=1, t0=t0, params=params, on_failure="raise")
        return traj.q[-1].copy(), traj.p[-1].copy()

    def step_del(
        self, q0: ArrayLike, q1: ArrayLike, h: float, t0: float = 0.0, params=None
    ) -> NDArray[np.float64]:
        r"""One step of the position-only DEL form, ``(q_{k-1}, q_k) -> q_{k+1}``.

        Solves the discrete Euler–Lagrange equation

        .. math::

            D_2 L_d(q_{k-1}, q_k) + D_1 L_d(q_k, q_{k+1}) = 0

        together with the interior stationarity conditions of both steps, as
        one Newton system in the interior points of step :math:`k-1` and all
        free control points of step :math:`k`. ``q0`` is at time ``t0``.
        """
        return position_step(self, q0, q1, h, t0, params)
