r"""The explicit loop with its tangent map: variations along compositions of Störmer–Verlet
and splittings.

The states are those of :func:`.explicit.explicit_loop` bit for bit (the same
operations in the same order, the same first-same-as-last forces). A sub-step
with drift :math:`\eta = a_i h` and kicks :math:`\beta^\pm = \beta^\pm_i h` from
:math:`(\tau_{i-1}, q, p)` to :math:`(\tau_i, q', p')`,

.. math::

    \bar p = p + \beta^- L_q(\tau_{i-1}, q),\quad
    q' = q + \eta M^{-1}(\bar p - \bar a),\quad
    p' = \bar p + \beta^+ L_q(\tau_i, q'),

with :math:`\bar a = \tfrac12(a(\tau_{i-1}) + a(\tau_i))`, is differentiated
exactly: a variation :math:`(\delta q, \delta p, \delta\theta)` goes to

.. math::

    \delta\bar p = \delta p + \beta^- \big(H\,\delta q + L_{q\theta}\,\delta\theta\big),\quad
    \delta q' = \delta q + \eta M^{-1}\big(\delta\bar p - \bar a_\theta\,\delta\theta\big),\quad
    \delta p' = \delta\bar p + \beta^+ \big(H'\delta q' + L'_{q\theta}\,\delta\theta\big),

with :math:`H = L_{qq} + f_q` at the sub-step's start, :math:`H'` at its end
(each point's Hessian serves the two sub-steps that meet there) and
:math:`a_\theta = \partial L_v(t, q, 0)/\partial\theta`. The mass matrix is
constant and does not depend on the parameters differentiated (the run
pipeline refuses those). Each sub-step is a symplectic map, so the tangent
:math:`\Phi_k` satisfies :math:`\Phi_k^T J \Phi_k = J` to round-off. The frame
``T`` (directions of :math:`(q_0, p_0)`) and the sensitivities ``S``
(:math:`\partial x/\partial\theta`) are advanced in place; renormalisation and
MEGNO as in :func:`.tangent.tangent_loop` (Benettin et al. 1980; Cincotta &
Simó 2000).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .common import STATUS_NONFINITE, STATUS_OK, save_row, wrap_angles
from .linalg import block_size
from .on_demand import driver
from .point import point_gradient, point_hessian
from .tangent import advance_chaos, finish_chaos, save_variations, start_chaos

__all__ = ["explicit_tangent_loop"]


@driver
def explicit_tangent_loop(
    fn,
    fnp,
    pattern,
    periodic,
    time_dependent,
    q0,
    p0,
    t0,
    h,
    n_steps,
    save_every,
    prm,
    Minv,
    Minv_diagonal,
    drift,
    kick_before,
    kick_after,
    nodes,
    T,
    S,
    renormalize_every,
    t_origin,
    megno,
    t_out,
    q_out,
    p_out,
    turns_out,
    T_out,
    S_out,
    growth_out,
    megno_out,
):
    r"""Run ``n_steps`` steps of a composition or splitting with its tangent map.

    ``fn`` the point functions' addresses (slots gradient and Hessian), ``fnp``
    the parameter derivatives' (slot gradient, flat ``a P + j``; unread without
    sensitivities), ``pattern`` the Hessians' banded storage or None,
    ``periodic`` the angles' mask or None, ``time_dependent`` a bool; the
    segment arguments of :func:`.explicit.explicit_loop`, ``Minv`` the dense
    :math:`M^{-1}`, ``Minv_diagonal`` its diagonal when :math:`M` is diagonal (n
    products per column, as the explicit loop's diagonal variant), else empty;
    ``drift``, ``kick_before``, ``kick_after`` and ``nodes`` the sub-steps (as in
    :func:`.explicit.explicit_loop`); ``T`` (2n, r), ``S``
    (2n, P), ``renormalize_every``, ``t_origin``, ``megno`` and the outputs
    ``T_out``, ``S_out``, ``growth_out``, ``megno_out`` as in
    :func:`.tangent.tangent_loop`. Returns the 5-tuple of :mod:`.abi`.
    """
    n = q0.shape[0]
    m = drift.shape[0]
    n_dir = T.shape[1]
    n_theta = S.shape[1]
    nnz = block_size(n, pattern)
    # a run-time switch: the variations' products dwarf its test
    diagonal = Minv_diagonal.shape[0] > 0
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    zero = np.zeros(n)
    lq = np.zeros(n)
    lq_next = np.zeros(n)
    a0 = np.zeros(n)
    a1 = np.zeros(n)
    rhs = np.zeros(n)
    H0 = np.zeros(nnz)
    H1 = np.zeros(nnz)
    lqh = np.zeros(n)
    lvh = np.zeros(n)
    hqv = np.zeros(nnz)
    hvv = np.zeros(nnz)
    hfv = np.zeros(nnz)
    TQ0 = np.zeros(n * n_theta)
    TQ1 = np.zeros(n * n_theta)
    TV0 = np.zeros(n * n_theta)
    TV1 = np.zeros(n * n_theta)
    dq = np.zeros(n)
    dp = np.zeros(n)
    g = np.zeros(n)
    half = np.zeros(n)
    q_before = np.zeros(n)
    p_before = np.zeros(n)
    lost_before = np.zeros(n)
    turns_before = np.zeros(n)
    T_before = np.zeros(T.shape)
    S_before = np.zeros(S.shape)
    chaos = renormalize_every > 0
    growth, sums = start_chaos(T, megno, t0, t_origin, h, chaos)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    save_variations(0, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    point_gradient(fn, t0, qk, zero, prm, lq, a0)
    point_gradient(fn, t0, qk, zero, prm, lq_next, a1)
    point_hessian(fn, t0, qk, zero, prm, lqh, lvh, H0, hqv, hvv, hfv)
    if n_theta > 0:
        point_gradient(fnp, t0, qk, zero, prm, TQ0, TV0)
    for k in range(n_steps):
        tk = t0 + k * h
        tk1 = t0 + (k + 1) * h
        finite = True
        T_before[:, :] = T
        S_before[:, :] = S
        for i in range(m):
            eta = drift[i] * h
            before = kick_before[i] * h
            after = kick_after[i] * h
            tau = t0 + (k + nodes[i]) * h
            if time_dependent:
                point_gradient(fn, tau, qk, zero, prm, lq_next, a1)
            if i == 0:
                for a in range(n):
                    q_before[a] = qk[a]
                    p_before[a] = pk[a]
                    lost_before[a] = q_lost[a]
                    turns_before[a] = turns[a]
            for a in range(n):
                rhs[a] = pk[a] + before * lq[a] - 0.5 * (a0[a] + a1[a])
            for a in range(n):
                if diagonal:
                    acc = Minv_diagonal[a] * rhs[a]
                else:
                    acc = 0.0
                    for b in range(n):
                        acc += Minv[a, b] * rhs[b]
                if periodic is None:
                    qk[a] += eta * acc
                else:
                    y = eta * acc - q_lost[a]
                    total = qk[a] + y
                    q_lost[a] = (total - qk[a]) - y
                    qk[a] = total
            if periodic is not None and i == m - 1:
                wrap_angles(qk, q_lost, turns, periodic)
            point_gradient(fn, tau, qk, zero, prm, lq_next, a1)
            # the derivatives at the sub-step's end: a translation by whole turns leaves
            # them unchanged, so they are taken where the state is kept
            point_hessian(fn, tau, qk, zero, prm, lqh, lvh, H1, hqv, hvv, hfv)
            if n_theta > 0:
                point_gradient(fnp, tau, qk, zero, prm, TQ1, TV1)
            # every column of the frame T, then of the sensitivities S (theta >= 0: the
            # parameter's inhomogeneous terms), through the sub-step; written out here:
            # an inlined helper costs an atomic reference count pair per array argument
            # and call, four times the arithmetic of a small system's sub-step
            for j in range(n_dir + n_theta):
                theta = j - n_dir
                for a in range(n):
                    if theta < 0:
                        dq[a] = T[a, j]
                        dp[a] = T[n + a, j]
                    else:
                        dq[a] = S[a, theta]
                        dp[a] = S[n + a, theta]
                    g[a] = 0.0
                if pattern is None:
                    for a in range(n):
                        acc = 0.0
                        for b in range(n):
                            acc += H0[a * n + b] * dq[b]
                        g[a] = acc
                else:
                    for e in range(pattern.shape[0]):
                        g[pattern[e, 0]] += H0[e] * dq[pattern[e, 1]]
                for a in range(n):
                    force = g[a]
                    if theta >= 0:
                        force += TQ0[a * n_theta + theta]
                    half[a] = dp[a] + before * force
                    dp[a] = half[a]  # the drift's right-hand side from here on
                    if theta >= 0:
                        dp[a] -= 0.5 * (TV0[a * n_theta + theta] + TV1[a * n_theta + theta])
                for a in range(n):
                    if diagonal:
                        acc = Minv_diagonal[a] * dp[a]
                    else:
                        acc = 0.0
                        for b in range(n):
                            acc += Minv[a, b] * dp[b]
                    dq[a] += eta * acc
                    g[a] = 0.0
                if pattern is None:
                    for a in range(n):
                        acc = 0.0
                        for b in range(n):
                            acc += H1[a * n + b] * dq[b]
                        g[a] = acc
                else:
                    for e in range(pattern.shape[0]):
                        g[pattern[e, 0]] += H1[e] * dq[pattern[e, 1]]
                for a in range(n):
                    force = g[a]
                    if theta >= 0:
                        force += TQ1[a * n_theta + theta]
                    if theta < 0:
                        T[a, j] = dq[a]
                        T[n + a, j] = half[a] + after * force
                    else:
                        S[a, theta] = dq[a]
                        S[n + a, theta] = half[a] + after * force
            for a in range(n):
                pk[a] += before * lq[a] + after * lq_next[a]
                lq[a] = lq_next[a]
                if time_dependent:
                    a0[a] = a1[a]
                if not abs(pk[a]) < 1e300 or not abs(qk[a]) < 1e300:
                    finite = False
            H0, H1 = H1, H0
            TQ0, TQ1 = TQ1, TQ0
            TV0, TV1 = TV1, TV0
        for a in range(2 * n):
            for j in range(n_dir):
                if not abs(T[a, j]) < 1e300:
                    finite = False
            for j in range(n_theta):
                if not abs(S[a, j]) < 1e300:
                    finite = False
        if finite and chaos:
            due = (k + 1) % renormalize_every == 0
            finite = advance_chaos(T, growth, sums, tk1 - t_origin, h, due)
        if not finite:
            if k % save_every != 0:
                row = saved
                saved = save_row(
                    saved, tk, q_before, lost_before, turns_before, p_before, t_out, q_out,
                    p_out, turns_out, periodic,
                )  # fmt: skip
                save_variations(
                    row, T_before, S_before, growth, sums, T_out, S_out, growth_out, megno_out
                )
            return STATUS_NONFINITE, k, saved, 0.0, np.nan
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            row = saved
            saved = save_row(
                saved, tk1, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
            )
            save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    finish_chaos(megno, sums, n_dir)
    return STATUS_OK, n_steps, saved, 0.0, np.nan
