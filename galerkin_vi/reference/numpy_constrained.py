r"""Reference backend of the constrained integrator (NumPy, no compiler).

The same equations as :mod:`galerkin_vi.loops.constrained` (see
:mod:`galerkin_vi.model.constraints`), written with whole arrays: the oracle the
compiled constrained loop is tested against.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..method.galerkin import MethodTables
from ..model.constraints import project_momentum
from ..model.system import LagrangianSystem
from ..newton import CONVERGED, NewtonResult, newton_solve
from .numpy import discrete_gradient, discrete_hessian, save_row, wrap_angles

__all__ = ["integrate", "solve_constrained_step"]


def solve_constrained_step(
    system: LagrangianSystem,
    tables: MethodTables,
    t0: float,
    h: float,
    qk: NDArray,
    pk: NDArray,
    guess: NDArray,
    lam: NDArray,
    prm: NDArray,
    tol: float,
    maxiter: int,
) -> tuple[NDArray, NDArray, NewtonResult]:
    r"""Solve the constrained stage equations for :math:`C^1..C^s` and the multipliers.

    The multipliers are carried as impulses :math:`h b_\nu\lambda^\nu`; the
    stopping test watches the positions only.
    ``guess`` (shape (s + 1, n), increments from ``qk``) and ``lam`` (impulses,
    shape (s, m)) are the starting values. Returns the increments, the
    impulses and Newton's result.
    """
    s1, n = guess.shape
    s, m = s1 - 1, system.m
    t_nodes = t0 + tables.d * h
    zero = np.zeros((1, n))

    def residual_and_jacobian(x: NDArray) -> tuple[NDArray, NDArray]:
        C = np.vstack([zero, x[: s * n].reshape(s, n)])
        impulse = x[s * n :].reshape(s, m)
        q_nodes = qk + C
        G, H = discrete_hessian(system, tables, t0, h, qk, C, prm)
        jac = system.constraint_jacobian(q_nodes, t_nodes, prm)  # (s + 1, m, n)
        hess = system.constraint_hessians(q_nodes, t_nodes, prm)  # (s + 1, m, n, n)
        R = G[:s].copy()
        R[0] += pk
        R -= np.einsum("vja,vj->va", jac[:s], impulse)
        K = H[:s, :, 1:, :].copy()
        for nu in range(1, s):
            K[nu, :, nu - 1, :] -= np.einsum("j,jab->ab", impulse[nu], hess[nu])
        J = np.zeros((s * (n + m), s * (n + m)))
        J[: s * n, : s * n] = K.reshape(s * n, s * n)
        for nu in range(s):
            J[nu * n : (nu + 1) * n, s * n + nu * m : s * n + (nu + 1) * m] = -jac[nu].T
            J[s * n + nu * m : s * n + (nu + 1) * m, nu * n : (nu + 1) * n] = jac[nu + 1]
        g = system.constraint_values(q_nodes[1:], t_nodes[1:], prm)
        return np.concatenate([R.ravel(), g.ravel()]), J

    x0 = np.concatenate([guess[1:].ravel(), lam.ravel()])
    # the stopping test watches the positions: the impulses' round-off floor is
    # far above theirs (trigonometric L_v of large angles), and they converge with them
    result = newton_solve(
        residual_and_jacobian,
        x0,
        tol=tol,
        maxiter=maxiter,
        watched=s * n,
        base=float(np.max(np.abs(qk))),
    )
    C = np.vstack([zero, result.x[: s * n].reshape(s, n)])
    return C, result.x[s * n :].reshape(s, m), result


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
    turns_out: NDArray,
    iterations_out: NDArray,
    iteration_total: NDArray,
) -> tuple[int, int, int, float, float]:
    """Same contract as the compiled :func:`galerkin_vi.loops.constrained.constrained_loop`.

    The system and the method tables take the place of the loop's point-function
    addresses and structure arguments; the outputs are written in place and the
    returned (status, steps done, rows saved, worst, increment) are the loop's.
    """
    d, E = tables.d, tables.extrapolation
    s = d.size - 1
    C = d[:, None] * h * v0[None, :]
    lam = np.zeros((s, system.m))
    qk, pk = q0.copy(), p0.copy()
    q_lost = np.zeros_like(q0)
    turns = np.zeros_like(q0)
    periodic = np.array(system.periodic, dtype=bool)
    wrap_angles(periodic, qk, q_lost, turns)
    outputs = (t_out, q_out, p_out, turns_out)
    save_row(0, t0, qk, q_lost, turns, pk, periodic, *outputs)
    saved, worst = 1, 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            C = E[:, 1:] @ C[1:] - C[s]
            C[0] = 0.0
        C, lam, result = solve_constrained_step(
            system, tables, tk, h, qk, pk, C, lam, prm, tol, maxiter
        )
        slot = k // save_every
        iterations_out[slot] = max(iterations_out[slot], result.iterations)
        iteration_total[0] += result.iterations
        status = 0 if result.status == CONVERGED else 1
        if status == 0:
            p_tilde = discrete_gradient(system, tables, tk, h, qk, C, prm)[s]
            v_end = tables.D[-1, 1:] @ C[1:] / h  # the polynomial's slope at the step's end
            try:
                p_next, _ = project_momentum(system, tk + h, qk + C[s], p_tilde, v_end, prm)
                status = 0 if np.all(np.isfinite(p_next)) else 3
            except ValueError:
                status = 1
        if status != 0:
            if k % save_every != 0:
                save_row(saved, tk, qk, q_lost, turns, pk, periodic, *outputs)
                saved += 1
            return status, k, saved, worst, result.increment
        worst = max(worst, result.residual)
        y = C[s] - q_lost
        total = qk + y
        q_lost = (total - qk) - y
        qk, pk = total, p_next
        wrap_angles(periodic, qk, q_lost, turns)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            save_row(saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, periodic, *outputs)
            saved += 1
    return 0, n_steps, saved, worst, 0.0
