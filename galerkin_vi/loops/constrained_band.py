r"""The constrained step's linear algebra in band storage, for chains of bodies.

The constrained stage equations (:mod:`.constrained`) have :math:`s(n + m)`
unknowns. For a chain of bodies joined end to end, each coordinate couples only
with the coordinates of its own body and each joint's multipliers only with the
coordinates of the two bodies it joins: ordered by position along the chain (a
coordinate's :math:`s` stage increments, then the :math:`s` impulses of each
constraint after the last coordinate it touches), the stage Jacobian is banded,
with a half-bandwidth :math:`k_b` independent of the chain's length, and its LU
costs :math:`O(s(n + m) k_b^2)` instead of :math:`O(s^3 (n + m)^3)`. The same
order, with one stage, makes the hidden-constraint projection's saddle-point
matrix banded.

The order is found in :mod:`galerkin_vi.run.constrained_band` from the
sparsity of the Hessians and of the constraint Jacobian, and arrives here as
``band = (place, kb, kpairs, gpairs, hpairs, place_b, kb_b, vpairs)``:

- ``place[i]``: the banded position of dense unknown ``i`` (dense order
  ``[C^1..C^s, Lambda^0..Lambda^{s-1}]``, node-major);
- ``kpairs``: the (row, column) of the dense stage block ``K`` that can be nonzero;
- ``gpairs``: the (j, a) of :math:`\partial g_j/\partial q_a` that can be nonzero;
- ``hpairs``: the (a, b) of :math:`\sum_j\lambda_j\nabla^2 g_j` that can be nonzero;
- ``place_b``, ``kb_b``, ``vpairs``: the same for the projection, unknowns
  ``[v, mu]``, and the (a, b) of :math:`L_{vv}`.

The point functions, the stopping rule and the frozen-factor reuse are those of
:func:`.constrained.solve_constrained_stages`; only the storage and the loops
over couplings (the nonzero lists, not every pair) differ.
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
)
from .general import assemble_gradient, assemble_newton
from .linalg import CONTINUE, CONVERGED, band_lu_factor, band_lu_solve, newton_status
from .point import (
    point_constraint,
    point_constraint_hessian,
    point_constraint_jacobian,
    point_constraint_rate,
    point_hessian,
)
from .traits import HAS_FV, HAS_LQV

__all__ = ["STALE_RATIO", "make_band_work", "project_hidden_band", "solve_constrained_band"]

#: the contraction of an increment by an earlier step's factors above which the
#: band iteration factorises afresh
STALE_RATIO = 0.125


@kernel
def make_band_work(s, n, m, band):
    """Band storage of the stage and projection matrices (allocated once per run)."""
    place, kb, kpairs, gpairs, hpairs, place_b, kb_b, vpairs = band
    size = s * (n + m)
    A = np.zeros((3 * kb + 1, size))
    X = np.zeros(size)
    pivot = np.zeros(size, dtype=np.int64)
    B = np.zeros((3 * kb_b + 1, n + m))
    Y = np.zeros(n + m)
    pivot_b = np.zeros(n + m, dtype=np.int64)
    return (A, X, pivot, B, Y, pivot_b)


@kernel
def solve_constrained_band(
    fn, t0, h, qk, C, lam, pk, prm, b, c, Phi, D, d, tol, maxiter, work, cw, bw, traits, band,
    reuse,
):  # fmt: skip
    """:func:`.constrained.solve_constrained_stages` with the stage Jacobian in band
    storage (module notes); the same arguments, the band work ``bw`` and ``band``.

    With ``reuse``, the iteration starts with the factors left in ``bw`` by an
    earlier step (a simplified Newton iteration: the stage Jacobian moves by
    :math:`O(h)` from one step to the next); it factorises afresh once they
    contract slowly (an increment above :data:`STALE_RATIO` times the one before)
    or fail.
    """
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    _, _, _, g, Gq, gt, Hg, _, _, _, qn = cw
    A, X, pivot, B, Y, pivot_b = bw
    place, kb, kpairs, gpairs, hpairs, place_b, kb_b, vpairs = band
    s1, n = C.shape
    s = s1 - 1
    m = lam.shape[1]
    sn = s * n
    diag = 2 * kb
    previous = np.inf
    residual = np.inf
    frozen = reuse
    stale = reuse  # the factors are an earlier step's
    base = 0.0
    for a in range(n):
        base = max(base, abs(qk[a]))
    for it in range(1, maxiter + 1):
        if frozen:
            assemble_gradient(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        else:
            assemble_newton(
                fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K,
                traits, None, (traits[HAS_LQV] != 0, traits[HAS_FV] != 0),
            )  # fmt: skip
            A[:, :] = 0.0
            for k in range(kpairs.shape[0]):
                i = kpairs[k, 0]
                j = kpairs[k, 1]
                A[diag + place[i] - place[j], place[j]] = K[i, j]
        residual = 0.0
        for nu in range(s):
            tn = t0 + d[nu] * h
            for a in range(n):
                qn[a] = qk[a] + C[nu, a]
                val = G[nu, a] + (pk[a] if nu == 0 else 0.0)
                X[place[nu * n + a]] = val
            point_constraint_jacobian(fn, tn, qn, prm, Gq)
            for k in range(gpairs.shape[0]):
                j = gpairs[k, 0]
                a = gpairs[k, 1]
                X[place[nu * n + a]] -= Gq[j * n + a] * lam[nu, j]
                if not frozen:
                    row = place[nu * n + a]
                    col = place[sn + nu * m + j]
                    A[diag + row - col, col] = -Gq[j * n + a]
            for a in range(n):
                i = place[nu * n + a]
                val = X[i]
                X[i] = -val
                if not abs(val) <= residual:
                    residual = abs(val)
            if nu >= 1 and not frozen:
                point_constraint_hessian(fn, tn, qn, lam[nu], prm, Hg)
                for k in range(hpairs.shape[0]):
                    a = hpairs[k, 0]
                    cc = hpairs[k, 1]
                    row = place[nu * n + a]
                    col = place[(nu - 1) * n + cc]
                    A[diag + row - col, col] -= Hg[a * n + cc]
        for nu in range(1, s1):
            tn = t0 + d[nu] * h
            for a in range(n):
                qn[a] = qk[a] + C[nu, a]
            point_constraint(fn, tn, qn, prm, g)
            for j in range(m):
                X[place[sn + (nu - 1) * m + j]] = -g[j]
                if not abs(g[j]) <= residual:
                    residual = abs(g[j])
            if not frozen:
                point_constraint_jacobian(fn, tn, qn, prm, Gq)
                for k in range(gpairs.shape[0]):
                    j = gpairs[k, 0]
                    a = gpairs[k, 1]
                    row = place[sn + (nu - 1) * m + j]
                    col = place[(nu - 1) * n + a]
                    A[diag + row - col, col] = Gq[j * n + a]
        if not residual < 1e300:
            return STATUS_NONFINITE, it, np.inf, residual
        if not frozen and not band_lu_factor(A, pivot, kb, kb):
            return STATUS_SINGULAR, it, np.inf, residual
        band_lu_solve(A, pivot, kb, kb, X)
        increment = 0.0
        size = 0.0
        for nu in range(1, s1):
            for a in range(n):
                delta = X[place[(nu - 1) * n + a]]
                C[nu, a] += delta
                increment = max(increment, abs(delta))
                size = max(size, abs(C[nu, a]))
        for nu in range(s):
            for j in range(m):
                lam[nu, j] += X[place[sn + nu * m + j]]
                if not abs(lam[nu, j]) < 1e300:
                    return STATUS_NONFINITE, it, np.inf, residual
        status = newton_status(increment, previous, 1.0 + max(size, base), tol, it, maxiter)
        if status == CONVERGED:
            return STATUS_OK, it, increment, residual
        if stale and (status != CONTINUE or increment > STALE_RATIO * previous):
            # an earlier step's factors contract too slowly here: factorise afresh
            stale = False
            frozen = False
            previous = np.inf
            continue
        if status != CONTINUE:
            return STATUS_NEWTON_FAILED, it, increment, residual
        if increment <= FREEZE * (1.0 + size):
            frozen = True
        previous = increment
    return STATUS_NEWTON_FAILED, maxiter, previous, residual


@kernel
def project_hidden_band(fn, t, q, p_tilde, v, mu, prm, tol, maxiter, work, cw, bw, band, p_out):
    """:func:`.constrained.project_hidden` with the saddle-point matrix in band storage."""
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    _, _, _, g, Gq, gt, Hg, _, _, _, qn = cw
    A, X, pivot, B, Y, pivot_b = bw
    place, kb, kpairs, gpairs, hpairs, place_b, kb_b, vpairs = band
    n = q.shape[0]
    m = g.shape[0]
    diag = 2 * kb_b
    point_constraint_jacobian(fn, t, q, prm, Gq)
    point_constraint_rate(fn, t, q, prm, gt)
    mu[:] = 0.0
    previous = np.inf
    for it in range(1, maxiter + 1):
        point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        B[:, :] = 0.0
        for a in range(n):
            Y[place_b[a]] = Lv[a] - p_tilde[a]
        for j in range(m):
            Y[place_b[n + j]] = gt[j]
        for k in range(gpairs.shape[0]):
            j = gpairs[k, 0]
            a = gpairs[k, 1]
            value = Gq[j * n + a]
            ra = place_b[a]
            rj = place_b[n + j]
            Y[ra] += value * mu[j]
            Y[rj] += value * v[a]
            B[diag + ra - rj, rj] = value
            B[diag + rj - ra, ra] = value
        for k in range(vpairs.shape[0]):
            a = vpairs[k, 0]
            cc = vpairs[k, 1]
            ra = place_b[a]
            rc = place_b[cc]
            B[diag + ra - rc, rc] = Lvv[a * n + cc]
        for i in range(n + m):
            Y[i] = -Y[i]
        if not band_lu_factor(B, pivot_b, kb_b, kb_b):
            return False
        band_lu_solve(B, pivot_b, kb_b, kb_b, Y)
        step = 0.0
        size = 0.0
        for a in range(n):
            delta = Y[place_b[a]]
            v[a] += delta
            step = max(step, abs(delta))
            size = max(size, abs(v[a]))
        for j in range(m):
            delta = Y[place_b[n + j]]
            mu[j] += delta
            step = max(step, abs(delta))
            size = max(size, abs(mu[j]))
        status = newton_status(step, previous, 1.0 + size, tol, it, maxiter)
        if status == CONVERGED:
            break
        if status != CONTINUE:
            return False
        previous = step
    for a in range(n):
        p_out[a] = p_tilde[a]
    for k in range(gpairs.shape[0]):
        j = gpairs[k, 0]
        a = gpairs[k, 1]
        p_out[a] -= Gq[j * n + a] * mu[j]
    return True
