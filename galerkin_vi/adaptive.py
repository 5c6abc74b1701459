r"""Time-adaptive steps that stay symplectic: the Poincaré time transformation.

A fixed step in physical time is as small as the fastest part of an orbit
needs (the pericentre of an eccentric orbit, a close encounter). Variable steps
break the symplecticity of the map, and with it the bounded energy error. The
Poincaré transformation keeps both: for an autonomous :math:`H(q, p)` and a
step-size function :math:`g(q) > 0`, the Hamiltonian

.. math::

    K(q, p) = g(q)\,\big(H(q, p) - E\big), \qquad E = H(q_0, p_0),

has, on its level set :math:`K = 0`, the same orbits as :math:`H`, traversed in
a fictitious time :math:`\tau` with :math:`dt/d\tau = g(q)`. A symplectic method
with fixed steps :math:`\Delta\tau` applied to :math:`K` is a symplectic method
for :math:`H` with physical steps :math:`\approx g(q)\,\Delta\tau`, and :math:`K`,
hence :math:`H - E` where :math:`g` is bounded away from 0, stays bounded.

On the Lagrangian side (:math:`w = dq/d\tau`, so :math:`v = w/g`), the Legendre
transform of :math:`K` is

.. math::

    \tilde L(q, w) = g(q)\,\big[L(q, w/g(q)) + E\big],
    \qquad \frac{\partial \tilde L}{\partial w} = L_v = p,

so the momenta are the physical ones. Physical time is a further coordinate
:math:`z`, the clock, with

.. math::

    \hat L(q, z, w, \zeta) = \tilde L(q, w) + \tfrac12\,(\zeta - g(q))^2 .

:math:`z` is cyclic, so its momentum :math:`p_z = \zeta - g` is a Noether
momentum, which the Galerkin integrator conserves to round-off; it starts at 0,
so :math:`z' = g` and :math:`z = t` (with Gauss quadrature of :math:`s` points
the discrete equations of :math:`z` give :math:`\zeta = g` at every quadrature
point, and :math:`z_{k+1} - z_k = \Delta\tau \sum_i b_i g(q(\tau_k + c_i \Delta\tau))`).
The extended system is generated and compiled like any other: the general loop
runs it, one coordinate larger.

References: Hairer, Lubich & Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006, section VIII.2; Hairer, "Variable time step integration with
symplectic methods", Appl. Numer. Math. 25 (1997).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from .errors import ConvergenceError
from .integrator import Integrator
from .method.galerkin import Galerkin
from .model.system import LagrangianSystem
from .run.failures import check_failure_mode, failed_run
from .run.plan import state_vector
from .run.status import RunStatus
from .run.trajectory import Trajectory

__all__ = ["AdaptiveIntegrator", "AdaptiveTrajectory", "PoincareTransform", "encounter_scaling"]

#: the extended system's own symbols; names no user model is likely to use
CLOCK = sp.Symbol("t_clock")
CLOCK_RATE = sp.Symbol("t_clock_rate")
ENERGY = sp.Symbol("E_poincare")

#: steps of the first chunk of a run to a final time, before the rate dt/dtau is known
_FIRST_CHUNK = 256
_MAX_CHUNK = 1_000_000
#: secant iterations placing the last step on the final time
_LANDING_ITERATIONS = 20


def encounter_scaling(distances: Sequence[sp.Expr], alpha: float = 1.5) -> sp.Expr:
    r"""A step-size function for close encounters: :math:`g = (\sum_j d_j^{-\alpha})^{-1}`.

    For one distance this is :math:`d^\alpha`; for several it is at most the
    smallest :math:`d_j^\alpha` and close to it when one distance is much smaller
    than the others, and smooth (a minimum is not). :math:`\alpha = 3/2` matches
    the time scale of a Kepler orbit at distance :math:`d` (Kepler's third law:
    steps of equal fictitious time are about equal fractions of the local
    orbital period); :math:`\alpha = 1` is Sundman's transformation.

    Parameters
    ----------
    distances : sequence of sympy.Expr
        Positive expressions in q, e.g. ``sp.sqrt(x**2 + y**2)``.
    alpha : float
        Positive exponent.
    """
    if isinstance(distances, sp.Expr):
        distances = [distances]
    distances = list(distances)
    if not distances:
        raise ValueError("distances must contain at least one expression")
    if not (isinstance(alpha, numbers.Real) and math.isfinite(alpha) and alpha > 0):
        raise ValueError(f"alpha must be a positive real number, got {alpha!r}")
    a = sp.nsimplify(alpha)
    if len(distances) == 1:
        return sp.sympify(distances[0]) ** a
    return 1 / sum(sp.sympify(d) ** (-a) for d in distances)


@dataclass(frozen=True)
class PoincareTransform:
    r"""The extended Lagrangian :math:`\hat L` of a system and a step-size function.

    Parameters
    ----------
    system : LagrangianSystem
        An autonomous system without constraints or forces.
    g : sympy.Expr
        The step-size function :math:`g(q) > 0` (physical time per unit of
        fictitious time), an expression in the system's q and parameters.

    Attributes
    ----------
    extended : LagrangianSystem
        :math:`\hat L` in coordinates ``(*system.q, t_clock)``, parameters
        ``(*system.params, E_poincare)``.
    """

    system: LagrangianSystem
    g: sp.Expr
    extended: LagrangianSystem = field(init=False, repr=False)

    def __post_init__(self) -> None:
        system, g = self.system, self.g
        if not isinstance(system, LagrangianSystem):
            raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
        if system.t is not None:
            raise ValueError(
                "the Poincaré time transformation needs an autonomous system (t=None): "
                "with time in L the energy E of K = g (H - E) is not conserved"
            )
        if system.constraints is not None or system.forces is not None:
            raise ValueError(
                "the Poincaré time transformation is implemented for systems without "
                "constraints or forces"
            )
        if isinstance(g, numbers.Real):
            g = sp.sympify(g)
        if not isinstance(g, sp.Expr):
            raise TypeError(f"g must be a SymPy expression in q, got {type(g).__name__}")
        allowed = set(system.q) | set(system.params)
        stray = g.free_symbols - allowed
        if stray:
            names = ", ".join(sorted(str(s) for s in stray))
            raise ValueError(f"g may depend on q and the parameters only; it contains {names}")
        own = {CLOCK, CLOCK_RATE, ENERGY}
        taken = own & (set(system.q) | set(system.v) | set(system.params))
        if taken:
            raise ValueError(f"the system uses the reserved symbols {sorted(map(str, taken))}")
        w = system.v
        L_tilde = g * (system.L.xreplace({v: v / g for v in w}) + ENERGY)
        L_hat = L_tilde + (CLOCK_RATE - g) ** 2 / 2
        params = dict(zip(system.params, system.param_defaults, strict=True))
        params[ENERGY] = 0.0
        extended = LagrangianSystem(L_hat, [*system.q, CLOCK], [*w, CLOCK_RATE], params=params)
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "extended", extended)

    @cached_property
    def _g_numeric(self):
        return sp.lambdify([self.system.q, self.system.params], self.g, modules="numpy")

    def rate(self, q: ArrayLike, params: NDArray | None = None) -> NDArray:
        """:math:`g(q)`, the physical time per unit of fictitious time (rows of q)."""
        q = np.asarray(q, dtype=float)
        prm = self.system.param_defaults if params is None else params
        value = self._g_numeric(np.moveaxis(q, -1, 0), prm)
        return np.broadcast_to(np.asarray(value, dtype=float), q.shape[:-1]).copy()


class AdaptiveIntegrator:
    r"""Time-adaptive symplectic integration by the Poincaré transformation.

    Fixed steps :math:`\Delta\tau` of a Galerkin method on the extended
    Lagrangian of :class:`PoincareTransform`; the physical step is about
    :math:`g(q)\,\Delta\tau`. The energy :math:`E` is set from the initial
    state of each run.

    Parameters
    ----------
    system : LagrangianSystem
        Autonomous, without constraints or forces.
    method : Galerkin, optional
        Default ``Galerkin(2)``. With Gauss quadrature the clock is exactly the
        quadrature of :math:`g` over each step (see the module docstring).
    g : sympy.Expr
        Step-size function of q (and parameters), positive along the orbit;
        :func:`encounter_scaling` builds the usual choice.
    **options
        Passed to :class:`Integrator` (``backend``, ``tol``, ``maxiter``;
        ``fixed_point`` defaults to False here).

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
        g: sp.Expr,
        **options,
    ) -> None:
        self.transform = PoincareTransform(system, g)
        self.system = system
        # the long fictitious steps are near the fixed point's limit, where it hands
        # over to Newton: Newton alone takes less time there (docs/performance.md,
        # "Measurements behind design choices")
        options.setdefault("fixed_point", False)
        self.integrator = Integrator(self.transform.extended, method, **options)
        self.method = self.integrator.method

    # ------------------------------------------------------------------ set-up
    def _start(self, q0, v0, p0, t0, params):
        system = self.system
        prm = system.parameter_vector(params)
        q0 = state_vector("q0", q0, system.n)
        if (v0 is None) == (p0 is None):
            raise ValueError("give exactly one of v0 and p0")
        named = dict(zip(system.params, prm, strict=True))
        if p0 is None:
            p0 = system.legendre(q0, state_vector("v0", v0, system.n), 0.0, named)
        p0 = state_vector("p0", p0, system.n)
        rate = float(self.transform.rate(q0, prm))
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"g(q0) must be positive and finite, got {rate!r}")
        energy = float(system.hamiltonian(q0, p0, 0.0, named))
        if not math.isfinite(energy):
            raise ValueError(f"the energy at (q0, p0) is not finite: {energy!r}")
        extended_params = {**named, ENERGY: energy}
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
    ) -> AdaptiveTrajectory:
        r"""Integrate with fictitious step ``h`` for ``n_steps`` steps or up to ``t_final``.

        Parameters
        ----------
        q0 : array_like, shape (n,)
        v0, p0 : array_like, shape (n,)
            Exactly one: physical velocities or momenta.
        h : float
            The fixed step :math:`\Delta\tau` in fictitious time (positive).
        n_steps : int, optional
            Number of steps; or
        t_final : float, optional
            Physical time to reach: the run stops at the first step past it and
            replaces that step by one of the size that lands on ``t_final``
            (secant iteration on the clock), so that ``traj.t[-1] == t_final``.
        t0 : float
            Physical start time.
        params : mapping, optional
        save_every : int
            Save every ``save_every``-th step (and the last).
        on_failure : {"warn", "raise"}
            As for :meth:`Integrator.integrate`: a failed run returns the
            states before the failing step with ``success = False`` and a
            warning, or (``"raise"``) raises.

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
        if (n_steps is None) == (t_final is None):
            raise ValueError("give exactly one of n_steps and t_final")
        check_failure_mode(on_failure)
        if not (isinstance(h, numbers.Real) and math.isfinite(h) and h > 0):
            raise ValueError(f"h must be a positive fictitious step, got {h!r}")
        if isinstance(save_every, bool) or not isinstance(save_every, numbers.Integral):
            raise ValueError(f"save_every must be a positive int, got {save_every!r}")
        if save_every < 1:
            raise ValueError(f"save_every must be a positive int, got {save_every!r}")
        if t_final is not None:
            if not (isinstance(t_final, numbers.Real) and math.isfinite(t_final)):
                raise ValueError(f"t_final must be a finite real number, got {t_final!r}")
            if t_final <= t0:
                raise ValueError(f"t_final must be after t0 = {t0}, got {t_final!r}")
        qh, ph, extended_params, prm = self._start(q0, v0, p0, t0, params)
        try:
            if n_steps is not None:
                run = self.integrator.integrate(
                    qh, p0=ph, h=float(h), n_steps=n_steps, params=extended_params,
                    save_every=save_every, on_failure="raise",
                )  # fmt: skip
            else:
                run = self._run_to(qh, ph, float(h), float(t_final), extended_params, save_every)
        except ConvergenceError as exc:
            physical = self._physical_failure(exc, prm)
            if on_failure == "raise" or physical.partial is None:
                raise physical from exc
            return failed_run(
                physical.partial, on_failure, step=physical.step, t=physical.t,
                residual=physical.residual,
            )  # fmt: skip
        return self._trajectory(run, prm)

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

    def _run_to(self, qh, ph, h, t_final, params, save_every) -> Trajectory:
        """Chunks of steps until the clock passes ``t_final``, then a landing step.

        Steps past ``t_final`` in the last chunk are computed and dropped (their
        iterations still count in ``total_newton_iterations``: they were work).
        """
        integ = self.integrator
        rows = _Rows.start(qh, ph)
        tau = 0.0
        chunk = _FIRST_CHUNK
        while True:
            try:
                run = integ.integrate(rows.last_q, p0=rows.last_p, h=h, n_steps=chunk, t0=tau,
                                      params=params, on_failure="raise")  # fmt: skip
            except ConvergenceError as exc:
                # the chunks before and the failing chunk's good steps, as one partial run
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
            clock = run.q[:, -1]
            past = np.flatnonzero(clock[1:] >= t_final)
            keep = int(past[0]) if past.size else chunk  # steps that stay before t_final
            rows.extend(run, keep)
            tau = rows.last_tau
            if past.size:
                break
            # the mean dt/dtau of the whole run so far predicts the steps still needed;
            # that of the last chunk alone, which may end at a close encounter
            # (dt/dtau = g small), overestimates them by up to the ratio of g's extremes,
            # and the steps past t_final are computed for nothing (up to 14x the work kept
            # on Kepler e = 0.9). Chunks cover half of the prediction and grow at most 4x:
            # a few more calls, no large overshoot.
            done = rows.steps
            rate = (float(rows.last_q[-1]) - rows.first_clock) / tau
            need = (t_final - clock[-1]) / (rate * h) if rate > 0 else chunk
            chunk = int(min(_MAX_CHUNK, 4 * done, max(_FIRST_CHUNK, 0.5 * need + 16)))
        self._land(rows, h, t_final, params)
        return rows.trajectory(self.transform.extended, save_every)

    def _land(self, rows: _Rows, h: float, t_final: float, params) -> None:
        """Append one step of size in (0, h] whose clock lands on ``t_final``.

        The clock after a step is monotone in its size (dt/dtau = g > 0); the
        secant method on it, safeguarded by bisection, takes 3-6 single steps.
        """
        integ = self.integrator
        q, p, tau = rows.last_q, rows.last_p, rows.last_tau
        tiny = 4 * np.finfo(float).eps * max(1.0, abs(t_final))

        def miss(dtau: float) -> tuple[float, Trajectory]:
            run = integ.integrate(
                q, p0=p, h=dtau, n_steps=1, t0=tau, params=params, on_failure="raise"
            )
            rows.work += run.total_newton_iterations
            return float(run.q[-1, -1]) - t_final, run

        lo, f_lo = 0.0, float(q[-1]) - t_final  # below t_final
        hi = h
        f_hi, best = miss(hi)  # at or past t_final
        a, f_a, b, f_b = lo, f_lo, hi, f_hi
        for _ in range(_LANDING_ITERATIONS):
            if abs(f_b) <= tiny:
                break
            guess = b - f_b * (b - a) / (f_b - f_a) if f_b != f_a else 0.5 * (lo + hi)
            if not lo < guess < hi:
                guess = 0.5 * (lo + hi)
            f_guess, run = miss(guess)
            a, f_a, b, f_b = b, f_b, guess, f_guess
            best = run
            if f_guess < 0:
                lo = guess
            else:
                hi = guess
        rows.extend(best, 1)
        rows.last_q[-1] = t_final  # within a few ulps; exact for the caller


@dataclass
class _Rows:
    """The states of a run assembled from several integrations (save_every = 1).

    Kept as the runs' own arrays, joined once at the end: a list of rows, one
    array object per state, cost more than the steps of a short run.
    """

    tau: list[NDArray[np.float64]]
    q: list[NDArray[np.float64]]
    p: list[NDArray[np.float64]]
    iterations: list[NDArray]
    steps: int = 0
    work: int = 0
    worst: float = 0.0

    @classmethod
    def start(cls, q: NDArray, p: NDArray) -> _Rows:
        return cls(tau=[np.zeros(1)], q=[np.array(q, float)[None, :]],
                   p=[np.array(p, float)[None, :]], iterations=[])  # fmt: skip

    @property
    def last_q(self) -> NDArray[np.float64]:
        return self.q[-1][-1]

    @property
    def last_p(self) -> NDArray[np.float64]:
        return self.p[-1][-1]

    @property
    def last_tau(self) -> float:
        return float(self.tau[-1][-1])

    @property
    def first_clock(self) -> float:
        return float(self.q[0][0, -1])

    def extend(self, run: Trajectory, steps: int) -> None:
        """Append the states after the first ``steps`` steps of ``run``."""
        if steps <= 0:
            return
        self.tau.append(run.t[1 : steps + 1].copy())
        self.q.append(run.q[1 : steps + 1].copy())
        self.p.append(run.p[1 : steps + 1].copy())
        self.iterations.append(run.newton_iterations[:steps])
        self.steps += steps

    def trajectory(self, system: LagrangianSystem, save_every: int) -> Trajectory:
        steps = self.steps
        keep = np.unique(np.append(np.arange(0, steps + 1, save_every), steps))
        its = np.concatenate(self.iterations).astype(np.uint8) if self.iterations else np.zeros(0)
        groups = np.arange(0, steps, save_every)
        largest = np.maximum.reduceat(its, groups) if steps else its
        return Trajectory(
            t=np.concatenate(self.tau)[keep],
            q=np.concatenate(self.q)[keep],
            p=np.concatenate(self.p)[keep],
            newton_iterations=largest.astype(np.uint8),
            max_residual=self.worst,
            system=system,
            params=np.zeros(0),
            total_newton_iterations=self.work,
            n_steps=steps,
        )


@dataclass(frozen=True, eq=False)
class AdaptiveTrajectory(Trajectory):
    r"""A :class:`Trajectory` at physical times that are not equally spaced.

    Attributes
    ----------
    tau : ndarray, shape (N,)
        The fictitious times of the saved states (equally spaced but for a
        landing step on ``t_final``).
    clock_momentum : ndarray, shape (N,)
        :math:`p_z = \zeta - g`, 0 in exact arithmetic; its size is the
        round-off of the clock's Noether momentum.
    """

    tau: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    clock_momentum: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def step_sizes(self) -> NDArray[np.float64]:
        """Physical time between consecutive saved states."""
        return np.diff(self.t)
