r"""Velocity-level maps of a contact run, compiled: the inverse Legendre transform, the
hidden constraint's projection, the impact law and the stopped slip.

Each is one saddle-point Newton iteration in the velocities :math:`v` and
impulses :math:`\Lambda`,

.. math::

    L_v(t, q, v) = p + D^{\mathsf T}\Lambda, \qquad C\,v = \text{targets},

with the exact Jacobian :math:`\begin{pmatrix} L_{vv} & -D^{\mathsf T} \\ C & 0
\end{pmatrix}` (:func:`saddle_velocity`), as their NumPy forms
(:func:`galerkin_vi.contact.impact.impulse`, :func:`~galerkin_vi.contact.impact.stop_slip`,
:func:`galerkin_vi.model.constraints.project_momentum`,
:meth:`galerkin_vi.LagrangianSystem.inverse_legendre`) do: the projection takes
D = C = the constraints' Jacobian :math:`\mathcal G` and targets :math:`-g_t`; a
frictionless impact D = C = (:math:`\nabla\varphi`, :math:`\mathcal G`) with targets
(:math:`-e u^-`, :math:`-g_t`); a sticking impact adds the slip rows T with targets
:math:`-w_0`; a stopped slip D = C = T. :math:`L_v` and :math:`L_{vv}` come from the
system's ``point_hessian``.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import called
from .linalg import lu_factor_inplace, lu_solve_inplace
from .point import point_constraint_jacobian, point_constraint_rate, point_hessian

__all__ = ["inverse_legendre", "project_momentum", "saddle_velocity"]

#: Newton iterations at most (the NumPy forms' limits)
LEGENDRE_ITERATIONS = 50
SADDLE_ITERATIONS = 50


@called
def inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv, K, piv):
    r""":math:`v` with :math:`L_v(t, q, v) = p` into ``v``: Newton on :math:`L_{vv}` from
    v = 0, a step halved while it does not reduce the residual; one step when L is
    quadratic in v. False when no velocity is found.

    ``work`` has 6 rows of length n at least; K (n, n) and piv (n,) the factors.
    """
    Lq = work[0, :n]
    Lv = work[1, :n]
    r = work[2, :n]
    dv = work[3, :n]
    trial = work[4, :n]
    rt = work[5, :n]
    for a in range(n):
        v[a] = 0.0
    point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
    for a in range(n):
        r[a] = Lv[a] - p[a]
    for it in range(LEGENDRE_ITERATIONS):
        if it > 0:
            point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        for a in range(n):
            for cc in range(n):
                K[a, cc] = Lvv[a * n + cc]
            dv[a] = -r[a]
        if not lu_factor_inplace(K, piv):
            return False
        lu_solve_inplace(K, piv, dv)
        if quadratic:
            for a in range(n):
                v[a] += dv[a]
            break
        size = 0.0
        moving = False
        for a in range(n):
            size = max(size, abs(r[a]))
            if dv[a] != 0.0:
                moving = True
        step = 1.0
        for _ in range(60):
            for a in range(n):
                trial[a] = v[a] + step * dv[a]
            point_hessian(fn, t, q, trial, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
            largest = 0.0
            for a in range(n):
                rt[a] = Lv[a] - p[a]
                value = abs(rt[a])
                if not value <= largest:
                    largest = value
            if largest <= max(size, 1e-300) or not moving:
                break
            step *= 0.5
        change = 0.0
        biggest = 0.0
        for a in range(n):
            change = max(change, abs(trial[a] - v[a]))
            biggest = max(biggest, abs(trial[a]))
            v[a] = trial[a]
            r[a] = rt[a]
        if change <= 1e-15 * (1.0 + biggest):
            break
    if quadratic:
        return True
    for a in range(n):
        if not (abs(v[a]) < np.inf and abs(r[a]) <= 1e-10 * (1.0 + abs(p[a]))):
            return False
    return True


@called
def saddle_velocity(
    fn, t, q, p, prm, n, v, Dm, Cm, targets, k, lam, work, Lqq, Lqv, Lvv, Fv, K, piv, x
):  # fmt: skip
    r"""Newton on :math:`L_v(v) = p + D^{\mathsf T}\Lambda`, :math:`C v = \text{targets}`
    from ``v`` (in and out) and :math:`\Lambda = 0`; :math:`\Lambda` into ``lam[:k]``.

    ``Dm`` and ``Cm`` hold k rows of length n; ``K`` (n + k, n + k), ``piv`` and ``x``
    (n + k) are work. False if the saddle-point matrix is singular or the iteration
    does not converge.
    """
    Lq = work[0, :n]
    Lv = work[1, :n]
    size = n + k
    Kk = K[:size, :size]
    pk = piv[:size]
    xk = x[:size]
    for i in range(k):
        lam[i] = 0.0
    for _ in range(SADDLE_ITERATIONS):
        point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        for a in range(n):
            value = Lv[a] - p[a]
            for i in range(k):
                value -= Dm[i, a] * lam[i]
            xk[a] = -value
            for cc in range(n):
                Kk[a, cc] = Lvv[a * n + cc]
            for i in range(k):
                Kk[a, n + i] = -Dm[i, a]
        for i in range(k):
            value = -targets[i]
            for a in range(n):
                value += Cm[i, a] * v[a]
                Kk[n + i, a] = Cm[i, a]
            xk[n + i] = -value
            for j in range(k):
                Kk[n + i, n + j] = 0.0
        if not lu_factor_inplace(Kk, pk):
            return False
        lu_solve_inplace(Kk, pk, xk)
        step = 0.0
        scale = 1.0
        for a in range(n):
            v[a] += xk[a]
            step = max(step, abs(xk[a]))
            scale = max(scale, abs(v[a]))
        for i in range(k):
            lam[i] += xk[n + i]
            step = max(step, abs(xk[n + i]))
            scale = max(scale, abs(lam[i]))
        if not step < np.inf:
            return False
        if step <= 1e-15 * scale:
            return True
    return False


@called
def project_momentum(fn, t, q, p, prm, n, mh, quadratic):
    r"""``p`` projected onto the hidden constraint :math:`\mathcal G v + g_t = 0` at
    (t, q), in place: :math:`p + \mathcal G^{\mathsf T}\Lambda` with
    :math:`L_v(v) = p + \mathcal G^{\mathsf T}\Lambda` (from the velocity of p).
    False where a Newton iteration fails."""
    work = np.zeros((6, max(n, mh * n)))
    Lqq = np.zeros(n * n)
    Lqv = np.zeros(n * n)
    Lvv = np.zeros(n * n)
    Fv = np.zeros(n * n)
    K = np.zeros((n + mh, n + mh))
    piv = np.zeros(n + mh, dtype=np.int64)
    xs = np.zeros(n + mh)
    v = np.zeros(n)
    if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv,
                            K[:n, :n], piv[:n]):  # fmt: skip
        return False
    Gq = np.zeros(mh * n)
    gt = np.zeros(mh)
    point_constraint_jacobian(fn, t, q, prm, Gq)
    point_constraint_rate(fn, t, q, prm, gt)
    Dm = np.zeros((mh, n))
    targets = np.zeros(mh)
    lam = np.zeros(mh)
    for i in range(mh):
        targets[i] = -gt[i]
        for a in range(n):
            Dm[i, a] = Gq[i * n + a]
    if not saddle_velocity(fn, t, q, p, prm, n, v, Dm, Dm, targets, mh, lam, work, Lqq, Lqv,
                           Lvv, Fv, K, piv, xs):  # fmt: skip
        return False
    for a in range(n):
        for i in range(mh):
            p[a] += Dm[i, a] * lam[i]
    return True


#: fixed-point sweeps on the slip direction before Newton (the NumPy law's)
DIRECTION_SWEEPS = 3
#: Newton iterations of the sliding law at most
SLIDING_ITERATIONS = 30


@called
def sliding_impulse(
    fn, t, q, p, prm, n, mh, v_minus, g, T, w0, slips, target, mu, Gq, gt, out, work, Lqq,
    Lqv, Lvv, Fv,
):  # fmt: skip
    r"""A sliding impact (:func:`galerkin_vi.contact.impact._sliding`): the impulse
    :math:`\Lambda_n(\nabla\varphi - \mu T^{\mathsf T} d) + \mathcal G^{\mathsf T}\nu` with
    :math:`d = w^+/|w^+|` the slip direction after, :math:`\nabla\varphi\cdot v^+ =`
    ``target``; ``p`` updated in place and :math:`(\Lambda_n, \beta)` into ``out``.

    A few fixed-point sweeps on d (exact in the plane) start Newton on the whole system
    with the exact Jacobian (:math:`\partial d/\partial v = (I - dd^{\mathsf T})T/|w|`) and
    backtracking on the residual's norm. ``T`` holds the contact's slip rows (``slips``
    of them), ``w0`` their values at v = 0. False where an iteration fails.
    """
    size_all = n + 1 + mh
    K = np.zeros((size_all, size_all))
    piv = np.zeros(size_all, dtype=np.int64)
    xs = np.zeros(size_all)
    Dm = np.zeros((1 + mh, n))
    Cm = np.zeros((1 + mh, n))
    targets = np.zeros(1 + mh)
    lam = np.zeros(1 + mh)
    v = np.zeros(n)
    d = np.zeros(2)
    slip = np.zeros(2)
    push = np.zeros(n)
    residual = np.zeros(size_all)
    trial_r = np.zeros(size_all)
    v_trial = np.zeros(n)
    nu = np.zeros(max(mh, 1))
    nu_trial = np.zeros(max(mh, 1))
    Lq = work[0, :n]
    Lv = work[1, :n]

    def slip_of(v, slip):
        size = 0.0
        for e in range(slips):
            value = w0[e]
            for a in range(n):
                value += T[e, a] * v[a]
            slip[e] = value
            size += value * value
        return np.sqrt(size)

    size = slip_of(v_minus, slip)
    if not size > 0.0:
        return False
    for e in range(slips):
        d[e] = slip[e] / size
    for a in range(n):
        v[a] = v_minus[a]
    for i in range(mh):
        targets[1 + i] = -gt[i]
        for a in range(n):
            Dm[1 + i, a] = Gq[i * n + a]
            Cm[1 + i, a] = Gq[i * n + a]
    targets[0] = target
    for a in range(n):
        Cm[0, a] = g[a]
    for _ in range(DIRECTION_SWEEPS):
        for a in range(n):
            value = g[a]
            for e in range(slips):
                value -= mu * T[e, a] * d[e]
            Dm[0, a] = value
        for a in range(n):
            v[a] = v_minus[a]
        if not saddle_velocity(fn, t, q, p, prm, n, v, Dm, Cm, targets, 1 + mh, lam, work,
                               Lqq, Lqv, Lvv, Fv, K, piv, xs):  # fmt: skip
            return False
        size = slip_of(v, slip)
        if size == 0.0 or slips == 1:
            out[0] = lam[0]
            for e in range(slips):
                out[1 + e] = -mu * lam[0] * d[e]
            for a in range(n):
                for i in range(1 + mh):
                    p[a] += Dm[i, a] * lam[i]
            return True
        for e in range(slips):
            d[e] = slip[e] / size
    normal = lam[0]
    for i in range(mh):
        nu[i] = lam[1 + i]

    def equations(v, normal, nu, r, jacobian):
        size = slip_of(v, slip)
        for e in range(slips):
            d[e] = slip[e] / size
        for a in range(n):
            value = g[a]
            for e in range(slips):
                value -= mu * T[e, a] * d[e]
            push[a] = value
        point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        for a in range(n):
            value = Lv[a] - p[a] - normal * push[a]
            for i in range(mh):
                value -= Gq[i * n + a] * nu[i]
            r[a] = value
        value = -target
        for a in range(n):
            value += g[a] * v[a]
        r[n] = value
        for i in range(mh):
            value = gt[i]
            for a in range(n):
                value += Gq[i * n + a] * v[a]
            r[n + 1 + i] = value
        if jacobian:
            for a in range(size_all):
                for cc in range(size_all):
                    K[a, cc] = 0.0
            for a in range(n):
                for cc in range(n):
                    # mu normal T^T (I - d d^T) T / |w|
                    bend = 0.0
                    for e in range(slips):
                        for f in range(slips):
                            proj = (1.0 if e == f else 0.0) - d[e] * d[f]
                            bend += T[e, a] * proj * T[f, cc]
                    K[a, cc] = Lvv[a * n + cc] + mu * normal * bend / size
                K[a, n] = -push[a]
                K[n, a] = g[a]
                for i in range(mh):
                    K[a, n + 1 + i] = -Gq[i * n + a]
                    K[n + 1 + i, a] = Gq[i * n + a]
        norm = 0.0
        for a in range(size_all):
            norm += r[a] * r[a]
        return np.sqrt(norm)

    norm = equations(v, normal, nu, residual, True)
    for _ in range(SLIDING_ITERATIONS):
        for a in range(size_all):
            xs[a] = -residual[a]
        if not lu_factor_inplace(K, piv):
            return False
        lu_solve_inplace(K, piv, xs)
        step = 0.0
        scale = max(1.0, abs(normal))
        for a in range(size_all):
            step = max(step, abs(xs[a]))
        for a in range(n):
            scale = max(scale, abs(v[a]))
        if not step < np.inf:
            return False
        if step <= 1e-15 * scale:
            break
        alpha = 1.0
        while True:
            for a in range(n):
                v_trial[a] = v[a] + alpha * xs[a]
            normal_trial = normal + alpha * xs[n]
            for i in range(mh):
                nu_trial[i] = nu[i] + alpha * xs[n + 1 + i]
            new = equations(v_trial, normal_trial, nu_trial, trial_r, False)
            if new < norm or alpha < 1e-6:
                break
            alpha /= 2
        for a in range(n):
            v[a] = v_trial[a]
        normal = normal_trial
        for i in range(mh):
            nu[i] = nu_trial[i]
        norm = equations(v, normal, nu, residual, True)
    size = slip_of(v, slip)
    out[0] = normal
    for e in range(slips):
        d[e] = slip[e] / size
        out[1 + e] = -mu * normal * d[e]
    for a in range(n):
        value = normal * g[a]
        for e in range(slips):
            value += T[e, a] * out[1 + e]
        for i in range(mh):
            value += Gq[i * n + a] * nu[i]
        p[a] += value
    return True
