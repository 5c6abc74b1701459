r"""The general Newton loop: any regular Lagrangian, forces, time dependence.

With :math:`f` the external forces (discrete Lagrange–d'Alembert; the point
functions return :math:`L_q + f` and :math:`L_{qq} + f_q`, and :math:`f_v`
separately when it is not zero), the stage equations of one step are

.. math::

    G^\nu = \sum_i b_i \big[h\,\Phi_{i\nu} (L_q + f)^{(i)} + D_{i\nu} L_v^{(i)}\big],
    \qquad R^0 = p_k + G^0,\quad R^\nu = G^\nu\ (1 \le \nu < s),
    \qquad p_{k+1} = G^s = p_k + h \sum_i b_i (L_q + f)^{(i)},

solved by Newton's method with the exact Jacobian (notation of :mod:`.common`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import driver, kernel
from .common import (
    FREEZE,
    STATUS_NEWTON_FAILED,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR,
    advance_position,
    compensated_add,
    extrapolate,
    first_guess,
    interpolate,
    save_row,
    wrap_angles,
)
from .linalg import (
    CONTINUE,
    CONVERGED,
    add_block,
    block_size,
    factor_jacobian,
    new_jacobian,
    newton_status,
    solve_jacobian,
    unknown,
)
from .point import point_gradient, point_hessian
from .traits import HAS_FV

__all__ = [
    "assemble_gradient",
    "assemble_newton",
    "general_loop",
    "make_work",
    "momentum_increment",
    "solve_stages",
]


@kernel
def assemble_gradient(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G):
    """G[nu] = dL_d/dq^nu for all nu = 0..s."""
    r = b.shape[0]
    s1, n = C.shape
    G[:, :] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_gradient(fn, t0 + c[i] * h, Q, V, prm, Lq, Lv)
        for nu in range(s1):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                G[nu, a] += wq * Lq[a] + wv * Lv[a]


@kernel
def momentum_increment(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, out):
    r"""out = h \sum_i b_i (L_q + f)^{(i)}, the step's momentum change; False if not finite.

    Summing :math:`G^\nu` over all :math:`\nu` (:math:`\sum_\nu \ell_\nu = 1`,
    :math:`\sum_\nu \ell_\nu' = 0`) shows that :math:`p_k` plus this is
    :math:`G^s = p_{k+1}` once the stage equations hold. Formed as :math:`G^s`
    directly, the new momentum is a sum of terms of the size of :math:`p` that
    cancel down to it, with a rounding error of order :math:`\varepsilon|p|`
    in every step; the increment is small, and :func:`compensated_add` carries
    the rounding of its addition to the next step. Measured over 1e6 steps
    (outer solar system, s = 3, h = 10 d): relative energy error in the last
    tenth 5.2e-12 through :math:`G^s`, 9e-15 this way.
    """
    r = b.shape[0]
    n = qk.shape[0]
    for a in range(n):
        out[a] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_gradient(fn, t0 + c[i] * h, Q, V, prm, Lq, Lv)
        for a in range(n):
            out[a] += b[i] * Lq[a]
    finite = True
    for a in range(n):
        out[a] *= h
        if not abs(out[a]) < 1e300:
            finite = False
    return finite


@kernel
def assemble_newton(
    fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K, traits, pattern,
    couplings,
):  # fmt: skip
    """G as above and K[(nu, a), (mu, c)] = dG^nu_a / dq^mu_c, nu = 0..s-1, mu = 1..s.

    K is stored as :func:`~.linalg.new_jacobian` allocates it, rows and columns
    placed by :func:`~.linalg.unknown`.
    """
    r = b.shape[0]
    s1, n = C.shape
    s = s1 - 1
    G[:, :] = 0.0
    K[:, :] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_hessian(fn, t0 + c[i] * h, Q, V, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        for nu in range(s1):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                G[nu, a] += wq * Lq[a] + wv * Lv[a]
        for nu in range(s):
            for mu in range(1, s1):
                add_block(
                    K,
                    nu,
                    mu,
                    s,
                    n,
                    b[i] * D[i, nu] * D[i, mu] / h,
                    Lvv,
                    b[i] * h * Phi[i, nu] * Phi[i, mu],
                    Lqq,
                    b[i] * Phi[i, nu] * D[i, mu],
                    b[i] * D[i, nu] * Phi[i, mu],
                    Lqv,
                    Fv,
                    traits,
                    pattern,
                    couplings,
                )


@kernel
def solve_stages(
    fn, t0, h, qk, C, pk, prm, b, c, Phi, D, tol, maxiter, work, traits, pattern, couplings
):
    r"""Newton on the stage equations; C[1:] holds the guess on entry, the solution on exit.

    Full Newton with the exact Jacobian, assembled and factorised, until an
    increment is below ``FREEZE * (1 + |C|)``: the next one is then at
    round-off level, so the remaining iterations reuse the last LU factors and
    evaluate only the gradient. The stopping rule: increment zero, or no longer
    decreasing once below ``tol`` (:func:`~galerkin_vi.newton.newton_status`).

    Returns (status, iterations, last increment, last residual max-norm).
    """
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    s1, n = C.shape
    s = s1 - 1
    banded = pattern is not None
    previous = np.inf
    residual = np.inf
    frozen = False
    # increments are judged against the size of q = q_k + C: far from the origin the
    # round-off floor of C is that of q
    base = 0.0
    for a in range(n):
        base = max(base, abs(qk[a]))
    for it in range(1, maxiter + 1):
        if frozen:
            assemble_gradient(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        else:
            assemble_newton(
                fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K,
                traits, pattern, couplings,
            )  # fmt: skip
        residual = 0.0
        for nu in range(s):
            for a in range(n):
                val = G[nu, a] + (pk[a] if nu == 0 else 0.0)
                R[unknown(nu, a, s, n, banded)] = -val
                if not abs(val) <= residual:  # also catches NaN
                    residual = abs(val)
        if not residual < 1e300:
            return STATUS_NONFINITE, it, np.inf, residual
        if not frozen and not factor_jacobian(K, piv, s, traits, pattern):
            return STATUS_SINGULAR, it, np.inf, residual
        solve_jacobian(K, piv, s, R, traits, pattern)
        increment = 0.0
        size = 0.0
        for nu in range(1, s1):
            for a in range(n):
                delta = R[unknown(nu - 1, a, s, n, banded)]
                C[nu, a] += delta
                if abs(delta) > increment:
                    increment = abs(delta)
                if abs(C[nu, a]) > size:
                    size = abs(C[nu, a])
        status = newton_status(increment, previous, 1.0 + max(size, base), tol, it, maxiter)
        if status == CONVERGED:
            return STATUS_OK, it, increment, residual
        if status != CONTINUE:
            return STATUS_NEWTON_FAILED, it, increment, residual
        if increment <= FREEZE * (1.0 + size):
            frozen = True
        previous = increment
    return STATUS_NEWTON_FAILED, maxiter, previous, residual


@kernel
def make_work(s, n, traits, pattern):
    """Preallocated work arrays of one step (allocated once per run)."""
    nnz = block_size(n, pattern)
    Q = np.zeros(n)
    V = np.zeros(n)
    Lq = np.zeros(n)
    Lv = np.zeros(n)
    Lqq = np.zeros(nnz)
    Lqv = np.zeros(nnz)
    Lvv = np.zeros(nnz)
    G = np.zeros((s + 1, n))
    K = new_jacobian(s, n, traits, pattern)
    R = np.zeros(s * n)
    piv = np.zeros(s * n, dtype=np.int64)
    Fv = np.zeros(nnz if traits[HAS_FV] != 0 else 1)
    return (Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv)


@driver
def general_loop(
    fn,
    traits,
    pattern,
    periodic,
    couplings,
    q0,
    p0,
    v0,
    t0,
    h,
    n_steps,
    save_every,
    prm,
    b,
    c,
    d,
    Phi,
    D,
    E,
    tol,
    maxiter,
    t_out,
    q_out,
    p_out,
    turns_out,
    iterations_out,
    iteration_total,
):
    """Run ``n_steps`` steps of the position–momentum map from (q0, p0).

    ``fn`` holds the point functions' addresses (:mod:`.point`), ``traits``,
    ``pattern`` (``None``: dense) and ``periodic`` the system's structure,
    ``couplings`` the switch of :math:`L_{qv}` and :math:`f_v` (:mod:`.traits`).
    ``iterations_out[j]`` receives the largest Newton iteration count of steps
    ``j*save_every .. (j+1)*save_every - 1`` (every step when save_every = 1) and
    ``iteration_total[0]`` their sum: a long run with ``save_every`` stores
    nothing per step.

    The new momentum is :math:`p_k` plus :func:`momentum_increment`, added
    with compensated summation like the positions. Saves rows at steps k with
    k % save_every == 0 and at the last step.
    Returns (status, steps completed, rows saved, max residual, failing increment).
    """
    n = q0.shape[0]
    s1 = d.shape[0]
    s = s1 - 1
    work = make_work(s, n, traits, pattern)
    Q, V, Lq, Lv = work[0], work[1], work[2], work[3]
    dp = np.zeros(n)  # the step's momentum change
    p_lost = np.zeros(n)  # compensated summation of the momenta
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)  # compensated summation: low-order bits of q lost so far
    turns = np.zeros(n)  # whole turns removed from periodic coordinates
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    first_guess(C, d, h, v0)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    worst = 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        status, its, increment, residual = solve_stages(
            fn, tk, h, qk, C, pk, prm, b, c, Phi, D, tol, maxiter, work, traits, pattern, couplings
        )
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK and not momentum_increment(
            fn, tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, dp
        ):
            status = STATUS_NONFINITE
        if status != STATUS_OK:
            if k % save_every != 0:  # keep the last good state, even if not due for saving
                saved = save_row(
                    saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                )
            return status, k, saved, worst, increment
        if residual > worst:
            worst = residual
        compensated_add(pk, p_lost, dp)
        advance_position(qk, q_lost, C, turns, periodic)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
    return STATUS_OK, n_steps, saved, worst, 0.0
