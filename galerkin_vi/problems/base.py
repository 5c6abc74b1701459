"""The :class:`Problem` record and trusted reference solutions."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..model.system import LagrangianSystem

__all__ = ["Problem", "ode_interpolant", "ode_reference"]


@dataclass(frozen=True, eq=False)
class Problem:
    """A test problem: a system, initial data, a time span and what is known about it.

    Attributes
    ----------
    name : str
    system : LagrangianSystem
    q0, v0 : ndarray, shape (n,)
        Default initial positions and velocities.
    t_final : float
        Default length of the time span (starting at 0).
    params : mapping
        Parameter values of this instance (override the system's defaults).
    exact : callable or None
        ``t -> q(t)`` where an exact solution exists.
    symmetries : mapping of str to tuple of sympy.Expr
        Infinitesimal generators :math:`\\xi_Q(q)` of symmetries whose momentum
        maps are conserved.
    """

    name: str
    system: LagrangianSystem
    q0: NDArray[np.float64]
    v0: NDArray[np.float64]
    t_final: float
    params: Mapping[sp.Symbol, float] = field(default_factory=dict)
    exact: Callable[[float], NDArray[np.float64]] | None = None
    symmetries: Mapping[str, tuple[sp.Expr, ...]] = field(default_factory=dict)

    def reference(self, t: float | NDArray) -> NDArray[np.float64]:
        """Position at time(s) ``t``: exact where known, else :func:`ode_reference`.

        A scalar ``t`` gives shape (n,), an array of times shape (len(t), n).
        """
        if self.exact is not None:
            return np.asarray(self.exact(t), dtype=float)
        return ode_reference(self.system, self.q0, self.v0, t, self.params)


def ode_reference(
    system: LagrangianSystem,
    q0: NDArray,
    v0: NDArray,
    t: float | NDArray,
    params: Mapping | None = None,
    rtol: float = 1e-13,
    t0: float = 0.0,
) -> NDArray[np.float64]:
    r"""Position at time(s) ``t`` from the Euler–Lagrange equations by DOP853.

    The accelerations solve

    .. math::

        L_{vv}\,a = L_q + f - L_{qv}^T v - \partial_t L_v ,

    all evaluated at :math:`(t, q, v)`: the forced Euler–Lagrange equations
    :math:`\frac{d}{dt} L_v = L_q + f` with the total derivative expanded
    (:math:`f = 0` without forces; :math:`\partial_t L_v = 0` when :math:`L_v`
    does not depend on time). An independent check on the Galerkin
    integrators, accurate to about ``1e-12`` on the library's smooth problems
    over short spans.

    Parameters
    ----------
    system : LagrangianSystem
        Without holonomic constraints (the unconstrained equations above would
        ignore them).
    q0, v0 : ndarray, shape (n,)
        Initial positions and velocities at ``t0``.
    t : float or ndarray
        Output time(s), none earlier than ``t0``.
    params : mapping, optional
        Parameter values (override the system's defaults).
    rtol : float
        Relative tolerance of DOP853 (absolute tolerance ``rtol * 1e-2``).
    t0 : float
        Initial time (matters for time-dependent Lagrangians and forces).

    Returns
    -------
    ndarray
        Shape (n,) for a scalar ``t``, (len(t), n) for an array.

    Raises
    ------
    NotImplementedError
        If the system has holonomic constraints.
    ValueError
        If an output time lies before ``t0``.
    RuntimeError
        If DOP853 fails.
    """
    if system.constraints is not None:
        raise NotImplementedError(
            "ode_reference integrates the unconstrained Euler-Lagrange equations: it does not "
            "support holonomic constraints (use a Richardson reference, measure_order's "
            "reference=None)"
        )
    n = system.n
    t0 = float(t0)
    times = np.atleast_1d(np.asarray(t, dtype=float))
    if times.size and float(times.min()) < t0:
        raise ValueError(
            f"ode_reference: output times must not precede t0={t0}, got {float(times.min())}"
        )
    t_end = float(times.max()) if times.size else t0
    if t_end <= t0:
        return np.tile(np.asarray(q0, dtype=float), (times.size, 1)).reshape(np.shape(t) + (n,))
    sol = _solve_euler_lagrange(system, q0, v0, t0, t_end, params, rtol, t_eval=times)
    return sol.y[:n].T.reshape(np.shape(t) + (n,))


def ode_interpolant(
    system: LagrangianSystem,
    q0: NDArray,
    v0: NDArray,
    t_final: float,
    params: Mapping | None = None,
    rtol: float = 1e-13,
    t0: float = 0.0,
) -> Callable[[float | NDArray], NDArray[np.float64]]:
    """:func:`ode_reference` solved once over ``[t0, t0 + t_final]``, as a function of time.

    Returns ``t -> q(t)`` (shape (n,) for a scalar ``t``, (len(t), n) for an
    array) from the dense output of the same DOP853 run that
    :func:`ode_reference` makes for a final time ``t0 + t_final``, so the values
    agree with it; evaluating costs no new integration (an order study asks for
    the reference at the step points of every run). Times are meant to lie in
    the span (just outside it, the last step's interpolant extrapolates).
    """
    if system.constraints is not None:
        raise NotImplementedError("ode_interpolant does not support holonomic constraints")
    if not (np.isfinite(t_final) and t_final > 0):
        raise ValueError(f"t_final must be finite and positive, got {t_final}")
    n = system.n
    t0 = float(t0)
    sol = _solve_euler_lagrange(system, q0, v0, t0, t0 + float(t_final), params, rtol)

    def reference(t: float | NDArray) -> NDArray[np.float64]:
        values = sol.sol(np.atleast_1d(np.asarray(t, dtype=float)))[:n].T
        return values.reshape(np.shape(t) + (n,))

    return reference


def _solve_euler_lagrange(
    system: LagrangianSystem,
    q0: NDArray,
    v0: NDArray,
    t0: float,
    t_end: float,
    params: Mapping | None,
    rtol: float,
    t_eval: NDArray | None = None,
):
    """DOP853 run of the forced, non-autonomous Euler–Lagrange equations (dense without t_eval)."""
    from scipy.integrate import solve_ivp  # here: SciPy adds 35 MB to every process

    n = system.n
    prm = system.parameter_vector(params)
    # d(L_v)/dt enters only when L_v itself depends on t (not when only L - L_v.v or f do)
    time = system.t
    timed_momentum = time is not None and any(e.has(time) for e in system.pieces.Lv)

    def rhs(s: float, y: NDArray) -> NDArray:
        q, v = y[:n], y[n:]
        values = system.evaluate("hessian", s, q, v, prm)
        generalised_force = values[:n]  # L_q + f
        Lqv = values[2 * n + n * n : 2 * n + 2 * n * n].reshape(n, n)
        Lvv = values[2 * n + 2 * n * n : 2 * n + 3 * n * n].reshape(n, n)
        right = generalised_force - Lqv.T @ v
        if timed_momentum:
            right = right - system.evaluate("Lvt", s, q, v, prm)
        return np.concatenate([v, np.linalg.solve(Lvv, right)])

    # steps capped so that the dense output between steps is as accurate as the steps
    sol = solve_ivp(
        rhs,
        (t0, t_end),
        np.concatenate([np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)]),
        method="DOP853",
        rtol=rtol,
        atol=rtol * 1e-2,
        t_eval=t_eval,
        dense_output=t_eval is None,
        max_step=0.02 * max(1.0, t_end - t0),
    )
    if not sol.success:
        raise RuntimeError(f"reference solution failed: {sol.message}")
    return sol
