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
