"""The :class:`Problem` record and trusted reference solutions."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..system import LagrangianSystem

__all__ = ["Problem", "ode_reference"]


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
) -> NDArray[np.float64]:
    r"""Position at time(s) ``t`` from the Euler–Lagrange equations by DOP853.

    The accelerations solve :math:`L_{vv}\,a = L_q - L_{qv}^T v` (autonomous
    systems). An independent check on the Galerkin integrators, accurate to
    about ``1e-12`` on the library's smooth problems over short spans.
    """
    from scipy.integrate import solve_ivp  # here: SciPy adds 35 MB to every process

    if not system.structure.autonomous:
        raise NotImplementedError("ode_reference supports autonomous systems only")
    n = system.n
    prm = system.parameter_vector(params)

    def rhs(_t: float, y: NDArray) -> NDArray:
        q, v = y[:n], y[n:]
        values = system.evaluate("hessian", 0.0, q, v, prm)
        Lq = values[:n]
        Lqv = values[2 * n + n * n : 2 * n + 2 * n * n].reshape(n, n)
        Lvv = values[2 * n + 2 * n * n :].reshape(n, n)
        return np.concatenate([v, np.linalg.solve(Lvv, Lq - Lqv.T @ v)])

    times = np.atleast_1d(np.asarray(t, dtype=float))
    t_end = float(times.max()) if times.size else 0.0
    if t_end <= 0.0:
        return np.tile(np.asarray(q0, dtype=float), (times.size, 1)).reshape(np.shape(t) + (n,))
    # steps capped so that the dense output between steps is as accurate as the steps
    sol = solve_ivp(
        rhs,
        (0.0, t_end),
        np.concatenate([q0, v0]),
        method="DOP853",
        rtol=rtol,
        atol=rtol * 1e-2,
        t_eval=times,
        max_step=0.02 * max(1.0, t_end),
    )
    if not sol.success:
        raise RuntimeError(f"reference solution failed: {sol.message}")
    return sol.y[:n].T.reshape(np.shape(t) + (n,))
