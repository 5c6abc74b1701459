r"""Reference backend: the same equations, vectorised with NumPy, no compiler.

Slow (Python runs every step) but short and independent of the generated
kernel, which makes it the oracle the compiled backend is tested against. It
also serves the position-only DEL form.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..method import MethodTables
from ..newton import CONVERGED, NewtonResult, newton_solve
from ..system import LagrangianSystem

__all__ = ["discrete_gradient", "discrete_hessian", "integrate", "solve_step"]


def _points(tables: MethodTables, t0: float, h: float, qk: NDArray, C: NDArray):
    # increments C from the base point qk keep V free of eps*|q|/h rounding (see kernel_template)
    t = t0 + tables.c * h
    Q = qk + tables.Phi[:, 1:] @ C[1:]
    V = (tables.D[:, 1:] @ C[1:]) / h
    return t, Q, V


def discrete_gradient(
    system: LagrangianSystem,
    tables: MethodTables,
    t0: float,
    h: float,
    qk: NDArray,
    C: NDArray,
    prm: NDArray,
) -> NDArray:
    r""":math:`G^\nu = \partial L_d/\partial q^\nu` at :math:`q^\nu = q_k + C^\nu`.

    Returns shape (s + 1, n).

    ``C`` holds the control points as increments from ``qk`` (``C[0] = 0``).
    """
    n = system.n
    t, Q, V = _points(tables, t0, h, qk, C)
    values = system.evaluate("gradient", t, Q, V, prm)
    Lq, Lv = values[:, :n], values[:, n:]
    b = tables.b[:, None]
    return h * tables.Phi.T @ (b * Lq) + tables.D.T @ (b * Lv)


def discrete_hessian(
    system: LagrangianSystem,
    tables: MethodTables,
    t0: float,
    h: float,
    qk: NDArray,
    C: NDArray,
    prm: NDArray,
) -> tuple[NDArray, NDArray]:
    r"""Gradient and full Hessian :math:`\partial^2 L_d/\partial q^\nu\partial q^\mu`.

    Returns ``G`` of shape (s + 1, n) and ``H`` of shape (s + 1, n, s + 1, n).
    """
    n = system.n
    t, Q, V = _points(tables, t0, h, qk, C)
    values = system.evaluate("hessian", t, Q, V, prm)
    Lq, Lv = values[:, :n], values[:, n : 2 * n]
    Lqq, Lqv, Lvv = (
        values[:, 2 * n + k * n * n : 2 * n + (k + 1) * n * n].reshape(-1, n, n) for k in range(3)
    )
    b, Phi, D = tables.b, tables.Phi, tables.D
    G = h * Phi.T @ (b[:, None] * Lq) + D.T @ (b[:, None] * Lv)
    H = (
        h * np.einsum("i,iv,iu,iac->vauc", b, Phi, Phi, Lqq)
        + np.einsum("i,iv,iu,iac->vauc", b, Phi, D, Lqv)
        + np.einsum("i,iv,iu,ica->vauc", b, D, Phi, Lqv)
        + np.einsum("i,iv,iu,iac->vauc", b, D, D, Lvv) / h
    )
    return G, H


def solve_step(
    system: LagrangianSystem,
    tables: MethodTables,
    t0: float,
    h: float,
    qk: NDArray,
    pk: NDArray,
    guess: NDArray,
    prm: NDArray,
    tol: float,
    maxiter: int,
) -> tuple[NDArray, NewtonResult]:
    r"""Solve :math:`p_k + G^0 = 0`, :math:`G^\nu = 0` (:math:`0<\nu<s`) for :math:`q^1..q^s`.

    ``guess`` and the returned ``C`` (shape (s + 1, n)) are increments from ``qk``.
    """
    s1, n = guess.shape
    s = s1 - 1
    zero = np.zeros((1, n))

    def residual_and_jacobian(x: NDArray) -> tuple[NDArray, NDArray]:
        C = np.vstack([zero, x.reshape(s, n)])
        G, H = discrete_hessian(system, tables, t0, h, qk, C, prm)
        R = G[:s].copy()
        R[0] += pk
        K = H[:s, :, 1:, :].reshape(s * n, s * n)
        return R.ravel(), K

    result = newton_solve(residual_and_jacobian, guess[1:].ravel(), tol=tol, maxiter=maxiter)
    return np.vstack([zero, result.x.reshape(s, n)]), result


def integrate(
    system: LagrangianSystem,
    tables: MethodTables,
    q0: NDArray,
    p0: NDArray,
    v0: NDArray,
    t0: float,
    h: float,
    n_steps: int,
    save_every: int,
    prm: NDArray,
    tol: float,
    maxiter: int,
    t_out: NDArray,
    q_out: NDArray,
    p_out: NDArray,
    iterations_out: NDArray,
    iteration_total: NDArray,
) -> tuple[int, int, int, float, float]:
    """Same contract as the compiled ``integrate_kernel`` (see kernel_template)."""
    d, E = tables.d, tables.extrapolation
    s = d.size - 1
    C = d[:, None] * h * v0[None, :]
    qk, pk = q0.copy(), p0.copy()
    q_lost = np.zeros_like(q0)
    t_out[0], q_out[0], p_out[0] = t0, q0, p0
    saved, worst = 1, 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            # previous polynomial extrapolated and re-based at the new start point
            C = E[:, 1:] @ C[1:] - C[s]
            C[0] = 0.0
        C, result = solve_step(system, tables, tk, h, qk, pk, C, prm, tol, maxiter)
        slot = k // save_every
        iterations_out[slot] = max(iterations_out[slot], result.iterations)
        iteration_total[0] += result.iterations
        status = 0 if result.status == CONVERGED else 1
        if status == 0:
            p_next = discrete_gradient(system, tables, tk, h, qk, C, prm)[s]
            status = 0 if np.all(np.isfinite(p_next)) else 3
        if status != 0:
            if k % save_every != 0:  # keep the last good state, even if not due for saving
                t_out[saved], q_out[saved], p_out[saved] = tk, qk, pk
                saved += 1
            return status, k, saved, worst, result.increment
        worst = max(worst, result.residual)
        # compensated (Kahan) summation of the position, as in the compiled kernel
        y = C[s] - q_lost
        total = qk + y
        q_lost = (total - qk) - y
        qk, pk = total, p_next
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            t_out[saved] = t0 + (k + 1) * h
            q_out[saved], p_out[saved] = qk, pk
            saved += 1
    return 0, n_steps, saved, worst, 0.0
