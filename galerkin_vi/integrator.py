r"""The integrator: a system, a method and a backend, run over many steps."""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from . import codegen
from .errors import (
    ConvergenceError,
    DegenerateLagrangianError,
    InstabilityWarning,
    RunFailureWarning,
)
from .method.galerkin import Galerkin
from .method.stage_form import has_stage_form, separable_tables
from .method.velocity_stages import MIN_FIXED_POINT_DEGREE, has_velocity_stages, varying_mass_tables
from .model.constraints import consistent_initial_state, project_momentum
from .model.system import LagrangianSystem, is_regular
from .newton import CONVERGED, newton_solve
from .reference import numpy as numpy_backend
from .reference import numpy_constrained, resolve_backend
from .run.chunks import run_in_chunks
from .run.ensemble import integrate_many
from .run.events import apply_events, as_events, event_function, locate_events, terminal_stop
from .run.failures import check_failure_mode, failed_run
from .run.growth import EXPLOSIVE_GROWTH, INSTABILITY_GROWTH, explosive_row
from .run.status import RunStatus, loop_status
from .run.trajectory import Trajectory

__all__ = ["Integrator"]

# below this many stage unknowns the constant-mass iteration does not pay (measured)
MIN_UNKNOWNS_CONSTANT_MASS = 1


def state_vector(name: str, x: ArrayLike, n: int) -> NDArray[np.float64]:
    """``x`` as a finite float array of shape (n,); ``name`` in the error otherwise."""
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers, got {x!r}") from exc
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf: {arr}")
    return arr


class Integrator:
    r"""Galerkin variational integrator of a :class:`LagrangianSystem`.

    Parameters
    ----------
    system : LagrangianSystem
    method : Galerkin, optional
        Defaults to ``Galerkin(2)`` (order 4).
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
    specialize : bool
        Let the structure of the problem pick a cheaper time loop (see
        :attr:`kernel_path`); ``False`` forces the general Newton loop.
    fixed_point : bool
        With a mass matrix that varies, iterate the stage velocities by fixed
        point (the ``"varying_mass"`` loop; default) rather than by Newton. The
        fixed point wins at moderate steps (double pendulum, s = 3-4); at steps
        near its convergence limit (the long fictitious steps of
        :class:`AdaptiveIntegrator`, which therefore passes ``False``) it hands
        over to Newton, and Newton alone is faster.

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
        specialize: bool = True,
        fixed_point: bool = True,
    ) -> None:
        if not isinstance(system, LagrangianSystem):
            raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
        method = Galerkin(2) if method is None else method
        if not isinstance(method, Galerkin):
            raise TypeError(f"method must be a Galerkin method, got {type(method).__name__}")
        if not (isinstance(tol, numbers.Real) and 0 < tol < 1):
            raise ValueError(f"tol must be a real number in (0, 1), got {tol!r}")
        if (
            isinstance(maxiter, bool)
            or not isinstance(maxiter, numbers.Integral)
            or not 1 <= maxiter <= 255
        ):
            raise ValueError(f"maxiter must be an int in [1, 255], got {maxiter!r}")
        if system.m and not method.collocated:
            raise ValueError(
                f"{method!r}: a constrained system needs collocated control and quadrature "
                "nodes, the constraints being imposed at the control points: use "
                f"Galerkin({method.degree}) (Lobatto nodes, gauss_lobatto({method.degree + 1}))"
            )
        self.system = system
        self.method = method
        self.backend = resolve_backend(backend)
        self.tol = float(tol)
        self.maxiter = int(maxiter)
        self.specialize = bool(specialize)
        self.fixed_point = bool(fixed_point)

    @property
    def kernel_path(self) -> str:
        r"""Which time loop runs: constrained, explicit, linear, separable, varying_mass or newton.

        ``"constrained"`` for every system with constraints (multipliers in the
        stage equations, momentum projected at each step's end; both backends).
        Otherwise, with the compiled backend and ``specialize=True`` (default):

        - ``"explicit"``: degree 1 with two Lobatto points on a separable
          :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)` (constant :math:`M`) is
          Störmer–Verlet in closed form, with :math:`M^{-1}` formed once and no Newton;
        - ``"linear"``: a Lagrangian quadratic in :math:`(q, v)` (constant
          Hessian) has linear stage equations: one LU factorisation per run and
          one triangular solve per step;
        - ``"separable"``: any other :math:`L = \tfrac12 v^TMv + a(t)\cdot v + U(t, q)`
          with constant :math:`M` and forces :math:`f(t, q)`: Newton on the
          stage increments at the implicit quadrature points only
          (:mod:`galerkin_vi.method.stage_form`; the :math:`s - 1` interior nodes for
          collocated Lobatto, the :math:`s` points for Gauss), momenta updated
          in increment form with compensated summation;
        - ``"varying_mass"``: any other :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v
          - U(t, q)` (a mass matrix that varies, or velocity couplings :math:`a(q)`;
          forces may depend on :math:`v`), stored dense, with Gauss quadrature of
          ``degree >= 3`` points (Gauss collocation): fixed-point iteration on the
          stage velocities with the exact mass matrix at every stage
          (:mod:`galerkin_vi.method.velocity_stages`), no Jacobian. A step on which the
          iteration contracts too slowly hands the run over to ``"newton"`` from the
          last saved state on;
        - ``"newton"``: the general Newton iteration (also the NumPy backend).
        """
        if self.system.m:
            return "constrained"
        if self.backend != "numba" or not self.specialize:
            return "newton"
        structure, method = self.system.structure, self.method
        if (
            structure.separable
            and structure.zero_fv
            and method.degree == 1
            and method.quadrature.family == "gauss_lobatto"
            and method.quadrature.npoints == 2
        ):
            return "explicit"
        if structure.quadratic:
            return "linear"
        if has_stage_form(self.system):
            return "separable"
        if (
            self.fixed_point
            and structure.quadratic_in_v
            and has_velocity_stages(method)
            and method.degree >= MIN_FIXED_POINT_DEGREE
            and not self._summary.banded
        ):
            return "varying_mass"
        return "newton"

    @property
    def uses_constant_mass(self) -> bool:
        r"""Whether the stage-form loop starts each step with the constant-mass iteration.

        True on the ``"separable"`` path (constant :math:`M`) with at least
        ``MIN_UNKNOWNS_CONSTANT_MASS = 1`` unknown, i.e. always. The iteration
        matrix is then :math:`I \otimes M`, the Jacobian without its
        :math:`h^2 L_{qq}` terms: fixed-point iteration, one gradient per implicit
        point and one solve with :math:`M` (a division when :math:`M` is diagonal)
        per sweep, no Hessian and no LU. It contracts by
        :math:`O(h^2\|M^{-1}L_{qq}\|)`; when an increment is not at least
        ``min(0.01 u n, 0.2)`` times the one before, full Newton takes over for
        the rest of the step and the next 64 steps. With the first iterate from the
        previous step's extrapolated forces and the bit-identical stopping rule
        it takes as many sweeps per step as the hand-written fixed-point kernels
        (``benchmarks/same_method.py``), and a sweep costs less than a Newton
        iteration at any size: measured on the pendulum (1-2 unknowns), full
        Newton 3.2-3.6 iterations and 450-750 ns per step against 3.9-4.7 sweeps
        and 290-430 ns.
        """
        if self.kernel_path != "separable":
            return False
        unknowns = separable_tables(self.method).implicit.size * self.system.n
        return unknowns >= MIN_UNKNOWNS_CONSTANT_MASS

    def __repr__(self) -> str:
        return f"Integrator({self.system!r}, {self.method!r}, backend={self.backend!r})"

    @cached_property
    def _spec(self) -> codegen.KernelSpec:
        return codegen.kernel_spec(self.system)

    @cached_property
    def _summary(self) -> codegen.SpecSummary:
        """What the loops need of the spec, kept with the system's analysis cache.

        A system seen by an earlier process then derives no spec and hashes no
        expressions (for a 60-mass chain, 0.3 s of SymPy printing).
        """
        from .codegen.compiled import numba_version, point_key

        stored = self.system.recalled("point_summary")
        if stored is not None and stored[0] == numba_version():
            return stored[1]
        summary = codegen.summarize(self._spec, point_key(self._spec))
        self.system.remember("point_summary", (numba_version(), summary))
        return summary

    @cached_property
    def _points(self):
        from .codegen.compiled import load_point_functions

        return load_point_functions(lambda: self._spec, self._summary.key)

    @property
    def source(self) -> str:
        """Source of the system's generated point functions (what is compiled per system).

        The time loops are not generated: they are the modules of
        :mod:`galerkin_vi.loops`, the same for every system.
        """
        if self.backend == "numba":
            return self._points.source
        key = codegen.signature(self._spec, "source", "")
        return codegen.render_module(self._spec, key)

    @cached_property
    def _loop_arguments(self):
        """The system's part of every loop's arguments: (fn, traits, pattern, periodic).

        Built on the first run and kept: looking up the compiled functions' addresses
        costs about 0.2 ms a call, which many short runs (adaptive landing steps,
        ensembles, ``step``) would pay every time.
        """
        from .loops.traits import AUTONOMOUS, BAND, HAS_FV, HAS_LQV, N_TRAITS

        spec = self._summary
        names = ("point_gradient",)
        if self.kernel_path != "explicit":
            names += ("point_hessian",)
        if self.kernel_path == "varying_mass":
            names += ("point_mass",)
        if spec.m:
            names += (
                "point_constraint",
                "point_constraint_jacobian",
                "point_constraint_rate",
                "point_constraint_hessian",
            )
        # tuples of ints, not arrays: passed by value into the loops' inlined helpers,
        # where every array argument costs an atomic reference count pair per call
        fn = tuple(int(address) for address in self._points.addresses(names))
        traits = [0] * N_TRAITS
        traits[BAND] = int(spec.half_bandwidth) if spec.banded else -1
        traits[HAS_LQV] = int(spec.has_Lqv)
        traits[HAS_FV] = int(spec.has_fv)
        traits[AUTONOMOUS] = int(spec.autonomous)
        traits = tuple(traits)
        # banded storage is a switch (loops.traits): the pattern, or None for dense storage
        pattern = None
        if spec.banded:
            position = {pair: k for k, pair in enumerate(spec.pattern)}
            pattern = np.array(
                [(a, b, position.get((b, a), 0)) for a, b in spec.pattern], dtype=np.int64
            )
        periodic = np.array(spec.periodic or (False,) * self.system.n, dtype=np.bool_)
        return fn, traits, pattern, periodic

    def compiled_point_functions(self, names: tuple[str, ...]) -> tuple[tuple[int, ...], tuple]:
        """(addresses, traits) of the system's compiled point functions ``names``.

        For compiled solvers outside the time loops (:mod:`galerkin_vi.action`):
        the addresses fill the slots of :mod:`galerkin_vi.loops.point` (0 where
        not asked for), the traits are the loops' (:mod:`galerkin_vi.loops.traits`).
        Numba backend only; the points are compiled (or loaded) on first use.
        """
        if self.backend != "numba":
            raise ValueError("compiled point functions need the numba backend")
        fn = tuple(int(address) for address in self._points.addresses(names))
        return fn, self._loop_arguments[1]

    @property
    def uses_banded_storage(self) -> bool:
        """Whether the point functions write second derivatives in banded (pattern) storage."""
        return bool(self._summary.banded)

    # ------------------------------------------------------------ validation
    def _state(self, name: str, x: ArrayLike) -> NDArray[np.float64]:
        return state_vector(name, x, self.system.n)

    @staticmethod
    def _step_size(h: float) -> float:
        if not isinstance(h, numbers.Real) or isinstance(h, bool):
            raise TypeError(f"h must be a real number, got {h!r}")
        h = float(h)
        if not np.isfinite(h) or h == 0.0:
            raise ValueError(f"h must be finite and nonzero, got {h}")
        return h

    def _run_plan(self, h, n_steps, t_span, t0, save_every) -> tuple[float, int, float, int]:
        """Checked (h, n_steps, t0, save_every) of a run, ``t_span`` resolved."""
        h = self._step_size(h)
        h, n_steps, t0 = _span_steps(h, n_steps, t_span, t0)
        n_steps, save_every, t0 = _run_lengths(n_steps, save_every, t0)
        return h, n_steps, t0, save_every

    @cached_property
    def _point_legendre(self):
        """:class:`PointLegendre` of the compiled Hessian, or None where it does not apply.

        Numba backend and a loop that compiles the Hessian (not the explicit one).
        """
        if self.backend != "numba" or self.kernel_path == "explicit":
            return None
        self._loop_arguments  # noqa: B018 - compiles the point functions the loop needs
        hessian = self._points.compiled.get("point_hessian")
        if hessian is None:
            return None
        from .run.legendre import PointLegendre

        pattern = self._summary.pattern if self._summary.banded else None
        return PointLegendre(hessian.address, self.system.n, pattern)

    def _initial_momentum(self, q0, v0, p0, t0, prm):
        if (v0 is None) == (p0 is None):
            raise ValueError("give exactly one of v0 (velocities) and p0 (momenta)")
        system = self.system
        fast = self._point_legendre
        if fast is not None:
            # the compiled point functions: a few microseconds instead of ~170 (NumPy);
            # None means singular or not finite, which the NumPy path below reports
            if v0 is not None:
                v = self._state("v0", v0)
                p = fast.momenta(t0, q0, v, prm)
            elif system.structure.quadratic_in_v:
                p = self._state("p0", p0)
                v = fast.velocities_of_quadratic(t0, q0, p, prm)
                p = p if v is not None else None
            else:
                p = None
            if p is not None and np.isfinite(p).all() and np.isfinite(v).all():
                return np.asarray(p, dtype=float), np.asarray(v, dtype=float)
        prm_dict = dict(zip(system.params, prm, strict=True))
        if v0 is not None:
            v = self._state("v0", v0)
            m = system.evaluate("Lvv", t0, q0, v, system.parameter_vector(prm_dict))
            if not np.all(np.isfinite(m)) or not is_regular(m.reshape(system.n, system.n)):
                raise DegenerateLagrangianError(
                    f"d2L/dv2 is singular at q0={q0}, v0={v}: the Lagrangian is degenerate there"
                )
            p = system.legendre(q0, v, t0, prm_dict)
        else:
            p = self._state("p0", p0)
            v = system.inverse_legendre(q0, p, t0, prm_dict)
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
            raise ValueError(f"the Legendre transform at q0={q0} is not finite")
        return np.asarray(p, dtype=float), np.asarray(v, dtype=float)

    # ------------------------------------------------------------------- run
    def integrate(
        self,
        q0: ArrayLike,
        v0: ArrayLike | None = None,
        p0: ArrayLike | None = None,
        *,
        h: float,
        n_steps: int | None = None,
        t0: float = 0.0,
        params: Mapping[sp.Symbol | str, float] | None = None,
        save_every: int = 1,
        project: bool = False,
        on_failure: str = "warn",
        dense_output: bool = False,
        t_span: tuple[float, float] | None = None,
        events: object = None,
        progress: bool | None = None,
        t_eval: ArrayLike | None = None,
        contact_mode: str = "auto",
    ) -> Trajectory:
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
            5000 steps go in chunks whose size depends on the system only
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
        run = dict(
            h=h, n_steps=n_steps, t0=t0, params=params, save_every=save_every, project=project,
            on_failure=on_failure, dense_output=dense_output, t_span=t_span, events=events,
            progress=progress, t_eval=t_eval,
        )  # fmt: skip
        if self.system.contacts:
            from .contact.runs import integrate_with_contacts

            return integrate_with_contacts(self, q0, v0, p0, contact_mode=contact_mode, **run)
        if contact_mode != "auto":
            raise ValueError(f"contact_mode={contact_mode!r} needs a system with contacts")
        return self._integrate_smooth(q0, v0, p0, **run)

    def _integrate_smooth(
        self, q0, v0, p0, *, h, n_steps, t0, params, save_every, project, on_failure,
        dense_output, t_span, events, progress, t_eval,
    ) -> Trajectory:  # fmt: skip
        """:meth:`integrate` without contacts: the loops, events, dense output."""
        system = self.system
        check_failure_mode(on_failure)
        q0 = self._state("q0", q0)
        h, n_steps, t0, save_every = self._run_plan(h, n_steps, t_span, t0, save_every)
        if not isinstance(dense_output, bool):
            raise TypeError(f"dense_output must be True or False, got {dense_output!r}")
        event_list = as_events(events)
        event_functions = [event_function(e, system) for e in event_list]
        times = _requested_times(t_eval, t0, h, n_steps)
        if event_list or times is not None:
            dense_output = True
        if dense_output and save_every != 1:
            what = "events are located" if event_list else "dense_output=True interpolates"
            raise ValueError(
                f"{what} between consecutive steps: it needs save_every=1, got {save_every}"
            )
        prm = system.parameter_vector(params)
        q0, p0_arr, v0_arr = self._initial_state(q0, v0, p0, t0, prm, project)
        run = (q0, p0_arr, v0_arr, t0, h, n_steps, save_every, prm)
        if progress is not None and not isinstance(progress, bool):
            raise TypeError(f"progress must be True, False or None, got {progress!r}")

        def restart(q, p, t):
            return self._initial_state(q, None, p, t, prm, False)

        traj, status, done, increment, interrupted = run_in_chunks(
            run, self._run, restart, progress, terminal_stop(event_list, event_functions, prm)
        )
        failure = None
        if interrupted:
            message = (
                f"{RunStatus.INTERRUPTED.cause} after step {done} (t = {traj.t[-1]:.6g}); the "
                "states computed so far are kept"
            )
            traj = replace(traj, status=RunStatus.INTERRUPTED, message=message)
        elif status != 0:
            code = loop_status(status)
            t_fail = t0 + done * h
            # the explicit loop has no iteration, hence no increment to report
            last = f" (last increment {increment:.3g})" if np.isfinite(increment) else ""
            failure = f"step {done} (t = {t_fail:.6g}, h = {h:.3g}): {code.cause}{last}"
            traj = replace(
                traj,
                status=code,
                message=f"{failure}; the states before the failing step are kept. Try a smaller h.",
            )
        traj = self._trusted(traj, h, failure)
        if dense_output and len(traj) >= 2:
            traj = replace(traj, sol=traj.dense())
        if event_list:
            traj = self._with_events(traj, event_list, event_functions, prm)
        if times is not None and traj.sol is not None:
            traj = _at_times(traj, times)
        if traj.status == RunStatus.INTERRUPTED:
            # asked for by the user: returned in either failure mode
            warnings.warn(traj.message, RunFailureWarning, stacklevel=3)
            return traj
        if not traj.success:
            step = int(round((traj.t[-1] - t0) / h))
            return failed_run(
                traj, on_failure, step=step, t=float(traj.t[-1]), residual=increment, stacklevel=4
            )
        _warn_if_unstable(traj, h)
        return traj

    def _run(self, run: tuple) -> tuple:
        """The loop's trajectory as it came, its status, steps done and last increment."""
        n_steps, save_every, prm = run[5], run[6], run[7]
        system = self.system
        out = RunOutputs.allocate(n_steps, save_every, system.n, any(system.periodic))
        status, done, saved, worst, increment = self._run_loop(run, out)
        traj = out.trajectory(
            status, done, saved, worst, save_every, system, prm, self.method.order
        )
        return traj, status, done, increment

    def _trusted(self, traj: Trajectory, h: float, failure: str | None) -> Trajectory:
        """``traj`` without the states reached by explosive growth (:mod:`.growth`).

        Growth is judged per step whatever ``save_every`` is: the steps between
        the saved rows where it shows (or, after a failure, between the last
        two) are run again one by one, at most ``save_every`` steps.
        """
        if len(traj) < 2:
            return traj
        if failure is None:
            # a completed run whose last state stays within the growth bound of its
            # first is not examined row by row: explosive growth does not calm down
            # again (it overflows), and the full test costs 20-60 us per short call
            ends = np.abs(np.concatenate((traj.q[0], traj.p[0], traj.q[-1], traj.p[-1])))
            n = traj.q.shape[1]
            if ends[2 * n :].max() <= EXPLOSIVE_GROWTH * max(1.0, ends[: 2 * n].max()):
                return traj
        steps = np.round((traj.t - traj.t[0]) / h).astype(np.int64)
        cut = explosive_row(traj.q, traj.p, steps)
        end = cut if cut is not None else len(traj) - 1 if failure is not None else None
        if end is None:
            return traj
        gap = int(steps[end] - steps[end - 1])
        if gap > 1:
            fine = self._steps_from(traj, end - 1, h, gap)
            inner = explosive_row(fine.q, fine.p, np.arange(len(fine)))
            if inner is not None:
                # the last trusted state lies between saved rows end - 1 and end
                kept = slice(0, end)
                # q_reduced dropped: the row appended below has none (diagnostics reduce)
                head = replace(traj, t=traj.t[kept], q=traj.q[kept], p=traj.p[kept], q_reduced=None)
                if inner > 1:
                    head = replace(
                        head,
                        t=np.append(head.t, fine.t[inner - 1]),
                        q=np.vstack([head.q, fine.q[inner - 1]]),
                        p=np.vstack([head.p, fine.p[inner - 1]]),
                    )
                step = int(steps[end - 1]) + inner
                return self._untrusted(head, len(head), step, fine, inner, h, failure)
        if cut is None:
            return traj
        return self._untrusted(traj, cut, int(steps[cut]), traj, cut, h, failure)

    def _steps_from(self, traj: Trajectory, row: int, h: float, m: int) -> Trajectory:
        """The m steps from saved row ``row``, every one saved."""
        q0, p0, t0, prm = traj.q[row], traj.p[row], float(traj.t[row]), traj.params
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            q0, p0, v0 = self._initial_state(q0, None, p0, t0, prm, False)
            # the raw run, failures and explosions included: they are what is looked for
            return self._run((q0, p0, v0, t0, h, m, 1, prm))[0]

    @staticmethod
    def _untrusted(traj, keep, step, rows, r, h, failure) -> Trajectory:
        """``traj`` cut to its first ``keep`` rows, flagged unstable from ``step`` on."""
        with np.errstate(all="ignore"):
            size = np.maximum(np.max(np.abs(rows.q[r])), np.max(np.abs(rows.p[r])))
            before = max(1.0, np.max(np.abs(rows.q[r - 1])), np.max(np.abs(rows.p[r - 1])))
        # named like a loop failure: by the step's start, the last state kept
        t_step = traj.t[0] + (step - 1) * h
        message = (
            f"step {step - 1} (t = {t_step:.6g}, h = {h:.3g}): {RunStatus.UNSTABLE.cause} (the "
            f"state grew from size {before:.3g} to {size:.3g} in one step); the states from "
            "there on are dropped"
        )
        if failure is not None:
            message += f", and then {failure}"
        message += ". Try a smaller h."
        kept = slice(0, keep)
        return replace(
            traj,
            t=traj.t[kept],
            q=traj.q[kept],
            p=traj.p[kept],
            q_reduced=None if traj.q_reduced is None else traj.q_reduced[kept],
            status=RunStatus.UNSTABLE,
            message=message,
        )

    def _with_events(self, traj, event_list, functions, prm) -> Trajectory:
        """``traj`` with its events located, cut at the first terminal one."""
        if traj.sol is None:  # fewer than 2 states: no interval to search
            return apply_events(traj, event_list, [])

        def method_step(k: int, tau: float):
            # one step of the method from node k, of length tau (exact event times)
            if tau == 0.0:  # the event at the node itself
                q, p = traj.q[k].copy(), traj.p[k].copy()
            else:
                q, p = self._one_step(traj.q[k], traj.p[k], tau, float(traj.t[k]), prm)
            v = self.system.inverse_legendre(q, p, traj.t[k] + tau, prm_map)
            return q, v

        prm_map = dict(zip(self.system.params, prm, strict=True))
        records = locate_events(event_list, functions, traj.sol, prm, method_step)
        return apply_events(traj, event_list, records)

    def _initial_state(self, q0, v0, p0, t0, prm, project):
        """(q0, p0, v0) from the user's data: Legendre transform, constraints checked."""
        system = self.system
        p0_arr, v0_arr = self._initial_momentum(q0, v0, p0, t0, prm)
        if system.m:
            q0, p0_arr, v0_arr = consistent_initial_state(
                system, t0, q0, p0_arr, v0_arr, prm, bool(project)
            )
            p0_arr, v0_arr = project_momentum(system, t0, q0, p0_arr, v0_arr, prm)
        elif project:
            raise ValueError("project=True needs a system with constraints")
        return q0, p0_arr, v0_arr

    def _run_loop(self, run: tuple, out: RunOutputs) -> tuple:
        """Run the loop of :attr:`kernel_path` (compiled, or the NumPy reference).

        Returns (status, steps completed, rows saved, max residual, failing increment).
        """
        path, system, tb = self.kernel_path, self.system, self.method.tables
        counters = (out.iterations, out.iteration_total)
        if self.backend != "numba":
            solver = numpy_constrained if path == "constrained" else numpy_backend
            return solver.integrate(
                system, tb, *run, self.tol, self.maxiter, *out.arrays, *counters
            )
        from .loops.readiness import ensure_loops

        ensure_loops()
        if path == "explicit":
            return run_explicit(system, self._summary, self._loop_arguments, run, out.arrays)
        loop, before, after = self._loop_call()
        result = loop(*before, *run, *after, *out.arrays, *counters)
        if path == "varying_mass" and result[0] != 0:
            return self._newton_from_last_row(run, out, result)
        return result

    def _newton_from_last_row(self, run: tuple, out: RunOutputs, result: tuple) -> tuple:
        """Continue a run the varying-mass loop gave up on with Newton, from its last saved row.

        The fixed-point iteration stops before a step on which it contracts too
        slowly (or fails); the general loop then runs the rest from the last
        saved state (a join like :meth:`stream`'s: the compensation bits and the
        extrapolated stages start afresh). Its failures are the run's.
        """
        from . import loops

        _, _, saved, worst, _ = result
        q0, p0, v0, t0, h, n_steps, save_every, prm = run
        row = saved - 1
        start = row * save_every
        q_row, p_row = out.q[row].copy(), out.p[row].copy()
        turns = out.turns[row].copy() if out.periodic else None
        # the velocities only start Newton's first guess: the compiled transform, the
        # NumPy one where there is none
        v_row = None
        if self._point_legendre is not None:
            v_row = self._point_legendre.velocities_of_quadratic(t0 + start * h, q_row, p_row, prm)
        if v_row is None:
            prm_map = dict(zip(self.system.params, prm, strict=True))
            v_row = self.system.inverse_legendre(q_row, p_row, t0 + start * h, prm_map)
        out.iterations[row:] = 0
        turns_tail = out.turns[row:] if out.periodic else out.turns
        tail = (out.t[row:], out.q[row:], out.p[row:], turns_tail)
        before, after = self._newton_call()
        status, done, saved_tail, worst_tail, increment = loops.general_loop(
            *before, q_row, p_row, np.asarray(v_row, dtype=float), t0 + start * h, h,
            n_steps - start, save_every, prm, *after, *tail, out.iterations[row:],
            out.iteration_total,
        )  # fmt: skip
        if turns is not None:
            out.turns[row : row + saved_tail] += turns
        # the times as the run's own clock gives them (t0 + k h, not (t0 + start h) + j h)
        steps = np.minimum(np.arange(saved_tail) * save_every, done)
        out.t[row : row + saved_tail] = t0 + (start + steps) * h
        return status, start + done, row + saved_tail, max(worst, worst_tail), increment

    def _loop_call(self) -> tuple:
        """(loop, before, after) of an implicit compiled path: the loop is called as
        ``loop(*before, q0, p0, v0, t0, h, n_steps, save_every, prm, *after, t, q, p,
        turns, iterations, iteration_total)`` (:mod:`galerkin_vi.loops.abi`).

        ``before`` may hold work space of the loop (the stage form's diagonal mass):
        a new one per call, so that threads running the loop at once do not share it.
        """
        from . import loops  # numba: imported on the first compiled run

        path, system, tb = self.kernel_path, self.system, self.method.tables
        model = self._loop_arguments
        newton = (self.tol, self.maxiter)
        if path == "separable":
            st = separable_tables(self.method)
            # a diagonal M is a compiled variant of its own (None: a full M)
            diagonal = np.zeros(system.n) if self._summary.diagonal_mass else None
            after = (tb.b, tb.c, *st.loop_arguments, *newton, self.uses_constant_mass)
            return loops.stage_form_loop, (*model, diagonal), after
        if path == "varying_mass":
            stages = varying_mass_tables(self.method)
            return loops.varying_mass_loop, model, (*stages.loop_arguments, *newton)
        method = (tb.b, tb.c, tb.d, tb.Phi, tb.D, tb.extrapolation)
        if path == "linear":
            return loops.linear_loop, model, method
        if path == "constrained":
            return loops.constrained_loop, (*model, system.m), (*method, *newton)
        return loops.general_loop, *self._newton_call()

    def _newton_call(self) -> tuple[tuple, tuple]:
        """(before, after) of the general Newton loop's call (as :meth:`_loop_call`)."""
        tb = self.method.tables
        method = (tb.b, tb.c, tb.d, tb.Phi, tb.D, tb.extrapolation)
        newton = (self.tol, self.maxiter)
        model = self._loop_arguments
        # a switch (loops.traits): None compiles the L_qv and f_v terms out
        spec = self._summary
        couplings = (spec.has_Lqv, spec.has_fv) if spec.has_Lqv or spec.has_fv else None
        return (*model, couplings), (*method, *newton)

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
        project: bool = False,
        on_failure: str = "warn",
    ) -> Iterator[Trajectory]:
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
        # validated here, when stream() is called, not at the first next()
        check_failure_mode(on_failure)
        if (
            isinstance(chunk_steps, bool)
            or not isinstance(chunk_steps, numbers.Integral)
            or chunk_steps < 1
        ):
            raise ValueError(f"chunk_steps must be a positive int, got {chunk_steps!r}")
        if not isinstance(save_every, numbers.Integral) or save_every < 1:
            raise ValueError(f"save_every must be a positive int, got {save_every!r}")
        if chunk_steps % save_every:
            raise ValueError(
                f"chunk_steps ({chunk_steps}) must be a multiple of save_every ({save_every}) "
                "for the chunks to save the rows one run would"
            )
        if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 0:
            raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")
        return self._chunks(
            q0, v0, p0, h, int(n_steps), int(chunk_steps), t0, params, save_every, project,
            on_failure,
        )  # fmt: skip

    def _chunks(
        self, q0, v0, p0, h, n_steps, chunk_steps, t0, params, save_every, project, on_failure
    ) -> Iterator[Trajectory]:
        done = 0
        offset = None  # whole turns of the angles, added back to later chunks' q
        start = {"v0": v0, "p0": p0}
        q_start: ArrayLike = q0
        t_start = float(t0)
        first = True
        while first or done < n_steps:
            steps = min(chunk_steps, n_steps - done)
            try:
                chunk = self.integrate(
                    q_start,
                    **start,
                    h=h,
                    n_steps=steps,
                    t0=t_start,
                    params=params,
                    save_every=save_every,
                    project=project and first,
                    on_failure="raise",
                )
            except ConvergenceError as exc:
                # report the failure in the coordinates and step count of the whole run
                exc.step += done
                partial = exc.partial
                if offset is not None:
                    partial = replace(partial, q=partial.q + offset)
                partial = partial if first else _without_first_row(partial)
                message = f"{partial.message} (step {exc.step} of the whole run)"
                exc.partial = replace(partial, message=message)
                if on_failure == "raise":
                    raise
                yield failed_run(
                    exc.partial, on_failure, step=exc.step, t=exc.t, residual=exc.residual
                )
                return
            if offset is not None:
                chunk = replace(chunk, q=chunk.q + offset)
            yield chunk if first else _without_first_row(chunk)
            done += steps
            first = False
            if chunk.q_reduced is not None:
                q_start = chunk.q_reduced[-1]
                offset = chunk.q[-1] - chunk.q_reduced[-1]
            else:
                q_start = chunk.q[-1]
            start = {"v0": None, "p0": chunk.p[-1]}
            t_start = float(t0) + done * h  # not chunk.t[-1]: no rounding accumulates

    def integrate_many(
        self,
        q0s: ArrayLike,
        v0s: ArrayLike | None = None,
        p0s: ArrayLike | None = None,
        *,
        params=None,
        executor=None,
        workers: int | None = None,
        **run,
    ):
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
        """One step of the position–momentum map, ``(q_k, p_k) -> (q_{k+1}, p_{k+1})``."""
        traj = self._integrate_smooth(
            q0, None, p0, h=h, n_steps=1, t0=t0, params=params, save_every=1, project=False,
            on_failure="raise", dense_output=False, t_span=None, events=None, progress=None,
            t_eval=None,
        )  # fmt: skip
        return traj.q[-1].copy(), traj.p[-1].copy()

    def _one_step(self, q, p, tau: float, t0: float, prm) -> tuple[NDArray, NDArray]:
        """:meth:`step` from a state a run produced, without its argument checks.

        The same loop call as :meth:`step` (bitwise the same result) at a fraction
        of its Python cost: the exact event secant and the contact cuts take many.
        """
        q0, p0, v0 = self._initial_state(q, None, p, t0, prm, False)
        traj, status, _, increment = self._run((q0, p0, v0, t0, tau, 1, 1, prm))
        if status != 0:
            raise ConvergenceError(
                f"one step of length {tau:.3g} from t = {t0:.6g} failed: "
                f"{loop_status(status).cause}",
                step=0, t=t0, residual=float(increment), partial=traj,
            )  # fmt: skip
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
        system = self.system
        if system.m:
            raise NotImplementedError(
                "step_del: the position-only DEL form is not available for constrained "
                "systems; use integrate or step (position-momentum form with multipliers)"
            )
        qa, qb = self._state("q0", q0), self._state("q1", q1)
        h = self._step_size(h)
        t0 = float(t0)
        if not np.isfinite(t0):
            raise ValueError(f"t0 must be finite, got {t0}")
        prm = system.parameter_vector(params)
        tb = self.method.tables
        s = tb.d.size - 1
        n = system.n
        t1 = float(t0) + h
        # unknowns as increments: interior points of step k-1 from q0, all of step k from q1;
        # guess: the line through q0, q1 for step k-1, continued for step k
        step = qb - qa
        x0 = np.concatenate([(tb.d[1:s, None] * step).ravel(), (tb.d[1:, None] * step).ravel()])
        m = (s - 1) * n
        zero = np.zeros((1, n))

        def residual_and_jacobian(x: NDArray) -> tuple[NDArray, NDArray]:
            Ca = np.vstack([zero, x[:m].reshape(s - 1, n), step[None, :]])
            Cb = np.vstack([zero, x[m:].reshape(s, n)])
            Ga, Ha = numpy_backend.discrete_hessian(system, tb, float(t0), h, qa, Ca, prm)
            Gb, Hb = numpy_backend.discrete_hessian(system, tb, t1, h, qb, Cb, prm)
            # equations: interior of step k-1, DEL at q_k, interior of step k
            R = np.concatenate([Ga[1:s].ravel(), Ga[s] + Gb[0], Gb[1:s].ravel()])
            J = np.zeros((R.size, x.size))
            J[:m, :m] = Ha[1:s, :, 1:s, :].reshape(m, m)
            J[m : m + n, :m] = Ha[s, :, 1:s, :].reshape(n, m)
            J[m : m + n, m:] = Hb[0, :, 1:, :].reshape(n, s * n)
            J[m + n :, m:] = Hb[1:s, :, 1:, :].reshape(m, s * n)
            return R, J

        result = newton_solve(residual_and_jacobian, x0, tol=self.tol, maxiter=self.maxiter)
        if result.status != CONVERGED:
            raise ConvergenceError(
                f"step_del: Newton iteration did not converge (increment {result.increment:.3g})",
                step=0,
                t=t1,
                residual=result.increment,
            )
        return qb + result.x[-n:]


def _requested_times(t_eval, t0: float, h: float, n_steps: int) -> NDArray | None:
    """``t_eval`` checked: finite, in the span, monotone in the run's direction."""
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


def _at_times(traj: Trajectory, times: NDArray) -> Trajectory:
    """``traj`` with rows at ``times`` from its dense output (a run cut short: those reached)."""
    sol = traj.sol
    reached = times[(times >= sol.t_min) & (times <= sol.t_max)]
    return replace(traj, t=reached, q=sol(reached), p=sol.momentum(reached), q_reduced=None)


def _span_steps(h: float, n_steps, t_span, t0) -> tuple[float, object, object]:
    """(h, n_steps, t0) from ``t_span``: equal steps of at most |h| landing on its end."""
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


def _run_lengths(n_steps, save_every, t0) -> tuple[int, int, float]:
    """Checked ``n_steps``, ``save_every`` and ``t0``."""
    if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")
    if (
        isinstance(save_every, bool)
        or not isinstance(save_every, numbers.Integral)
        or save_every < 1
    ):
        raise ValueError(f"save_every must be a positive int, got {save_every!r}")
    t0 = float(t0)
    if not np.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0}")
    return int(n_steps), int(save_every), t0


@dataclass
class RunOutputs:
    """The arrays a loop writes into, allocated once per run.

    Angles are saved in [-pi, pi) with the whole turns apart (``turns``; see
    :func:`galerkin_vi.loops.common.save_row`). Iteration counts are kept per
    saved interval, not per step: a 1e7-step run with ``save_every`` stores
    nothing per step.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    p: NDArray[np.float64]
    turns: NDArray[np.float64]
    iterations: NDArray[np.uint8]
    iteration_total: NDArray[np.int64]
    periodic: bool

    @classmethod
    def allocate(cls, n_steps: int, save_every: int, n: int, periodic: bool) -> RunOutputs:
        n_saved = n_steps // save_every + 1 + (1 if n_steps % save_every else 0)
        return cls(
            t=np.empty(n_saved),
            q=np.empty((n_saved, n)),
            p=np.empty((n_saved, n)),
            turns=np.zeros((n_saved if periodic else 1, n)),
            iterations=np.zeros(-(-n_steps // save_every), dtype=np.uint8),
            iteration_total=np.zeros(1, dtype=np.int64),
            periodic=periodic,
        )

    @property
    def arrays(self) -> tuple:
        """(t, q, p, turns), in the loops' argument order."""
        return self.t, self.q, self.p, self.turns

    def trajectory(
        self, status, done, saved, worst, save_every, system, prm, order=None
    ) -> Trajectory:
        """The saved rows as a :class:`Trajectory` (angles continued across turns)."""
        q_saved, q_reduced = self.q[:saved], None
        if self.periodic:
            q_reduced = q_saved
            q_saved = numpy_backend.unwrapped(q_saved, self.turns[:saved])
        attempted = int(done + (status != 0))
        return Trajectory(
            t=self.t[:saved],
            q=q_saved,
            q_reduced=q_reduced,
            p=self.p[:saved],
            newton_iterations=self.iterations[: -(-attempted // save_every)],
            total_newton_iterations=int(self.iteration_total[0]),
            n_steps=attempted,
            max_residual=float(worst),
            system=system,
            params=prm,
            order=order,
        )


def run_explicit(system, spec, model, run, arrays) -> tuple:
    """Störmer–Verlet with :math:`M^{-1}` formed once (a diagonal M as its diagonal only)."""
    q0, p0, _, t0, h, n_steps, save_every, prm = run
    n = system.n
    mass = system.evaluate("Lvv", t0, q0, np.zeros(n), prm).reshape(n, n)
    if not is_regular(mass):
        raise DegenerateLagrangianError(f"the mass matrix d2L/dv2 = {mass} is singular")
    fn, _, _, periodic = model
    # switches (loops.traits): a run-time test of either cost 25 % per step here
    periodic = periodic if periodic.any() else None
    inverse = np.linalg.inv(mass)
    # a writable copy: numba types a read-only view as another (compiled) variant
    diagonal = np.diag(inverse).copy() if spec.diagonal_mass else None
    from .loops import explicit_loop

    time_dependent = None if spec.autonomous else True  # a switch: see loops.traits
    return explicit_loop(
        fn, periodic, time_dependent, q0, p0, t0, h, n_steps, save_every, prm, inverse,
        diagonal, *arrays,
    )  # fmt: skip


def _warn_if_unstable(traj: Trajectory, h: float) -> None:
    """Warn when the momenta grew by more than ``INSTABILITY_GROWTH`` over the run.

    The growth is measured between the first and the last tenth of the saved
    states, a ratio, so it does not depend on units (a body falling from rest
    gains momentum linearly, a factor of about 10, not 1e6). Forced and
    time-dependent systems, whose energy may legitimately grow, and runs with
    fewer than 10 saved states are not checked.
    """
    structure = traj.system.structure
    if len(traj) < 10 or structure.forced or not structure.autonomous:
        return
    # at least two rows: a start at rest has p_0 = 0, and any motion is not growth
    tenth = max(2, len(traj) // 10)
    early = float(np.max(np.abs(traj.p[:tenth])))
    late = float(np.max(np.abs(traj.p[-tenth:])))
    if early > 0.0 and late > INSTABILITY_GROWTH * early:
        warnings.warn(
            f"the momenta grew by a factor {late / max(early, 1e-300):.3g} over the run: "
            f"h = {h:.3g} is probably past the method's stability limit (the discrete "
            "solution grows exponentially); use a smaller h",
            InstabilityWarning,
            stacklevel=4,
        )


def _without_first_row(traj: Trajectory) -> Trajectory:
    """The trajectory minus its first saved row (a chunk's start, the previous chunk's end)."""
    return replace(
        traj,
        t=traj.t[1:],
        q=traj.q[1:],
        p=traj.p[1:],
        q_reduced=None if traj.q_reduced is None else traj.q_reduced[1:],
    )
