r"""The tangent map of the constrained step (:mod:`.constrained`).

The step has three parts, each differentiated by the implicit function theorem
with its exact Jacobian at the solution:

1. the stage equations in :math:`Z = (q^1..q^s, \Lambda^0..\Lambda^{s-1})`,
   :math:`R^\nu = G^\nu + \delta_{\nu0}p_k - \mathcal G(q^\nu)^T\Lambda^\nu`,
   :math:`g(q^\nu) = 0`: :math:`A\,\delta Z = -(\delta G^\nu_0 + \delta_{\nu0}(\delta p_k -
   H_g(q_k, \Lambda^0)\,\delta q_k))`, with :math:`A` the Newton matrix of
   :func:`.constrained.solve_constrained_stages` assembled at the solution,
   :math:`\delta G^\nu_0` the variation through :math:`q^0 = q_k` (and
   :math:`\theta`) as in :mod:`.tangent`, and :math:`H_g(q, \Lambda) = \sum_j
   \Lambda_j \nabla^2 g_j(q)`;
2. :math:`\tilde p = G^s`: :math:`\delta\tilde p = \sum_i b_i[h\Phi_{is}\,\delta(L_q + f)^{(i)}
   + D_{is}\,\delta L_v^{(i)}]` with the full point variations;
3. the projection onto the hidden constraint, :math:`L_v(q, v) + \mathcal G^T\mu = \tilde p`,
   :math:`\mathcal G v = 0` at :math:`q = q_{k+1}`, then :math:`p_{k+1} = \tilde p -
   \mathcal G^T\mu`:

   .. math::

       \begin{pmatrix} L_{vv} & \mathcal G^T \\ \mathcal G & 0 \end{pmatrix}
       \begin{pmatrix}\delta v\\ \delta\mu\end{pmatrix} =
       \begin{pmatrix}\delta\tilde p - L_{qv}^T\delta q - H_g(q, \mu)\,\delta q\\
       -(\nabla^2 g_j\, v)^T\delta q\end{pmatrix},\qquad
       \delta p_{k+1} = \delta\tilde p - H_g(q, \mu)\,\delta q - \mathcal G^T\delta\mu .

So the tangent satisfies the linearised constraints :math:`\mathcal G\,\delta q_{k+1} = 0`
and the linearised hidden constraint: it stays tangent to the constraint
manifold in :math:`T^*Q`. Constraints that depend on time or on the parameters
differentiated are refused by the caller (their rate's derivative is not generated).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import kernel
from .common import (
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
from .constrained import (
    extrapolate_impulses,
    make_constraint_work,
    project_hidden,
    solve_constrained_stages,
)
from .general import make_work
from .linalg import lu_factor_inplace, lu_solve_inplace
from .on_demand import driver
from .point import point_constraint_hessian, point_constraint_jacobian, point_hessian
from .tangent import (
    advance_chaos,
    finish_chaos,
    linearize,
    make_tangent_work,
    point_variation,
    save_variations,
    start_chaos,
)
from .traits import HAS_FV, HAS_LQV

__all__ = ["constrained_tangent_loop"]


@kernel
def stage_matrix(fn, tk, h, qk, C, lam, prm, d, K, A, Gq, Hg, qn):
    """The constrained Newton matrix A at (C, lam) from the stage Jacobian K (dense)."""
    s1, n = C.shape
    s = s1 - 1
    m = lam.shape[1]
    sn = s * n
    A[:, :] = 0.0
    for i in range(sn):
        for j in range(sn):
            A[i, j] = K[i, j]
    for nu in range(s):
        tn = tk + d[nu] * h
        for a in range(n):
            qn[a] = qk[a] + C[nu, a]
        point_constraint_jacobian(fn, tn, qn, prm, Gq)
        for a in range(n):
            for j in range(m):
                A[nu * n + a, sn + nu * m + j] = -Gq[j * n + a]
        if nu >= 1:
            point_constraint_hessian(fn, tn, qn, lam[nu], prm, Hg)
            for a in range(n):
                for cc in range(n):
                    A[nu * n + a, (nu - 1) * n + cc] -= Hg[a * n + cc]
    for nu in range(1, s1):
        tn = tk + d[nu] * h
        for a in range(n):
            qn[a] = qk[a] + C[nu, a]
        point_constraint_jacobian(fn, tn, qn, prm, Gq)
        for j in range(m):
            for a in range(n):
                A[sn + (nu - 1) * m + j, (nu - 1) * n + a] = Gq[j * n + a]


@kernel
def projection_matrix(fn, t, q, v, mu, prm, B, Gq, Hmu, Hv, Hg, unit, Lq, Lv, Lqq, Lqv, Lvv, Fv):
    r"""The projection's saddle-point matrix B at (q, v, mu) (left in ``B``, not factored),
    :math:`H_g(q, \mu)` in ``Hmu``, the rows :math:`(\nabla^2 g_j v)^T` in ``Hv`` (m, n),
    and :math:`L_{qv}` in ``Lqv``."""
    n = q.shape[0]
    m = mu.shape[0]
    point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
    point_constraint_jacobian(fn, t, q, prm, Gq)
    point_constraint_hessian(fn, t, q, mu, prm, Hmu)
    B[:, :] = 0.0
    for a in range(n):
        for cc in range(n):
            B[a, cc] = Lvv[a * n + cc]
        for j in range(m):
            B[a, n + j] = Gq[j * n + a]
            B[n + j, a] = Gq[j * n + a]
    for j in range(m):
        unit[:] = 0.0
        unit[j] = 1.0
        point_constraint_hessian(fn, t, q, unit, prm, Hg)
        for a in range(n):
            acc = 0.0
            for cc in range(n):
                acc += Hg[a * n + cc] * v[cc]
            Hv[j, a] = acc


@kernel
def propagate_constrained(
    dq, dp, j, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, A, pivot, X, H0, B, pivot_b, Y,
    Gq1, Hmu, Hv, Lqv1, dQ, dV, dLq, dLv, traits,
):  # fmt: skip
    """One direction through the constrained step, (dq, dp) <- (dq', dp') in place."""
    r = b.shape[0]
    s1 = Phi.shape[1]
    s = s1 - 1
    n = dq.shape[0]
    m = Hv.shape[0]
    inv_h = 1.0 / h
    X[:] = 0.0
    for a in range(n):
        acc = dp[a]
        for cc in range(n):
            acc -= H0[a * n + cc] * dq[cc]
        X[a] = -acc
    for i in range(r):
        for a in range(n):
            dQ[a] = Phi[i, 0] * dq[a]
            dV[a] = D[i, 0] * dq[a] * inv_h
        point_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, j, dLq, dLv, True, traits, None)
        for nu in range(s):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                X[nu * n + a] -= wq * dLq[a] + wv * dLv[a]
    lu_solve_inplace(A, pivot, X)
    # d p~ = d G^s with the full point variations
    for a in range(n):
        Y[a] = 0.0
    for i in range(r):
        for a in range(n):
            x = Phi[i, 0] * dq[a]
            y = D[i, 0] * dq[a]
            for mu in range(1, s1):
                z = X[(mu - 1) * n + a]
                x += Phi[i, mu] * z
                y += D[i, mu] * z
            dQ[a] = x
            dV[a] = y * inv_h
        point_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, j, dLq, dLv, True, traits, None)
        for a in range(n):
            Y[a] += b[i] * (h * Phi[i, s] * dLq[a] + D[i, s] * dLv[a])
    for a in range(n):
        dq[a] = X[(s - 1) * n + a]
    # the projection: dp~ is Y[:n] now; p' = p~ - G^T mu
    for a in range(n):
        dp[a] = Y[a]
    for a in range(n):
        acc = Y[a]
        for cc in range(n):
            acc -= (Lqv1[cc * n + a] + Hmu[a * n + cc]) * dq[cc]
        Y[a] = acc
    for jj in range(m):
        acc = 0.0
        for a in range(n):
            acc -= Hv[jj, a] * dq[a]
        Y[n + jj] = acc
    lu_solve_inplace(B, pivot_b, Y)
    for a in range(n):
        acc = dp[a]
        for cc in range(n):
            acc -= Hmu[a * n + cc] * dq[cc]
        for jj in range(m):
            acc -= Gq1[jj * n + a] * Y[n + jj]
        dp[a] = acc


@driver
def constrained_tangent_loop(
    fn,
    traits,
    pattern,
    periodic,
    m,
    fnp,
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
    T,
    S,
    renormalize_every,
    t_origin,
    megno,
    stages_out,
    t_out,
    q_out,
    p_out,
    turns_out,
    T_out,
    S_out,
    growth_out,
    megno_out,
    iterations_out,
    iteration_total,
):
    """:func:`.constrained.constrained_loop` with the tangent map; the arguments and
    outputs of :func:`.tangent.tangent_loop` (``m`` the number of constraints in place
    of the couplings; ``stages_out`` must have no rows: no adjoint of constrained runs)."""
    n = q0.shape[0]
    s1 = d.shape[0]
    s = s1 - 1
    r = b.shape[0]
    n_dir = T.shape[1]
    n_theta = S.shape[1]
    couplings = (traits[HAS_LQV] != 0, traits[HAS_FV] != 0)
    work = make_work(s, n, traits, pattern)
    cw = make_constraint_work(s, n, m)
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    F, FV, HQQ, HQV, HVV, HFV, TQ, TV = make_tangent_work(r, s, n, n * n, n_theta)
    size = s * (n + m)
    A = np.zeros((size, size))
    pivot = np.zeros(size, dtype=np.int64)
    X = np.zeros(size)
    B = np.zeros((n + m, n + m))
    pivot_b = np.zeros(n + m, dtype=np.int64)
    Y = np.zeros(n + m)
    Gq = np.zeros(m * n)
    Gq1 = np.zeros(m * n)
    Hg = np.zeros(n * n)
    H0 = np.zeros(n * n)
    Hmu = np.zeros(n * n)
    Hv = np.zeros((m, n))
    unit = np.zeros(m)
    qn = np.zeros(n)
    Lqv1 = np.zeros(n * n)
    Lvv1 = np.zeros(n * n)
    Fv1 = np.zeros(n * n)
    Lq1 = np.zeros(n)
    Lv1 = np.zeros(n)
    Lqq1 = np.zeros(n * n)
    dQ = np.zeros(n)
    dV = np.zeros(n)
    dLq = np.zeros(n)
    dLv = np.zeros(n)
    dq = np.zeros(n)
    dp = np.zeros(n)
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
    chaos = renormalize_every > 0
    growth, sums = start_chaos(T, megno, t0, t_origin, h, chaos)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    save_variations(0, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    worst = 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
            extrapolate_impulses(lam, mu, b, E, multipliers)
        status, its, increment, residual = solve_constrained_stages(
            fn, tk, h, qk, C, lam, pk, prm, b, c, Phi, D, d, tol, maxiter, work, cw, traits, pattern
        )
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = min(its, 255)
        iteration_total[0] += its
        if status == STATUS_OK:
            # the point tables, K and A at the solution
            linearize(
                fn, fnp, tk, h, qk, C, prm, b, c, Phi, D, Q, V, F, FV, HQQ, HQV, HVV, HFV,
                TQ, TV, K, traits, pattern, couplings,
            )  # fmt: skip
            stage_matrix(fn, tk, h, qk, C, lam, prm, d, K, A, Gq, Hg, qn)
            if not lu_factor_inplace(A, pivot):
                status = STATUS_SINGULAR
            point_constraint_hessian(fn, tk, qk, lam[0], prm, H0)
            for a in range(n):
                acc = 0.0
                for i in range(r):
                    acc += b[i] * (h * Phi[i, s] * F[i, a] + D[i, s] * FV[i, a])
                p_tilde[a] = acc
            interpolate(r - 1, 1.0 / h, qk, C, Phi, D, Q, V)
            for a in range(n):
                vk[a] = V[a]
                Q[a] = qk[a] + C[s, a]
            if not project_hidden(
                fn, tk + h, Q, p_tilde, vk, mu, prm, tol, maxiter, work, cw, p_next
            ):
                status = STATUS_NEWTON_FAILED
            for a in range(n):
                if not abs(p_next[a]) < 1e300:
                    status = STATUS_NONFINITE
        if status == STATUS_OK:
            projection_matrix(
                fn, tk + h, Q, vk, mu, prm, B, Gq1, Hmu, Hv, Hg, unit, Lq1, Lv1, Lqq1, Lqv1,
                Lvv1, Fv1,
            )  # fmt: skip
            if not lu_factor_inplace(B, pivot_b):
                status = STATUS_SINGULAR
        if status != STATUS_OK:
            if k % save_every != 0:
                row = saved
                saved = save_row(
                    saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                )
                save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
            return status, k, saved, worst, increment
        if residual > worst:
            worst = residual
        for j in range(n_dir + n_theta):
            theta = j - n_dir
            for a in range(n):
                dq[a] = T[a, j] if theta < 0 else S[a, theta]
                dp[a] = T[n + a, j] if theta < 0 else S[n + a, theta]
            propagate_constrained(
                dq, dp, theta, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, A, pivot, X, H0, B,
                pivot_b, Y, Gq1, Hmu, Hv, Lqv1, dQ, dV, dLq, dLv, traits,
            )  # fmt: skip
            for a in range(n):
                if theta < 0:
                    T[a, j] = dq[a]
                    T[n + a, j] = dp[a]
                else:
                    S[a, theta] = dq[a]
                    S[n + a, theta] = dp[a]
        for a in range(n):
            pk[a] = p_next[a]
        advance_position(qk, q_lost, C, turns, periodic)
        if chaos:
            due = (k + 1) % renormalize_every == 0
            if not advance_chaos(T, growth, sums, tk + h - t_origin, h, due):
                return STATUS_NONFINITE, k + 1, saved, worst, 0.0
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            row = saved
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
            save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    finish_chaos(megno, sums, n_dir)
    _ = stages_out
    return STATUS_OK, n_steps, saved, worst, 0.0
