r"""Reference backend: the same equations, vectorised with NumPy, no compiler.

Slow (Python runs every step) but short and independent of the generated
kernel, which makes it the oracle the compiled backend is tested against. It
also serves the position-only DEL form.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..method.galerkin import MethodTables
from ..model.system import LagrangianSystem
from ..newton import CONVERGED, NewtonResult, newton_solve

__all__ = [
    "discrete_gradient",
    "discrete_hessian",
    "compensated_sum",
    "quadrature_points",
    "integrate",
    "momentum_increment",
    "solve_step",
    "save_row",
    "unwrapped",
    "wrap_angles",
]


def quadrature_points(tables: MethodTables, t0: float, h: float, qk: NDArray, C: NDArray):
    """Times, positions and velocities of the step's polynomial at the quadrature points.

    ``C`` are the control points as increments from ``qk`` (row 0 unused).
    """
    # increments C from the base point qk keep V free of eps*|q|/h rounding (see loops.general)
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
    r""":math:`G^\nu + F^\nu` at :math:`q^\nu = q_k + C^\nu`.

    :math:`G^\nu = \partial L_d/\partial q^\nu` plus the nodal forces :math:`F^\nu`.

    Returns shape (s + 1, n).

    ``C`` holds the control points as increments from ``qk`` (``C[0] = 0``).
    """
    n = system.n
    t, Q, V = quadrature_points(tables, t0, h, qk, C)
    values = system.evaluate("gradient", t, Q, V, prm)
    Lq, Lv = values[:, :n], values[:, n:]
    b = tables.b[:, None]
    return h * tables.Phi.T @ (b * Lq) + tables.D.T @ (b * Lv)


def momentum_increment(
    system: LagrangianSystem,
    tables: MethodTables,
    t0: float,
    h: float,
    qk: NDArray,
    C: NDArray,
    prm: NDArray,
) -> NDArray:
    r""":math:`h\sum_i b_i (L_q + f)^{(i)}`: :math:`G^s - p_k` once the stage equations hold.

    The compiled loops add it to :math:`p_k` with compensated summation (see
    ``loops.general.momentum_increment``); so does :func:`integrate`.
    """
    t, Q, V = quadrature_points(tables, t0, h, qk, C)
    Lq = system.evaluate("gradient", t, Q, V, prm)[:, : system.n]
    return h * (tables.b @ Lq)


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
    t, Q, V = quadrature_points(tables, t0, h, qk, C)
    values = system.evaluate("hessian", t, Q, V, prm)
    Lq, Lv = values[:, :n], values[:, n : 2 * n]
    # Lq and Lqq include the forces (L_q + f, L_qq + f_q); f_v follows when nonzero
    blocks = (values.shape[1] - 2 * n) // (n * n)
    Lqq, Lqv, Lvv, *fv = (
        values[:, 2 * n + k * n * n : 2 * n + (k + 1) * n * n].reshape(-1, n, n)
        for k in range(blocks)
    )
    Lqv_row = Lqv + fv[0] if fv else Lqv
    b, Phi, D = tables.b, tables.Phi, tables.D
    G = h * Phi.T @ (b[:, None] * Lq) + D.T @ (b[:, None] * Lv)
    H = (
        h * np.einsum("i,iv,iu,iac->vauc", b, Phi, Phi, Lqq)
        + np.einsum("i,iv,iu,iac->vauc", b, Phi, D, Lqv_row)
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

    result = newton_solve(
        residual_and_jacobian,
        guess[1:].ravel(),
        tol=tol,
        maxiter=maxiter,
        base=float(np.max(np.abs(qk))),
    )
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
    turns_out: NDArray,
    iterations_out: NDArray,
    iteration_total: NDArray,
) -> tuple[int, int, int, float, float]:
    """Same contract as the compiled :func:`galerkin_vi.loops.general.general_loop`.

    The system and the method tables take the place of the loop's point-function
    addresses and structure arguments; the outputs are written in place and the
    returned (status, steps done, rows saved, worst, increment) are the loop's.
    """
    d, E = tables.d, tables.extrapolation
    s = d.size - 1
    C = d[:, None] * h * v0[None, :]
    qk, pk = q0.copy(), p0.copy()
    q_lost = np.zeros_like(q0)
    p_lost = np.zeros_like(q0)
    turns = np.zeros_like(q0)
    periodic = np.array(system.periodic, dtype=bool)
    wrap_angles(periodic, qk, q_lost, turns)
    outputs = (t_out, q_out, p_out, turns_out)
    save_row(0, t0, qk, q_lost, turns, pk, periodic, *outputs)
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
            dp = momentum_increment(system, tables, tk, h, qk, C, prm)
            status = 0 if np.all(np.isfinite(dp)) else 3
        if status != 0:
            if k % save_every != 0:  # keep the last good state, even if not due for saving
                save_row(saved, tk, qk, q_lost, turns, pk, periodic, *outputs)
                saved += 1
            return status, k, saved, worst, result.increment
        worst = max(worst, result.residual)
        # compensated (Kahan) summation of position and momentum, as in the compiled kernel
        qk, q_lost = compensated_sum(qk, q_lost, C[s])
        pk, p_lost = compensated_sum(pk, p_lost, dp)
        wrap_angles(periodic, qk, q_lost, turns)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            save_row(saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, periodic, *outputs)
            saved += 1
    return 0, n_steps, saved, worst, 0.0


def compensated_sum(x: NDArray, lost: NDArray, y: NDArray) -> tuple[NDArray, NDArray]:
    """(x + y, its rounding error) by Kahan's compensated summation; ``lost`` from the last call."""
    z = y - lost
    total = x + z
    return total, (total - x) - z


# 2 pi = TWO_PI_HI + TWO_PI_LO, both floats
TWO_PI_HI = 6.283185307179586
TWO_PI_LO = 2.4492935982947064e-16


def wrap_angles(periodic: NDArray, qk: NDArray, q_lost: NDArray, turns: NDArray) -> None:
    """Move periodic coordinates into [-pi, pi) by whole turns, in place (see the kernel)."""
    for a in np.flatnonzero(periodic):
        if not -np.pi <= qk[a] < np.pi:
            k = np.floor((qk[a] + np.pi) / TWO_PI_HI)
            qk[a] -= k * TWO_PI_HI
            q_lost[a] += k * TWO_PI_LO
            turns[a] += k
        while qk[a] >= np.pi:
            qk[a] -= TWO_PI_HI
            q_lost[a] += TWO_PI_LO
            turns[a] += 1.0
        while qk[a] < -np.pi:
            qk[a] += TWO_PI_HI
            q_lost[a] -= TWO_PI_LO
            turns[a] -= 1.0


def save_row(saved, t, qk, q_lost, turns, pk, periodic, t_out, q_out, p_out, turns_out) -> None:
    """Row ``saved`` of the outputs, as the compiled ``save_row`` writes it."""
    t_out[saved] = t
    q_out[saved] = np.where(periodic, qk - q_lost, qk)
    p_out[saved] = pk
    if periodic.any():
        turns_out[saved] = turns


def unwrapped(q: NDArray, turns: NDArray) -> NDArray:
    """Continuous angles from saved states in [-pi, pi) and the whole turns removed."""
    return (q + turns * TWO_PI_HI) + turns * TWO_PI_LO
