r"""The compiled time loop of the constrained Galerkin integrator.

For a system with holonomic constraints, with the assembly of
:mod:`.general`. The method is collocated (control nodes equal
the Lobatto quadrature nodes, :math:`\Phi = I`, ``b[nu]`` the weight of node
:math:`\nu`). Per step the unknowns are the increments :math:`C^1..C^s` and the
multipliers as impulses :math:`\Lambda^\nu = h b_\nu\lambda^\nu` (:math:`\nu < s`),
:math:`s(n + m)` in all, ordered ``[C^1, ..., C^s, Lambda^0, ..., Lambda^{s-1}]``:

.. math::

    R^\nu = G^\nu + \delta_{\nu0}p_k - \mathcal G(q^\nu)^T\Lambda^\nu = 0
    \ (0 \le \nu < s),\qquad g(t_\nu, q^\nu) = 0\ (1 \le \nu \le s),

with Jacobian blocks :math:`K^{\nu\mu} - \delta_{\nu\mu} \sum_j
\Lambda^\nu_j \nabla^2 g_j(q^\nu)` (for :math:`\nu \ge 1`),
:math:`-\mathcal G(q^\nu)^T` in the multiplier columns and
:math:`\mathcal G(q^\nu)` in the constraint rows. After convergence the
momentum is projected onto the hidden constraint (see :mod:`galerkin_vi.model.constraints`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import kernel
from .common import (
    FREEZE,
    STATUS_NEWTON_FAILED,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR,
    advance_position,
    extrapolate,
    first_guess,
    interpolate,
    save_row,
    wrap_angles,
)
from .constrained_band import make_band_work, project_hidden_band, solve_constrained_band
from .general import assemble_gradient, assemble_newton, make_work
from .linalg import CONTINUE, CONVERGED, lu_factor_inplace, lu_solve_inplace, newton_status
from .on_demand import driver
from .point import (
    point_constraint,
    point_constraint_hessian,
    point_constraint_jacobian,
    point_constraint_rate,
    point_hessian,
)
from .traits import HAS_FV, HAS_LQV

__all__ = ["constrained_loop", "project_hidden", "solve_constrained_stages"]


@kernel
def make_constraint_work(s, n, m):
    """Work arrays of the constrained step (allocated once per run)."""
    size = s * (n + m)
    A = np.zeros((size, size))
    X = np.zeros(size)
    pivot = np.zeros(size, dtype=np.int64)
    g = np.zeros(m)
    Gq = np.zeros(m * n)
    gt = np.zeros(m)
    Hg = np.zeros(n * n)
    B = np.zeros((n + m, n + m))
    Y = np.zeros(n + m)
    pivot_b = np.zeros(n + m, dtype=np.int64)
    qn = np.zeros(n)
    return (A, X, pivot, g, Gq, gt, Hg, B, Y, pivot_b, qn)


@kernel
def solve_constrained_stages(
    fn, t0, h, qk, C, lam, pk, prm, b, c, Phi, D, d, tol, maxiter, work, cw, traits, pattern
):
    """Newton on the constrained stage equations; C[1:] and lam (impulses) hold the guess.

    Once an increment is below ``FREEZE``, later iterations reuse the LU
    factors (as in :func:`.general_loop`). Same stopping rule, applied to the increments
    :math:`C`: the impulses converge with them (Newton is quadratic in all
    unknowns jointly), but their own round-off floor is far higher (the
    momentum balance of large, cancelling terms). Returns
    (status, iterations, last increment, last residual max-norm).
    """
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    A, X, pivot, g, Gq, gt, Hg, B, Y, pivot_b, qn = cw
    s1, n = C.shape
    s = s1 - 1
    m = lam.shape[1]
    sn = s * n
    previous = np.inf
    residual = np.inf
    frozen = False
    base = 0.0  # as in general_loop: increments against the size of q = q_k + C
    for a in range(n):
        base = max(base, abs(qk[a]))
    for it in range(1, maxiter + 1):
        if frozen:
            # at the round-off floor: reuse the last factors, evaluate the residual only
            assemble_gradient(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        else:
            assemble_newton(
                fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K,
                traits, pattern, (traits[HAS_LQV] != 0, traits[HAS_FV] != 0),
            )  # fmt: skip
            A[:, :] = 0.0
            for i in range(sn):
                for j in range(sn):
                    A[i, j] = K[i, j]
        residual = 0.0
        for nu in range(s):
            tn = t0 + d[nu] * h
            for a in range(n):
                qn[a] = qk[a] + C[nu, a]
            point_constraint_jacobian(fn, tn, qn, prm, Gq)
            for a in range(n):
                val = G[nu, a] + (pk[a] if nu == 0 else 0.0)
                for j in range(m):
                    val -= Gq[j * n + a] * lam[nu, j]
                    if not frozen:
                        A[nu * n + a, sn + nu * m + j] = -Gq[j * n + a]
                X[nu * n + a] = -val
                if not abs(val) <= residual:
                    residual = abs(val)
            if nu >= 1 and not frozen:
                point_constraint_hessian(fn, tn, qn, lam[nu], prm, Hg)
                for a in range(n):
                    for cc in range(n):
                        A[nu * n + a, (nu - 1) * n + cc] -= Hg[a * n + cc]
        for nu in range(1, s1):
            tn = t0 + d[nu] * h
            for a in range(n):
                qn[a] = qk[a] + C[nu, a]
            point_constraint(fn, tn, qn, prm, g)
            if not frozen:
                point_constraint_jacobian(fn, tn, qn, prm, Gq)
            for j in range(m):
                row = sn + (nu - 1) * m + j
                X[row] = -g[j]
                if not abs(g[j]) <= residual:
                    residual = abs(g[j])
                if not frozen:
                    for a in range(n):
                        A[row, (nu - 1) * n + a] = Gq[j * n + a]
        if not residual < 1e300:
            return STATUS_NONFINITE, it, np.inf, residual
        if not frozen and not lu_factor_inplace(A, pivot):
            return STATUS_SINGULAR, it, np.inf, residual
        lu_solve_inplace(A, pivot, X)
        increment = 0.0
        size = 0.0
        for nu in range(1, s1):
            for a in range(n):
                delta = X[(nu - 1) * n + a]
                C[nu, a] += delta
                increment = max(increment, abs(delta))
                size = max(size, abs(C[nu, a]))
        for nu in range(s):
            for j in range(m):
                lam[nu, j] += X[sn + nu * m + j]
                if not abs(lam[nu, j]) < 1e300:
                    return STATUS_NONFINITE, it, np.inf, residual
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
def extrapolate_impulses(lam, mu, b, E, values):
    r"""Newton's guess of the impulses: the previous step's multiplier polynomial extrapolated.

    On entry ``lam`` holds the previous step's impulses :math:`\Lambda^\nu =
    h b_\nu\lambda^\nu` (:math:`\nu < s`) and ``mu`` its end impulse
    :math:`h b_s\lambda^s`; the multipliers :math:`\lambda^0..\lambda^s` at the
    control nodes define a polynomial, evaluated at this step's nodes with
    :math:`E_{\nu\mu} = \ell_\mu(1 + d_\nu)`. Collocated nodes: ``b[nu]``
    is the weight of node :math:`\nu`. ``values`` (length s + 1) is work space.
    """
    s, m = lam.shape
    for j in range(m):
        previous_end = mu[j] / b[s]
        for nu in range(s):
            values[nu] = lam[nu, j] / b[nu]
        values[s] = previous_end
        for nu in range(s):
            acc = 0.0
            for k in range(s + 1):
                acc += E[nu, k] * values[k]
            lam[nu, j] = b[nu] * acc


@kernel
def project_hidden(fn, t, q, p_tilde, v, mu, prm, tol, maxiter, work, cw, p_out):
    r"""Momentum on the hidden constraint: solve :math:`L_v(t, q, v) + \mathcal G^T\mu = \tilde p`,
    :math:`\mathcal G v + g_t = 0` by Newton from ``v``; write :math:`\tilde p - \mathcal G^T\mu`
    into ``p_out``. Returns True on convergence (``v`` then holds the velocity,
    ``mu`` the end impulse :math:`\mu = h b_s \lambda^s`).
    """
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    A, X, pivot, g, Gq, gt, Hg, B, Y, pivot_b, qn = cw
    n = q.shape[0]
    m = g.shape[0]
    point_constraint_jacobian(fn, t, q, prm, Gq)
    point_constraint_rate(fn, t, q, prm, gt)
    mu[:] = 0.0
    previous = np.inf
    for it in range(1, maxiter + 1):
        point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        B[:, :] = 0.0
        for a in range(n):
            acc = Lv[a] - p_tilde[a]
            for j in range(m):
                acc += Gq[j * n + a] * mu[j]
                B[a, n + j] = Gq[j * n + a]
                B[n + j, a] = Gq[j * n + a]
            Y[a] = -acc
            for cc in range(n):
                B[a, cc] = Lvv[a * n + cc]
        for j in range(m):
            acc = gt[j]
            for a in range(n):
                acc += Gq[j * n + a] * v[a]
            Y[n + j] = -acc
        if not lu_factor_inplace(B, pivot_b):
            return False
        lu_solve_inplace(B, pivot_b, Y)
        step = 0.0
        size = 0.0
        for a in range(n):
            v[a] += Y[a]
            step = max(step, abs(Y[a]))
            size = max(size, abs(v[a]))
        for j in range(m):
            mu[j] += Y[n + j]
            step = max(step, abs(Y[n + j]))
            size = max(size, abs(mu[j]))
        status = newton_status(step, previous, 1.0 + size, tol, it, maxiter)
        if status == CONVERGED:
            break
        if status != CONTINUE:
            return False
        previous = step
    for a in range(n):
        acc = p_tilde[a]
        for j in range(m):
            acc -= Gq[j * n + a] * mu[j]
        p_out[a] = acc
    return True


@driver
def constrained_loop(
    fn,
    traits,
    pattern,
    periodic,
    m,
    band,
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
    """Run ``n_steps`` constrained steps from a consistent (q0, p0).

    Same contract as :func:`.general_loop`; ``m`` is the number of constraints,
    ``band`` None (dense linear algebra) or the band order of
    :mod:`.constrained_band` (a compiled switch).
    """
    n = q0.shape[0]
    s1 = d.shape[0]
    s = s1 - 1
    work = make_work(s, n, traits, pattern)
    # the switch ``band`` leaves one of these branches (numba prunes the other)
    if band is None:
        cw = make_constraint_work(s, n, m)
        bw = None
    else:
        cw = make_constraint_work(0, n, m)  # the point values' work only
        bw = make_band_work(s, n, m, band)
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    lam = np.zeros((s, m))
    mu = np.zeros(m)
    multipliers = np.zeros(s + 1)
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    p_tilde = np.zeros(n)
    p_next = np.zeros(n)
    vk = v0.copy()
    first_guess(C, d, h, v0)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    worst = 0.0
    r = b.shape[0]
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
            extrapolate_impulses(lam, mu, b, E, multipliers)
        if band is None:
            status, its, increment, residual = solve_constrained_stages(
                fn, tk, h, qk, C, lam, pk, prm, b, c, Phi, D, d, tol, maxiter, work, cw, traits,
                pattern,
            )  # fmt: skip
        else:
            status, its, increment, residual = solve_constrained_band(
                fn, tk, h, qk, C, lam, pk, prm, b, c, Phi, D, d, tol, maxiter, work, cw, bw,
                traits, band, k > 0,
            )  # fmt: skip
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK:
            assemble_gradient(fn, tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
            for a in range(n):
                p_tilde[a] = G[s, a]
            # velocity guess: the polynomial's derivative at the step's end
            interpolate(r - 1, 1.0 / h, qk, C, Phi, D, Q, V)
            for a in range(n):
                vk[a] = V[a]
                Q[a] = qk[a] + C[s, a]
            if band is None:
                projected = project_hidden(
                    fn, tk + h, Q, p_tilde, vk, mu, prm, tol, maxiter, work, cw, p_next
                )
            else:
                projected = project_hidden_band(
                    fn, tk + h, Q, p_tilde, vk, mu, prm, tol, maxiter, work, cw, bw, band, p_next
                )
            if not projected:
                status = STATUS_NEWTON_FAILED
            for a in range(n):
                if not abs(p_next[a]) < 1e300:
                    status = STATUS_NONFINITE
        if status != STATUS_OK:
            if k % save_every != 0:
                saved = save_row(
                    saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                )
            return status, k, saved, worst, increment
        if residual > worst:
            worst = residual
        for a in range(n):
            pk[a] = p_next[a]
        advance_position(qk, q_lost, C, turns, periodic)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
    return STATUS_OK, n_steps, saved, worst, 0.0
