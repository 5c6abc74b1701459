r"""The compiled Newton iteration of a boundary-value problem: a whole path at once.

The equations and their linear algebra are those of :mod:`galerkin_vi.action`
(element residuals :math:`G_k` and Jacobians :math:`H_k` from the point
functions at every quadrature point, the interior points condensed element by
element, one banded LU with partial pivoting for the nodes); here they run in
one compiled call for every Newton iteration and line-search trial, with the
system's point functions called by address (:mod:`.point`), so the driver is
compiled once per machine for every system. Dense point-function storage,
no constraints: the NumPy path of :mod:`galerkin_vi.action` serves the rest.

Layout: ``X`` (N, s + 1, n) holds every element's control points, the shared
nodes twice (``X[k, s] = X[k + 1, 0]``, kept equal); the nodes 1 .. N - 1 are
the unknowns of the band system, node-major (``(j - 1) n + a``), with
half-bandwidths ``kl = ku = 2 n - 1``.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import kernel
from .common import interpolate
from .general import assemble_gradient
from .linalg import (
    add_dense_block,
    band_lu_backward,
    band_lu_factor,
    band_lu_forward,
    lu_factor_inplace,
    lu_solve_inplace,
)
from .on_demand import driver
from .point import lagrangian, point_hessian
from .traits import HAS_FV, HAS_LQV

__all__ = ["stationary_path"]

STATUS_CONVERGED = 0
STATUS_MAX_ITERATIONS = 1
STATUS_SINGULAR = 2
STATUS_NONFINITE = 3
STATUS_NO_DESCENT = 4


@kernel
def element_residual(fn, t0, h, Xk, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G):
    r""":math:`G^\nu_a` of one element (shape (s + 1, n)) at its control points ``Xk``."""
    s1, n = Xk.shape
    for nu in range(s1):
        for a in range(n):
            C[nu, a] = Xk[nu, a] - Xk[0, a]
    assemble_gradient(fn, t0, h, Xk[0], C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)


@kernel
def point_work(n):
    """Work arrays of the point functions: Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv (dense storage)."""
    nn = n * n
    return (np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(nn), np.zeros(nn),
            np.zeros(nn), np.zeros(nn))  # fmt: skip


@kernel
def element_jacobian(
    fn, t0, h, Xk, prm, b, c, Phi, D, C, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, H, has_lqv, has_fv
):  # fmt: skip
    r""":math:`G` and the full element Jacobian ``H[(nu, a), (mu, c)]`` ((s + 1) n square)."""
    s1, n = Xk.shape
    inv_h = 1.0 / h
    for nu in range(s1):
        for a in range(n):
            C[nu, a] = Xk[nu, a] - Xk[0, a]
            G[nu, a] = 0.0
    H[:, :] = 0.0
    for i in range(b.shape[0]):
        interpolate(i, inv_h, Xk[0], C, Phi, D, Q, V)
        point_hessian(fn, t0 + c[i] * h, Q, V, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        for nu in range(s1):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                G[nu, a] += wq * Lq[a] + wv * Lv[a]
            for mu in range(s1):
                add_dense_block(
                    H, nu * n, mu * n, n,
                    b[i] * D[i, nu] * D[i, mu] * inv_h, Lvv,
                    b[i] * h * Phi[i, nu] * Phi[i, mu], Lqq,
                    b[i] * Phi[i, nu] * D[i, mu], b[i] * D[i, nu] * Phi[i, mu], Lqv, Fv,
                    has_lqv, has_fv,
                )  # fmt: skip


@kernel
def condense_element(H, G, n, Hii, piv, Y, K, r):
    r"""Eliminate the interior points: ``K`` (2n, 2n), ``r`` (2n), ``Y`` = Hii^{-1}[Hie | Gi].

    Returns False if the interior block is singular.
    """
    s1 = G.shape[0]
    s = s1 - 1
    m = (s - 1) * n
    w2 = 2 * n
    # end rows and columns: point 0 at 0..n-1, point s at n..2n-1 of K
    for alpha in range(2):
        nu = 0 if alpha == 0 else s
        for a in range(n):
            r[alpha * n + a] = G[nu, a]
            for beta in range(2):
                mu = 0 if beta == 0 else s
                for cc in range(n):
                    K[alpha * n + a, beta * n + cc] = H[nu * n + a, mu * n + cc]
    if m == 0:
        return True
    for i in range(m):
        for j in range(m):
            Hii[i, j] = H[n + i, n + j]
        for beta in range(2):
            mu = 0 if beta == 0 else s
            for cc in range(n):
                Y[i, beta * n + cc] = H[n + i, mu * n + cc]
        Y[i, w2] = G[1 + i // n, i % n]
    if not lu_factor_inplace(Hii, piv):
        return False
    column = np.empty(m)
    for j in range(w2 + 1):
        for i in range(m):
            column[i] = Y[i, j]
        lu_solve_inplace(Hii, piv, column)
        for i in range(m):
            Y[i, j] = column[i]
    for alpha in range(2):
        nu = 0 if alpha == 0 else s
        for a in range(n):
            row = nu * n + a
            acc = 0.0
            for i in range(m):
                acc += H[row, n + i] * Y[i, w2]
            r[alpha * n + a] -= acc
            for j in range(w2):
                acc = 0.0
                for i in range(m):
                    acc += H[row, n + i] * Y[i, j]
                K[alpha * n + a, j] -= acc
    return True


@kernel
def path_merit(fn, t_nodes, h, X, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G, node_sum):
    """(sum of squares, largest entry) of the free points' residuals at the path ``X``."""
    N, s1, n = X.shape
    s = s1 - 1
    node_sum[:, :] = 0.0
    total = 0.0
    largest = 0.0
    for k in range(N):
        element_residual(fn, t_nodes[k], h, X[k], prm, b, c, Phi, D, C, Q, V, Lq, Lv, G)
        for a in range(n):
            node_sum[k, a] += G[0, a]
            node_sum[k + 1, a] += G[s, a]
            for nu in range(1, s):
                total += G[nu, a] * G[nu, a]
                largest = max(largest, abs(G[nu, a]))
    for j in range(1, N):
        for a in range(n):
            total += node_sum[j, a] * node_sum[j, a]
            largest = max(largest, abs(node_sum[j, a]))
    return total, largest


@kernel
def move_path(X, X0, node_step, inner_step, alpha):
    """X = X0 + alpha (node and interior steps), the shared nodes kept equal."""
    N, s1, n = X.shape
    s = s1 - 1
    for k in range(N):
        for a in range(n):
            X[k, 0, a] = X0[k, 0, a] + alpha * node_step[k, a]
            X[k, s, a] = X0[k, s, a] + alpha * node_step[k + 1, a]
            for nu in range(1, s):
                X[k, nu, a] = X0[k, nu, a] + alpha * inner_step[k, nu - 1, a]


@kernel
def path_momenta_and_action(fn, t_nodes, h, X, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G, P):
    r"""Momenta :math:`p_k = -G_k^0`, :math:`p_N = G_{N-1}^s` into ``P``; returns the action."""
    N, s1, n = X.shape
    inv_h = 1.0 / h
    action = 0.0
    for k in range(N):
        element_residual(fn, t_nodes[k], h, X[k], prm, b, c, Phi, D, C, Q, V, Lq, Lv, G)
        for a in range(n):
            P[k, a] = -G[0, a]
            if k == N - 1:
                P[N, a] = G[s1 - 1, a]
        for i in range(b.shape[0]):
            interpolate(i, inv_h, X[k, 0], C, Phi, D, Q, V)
            action += b[i] * h * lagrangian(fn, t_nodes[k] + c[i] * h, Q, V, prm)
    return action


@kernel
def node_velocities(fn, t_nodes, h, X, P, slope_start, slope_end, prm, W):
    r"""Velocities at the nodes: :math:`L_v(t_k, q_k, v_k) = p_k`, into ``W`` (N + 1, n).

    Newton from the element polynomial's slope at the node (``slope_start`` and
    ``slope_end``: :math:`\ell_\nu'(0)`, :math:`\ell_\nu'(1)`), which is
    :math:`O(h^s)` from the answer: a few iterations reach round-off.
    """
    N, s1, n = X.shape
    _, _, Lq, Lv, Lqq, Lqv, Lvv, Fv = point_work(n)
    A = np.zeros((n, n))
    piv = np.zeros(n, dtype=np.int64)
    r = np.zeros(n)
    q = np.zeros(n)
    v = np.zeros(n)
    for k in range(N + 1):
        element = k if k < N else N - 1
        slope = slope_start if k < N else slope_end
        for a in range(n):
            q[a] = X[element, 0, a] if k < N else X[N - 1, s1 - 1, a]
            acc = 0.0
            for nu in range(s1):
                acc += slope[nu] * X[element, nu, a]
            v[a] = acc / h
        for _ in range(8):
            point_hessian(fn, t_nodes[k], q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
            size = 0.0
            for a in range(n):
                r[a] = P[k, a] - Lv[a]
                for cc in range(n):
                    A[a, cc] = Lvv[a * n + cc]
            if not lu_factor_inplace(A, piv):
                break
            lu_solve_inplace(A, piv, r)
            for a in range(n):
                v[a] += r[a]
                size = max(size, abs(r[a]) / (1.0 + abs(v[a])))
            if size < 1e-15:
                break
        for a in range(n):
            W[k, a] = v[a]


@driver
def stationary_path(
    fn, traits, t_nodes, h, b, c, Phi, D, X, prm, tol, maxiter, info, P, slope_start, slope_end, W
):  # fmt: skip
    """Newton on the stationarity of the discrete action, the end nodes fixed; ``X`` in/out.

    Returns a status (0 converged, 1 maxiter, 2 singular, 3 non-finite, 4 no
    descent); ``info`` receives (iterations, largest residual at the last
    Jacobian, largest residual at the returned path, the discrete action
    there), ``P`` (N + 1, n) the momenta of the discrete Legendre transforms
    and ``W`` (N + 1, n) the velocities they belong to (:func:`node_velocities`).
    """
    N, s1, n = X.shape
    s = s1 - 1
    m = (s - 1) * n
    w2 = 2 * n
    has_lqv = traits[HAS_LQV] != 0
    has_fv = traits[HAS_FV] != 0
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv = point_work(n)
    C = np.zeros((s1, n))
    G = np.zeros((s1, n))
    H = np.zeros((s1 * n, s1 * n))
    Hii = np.zeros((max(m, 1), max(m, 1)))
    piv = np.zeros(max(m, 1), dtype=np.int64)
    Y = np.zeros((N, max(m, 1), w2 + 1))
    K = np.zeros((w2, w2))
    r = np.zeros(w2)
    kl = w2 - 1
    size = (N - 1) * n
    ab = np.zeros((3 * kl + 1, max(size, 1)))
    band_piv = np.zeros(max(size, 1), dtype=np.int64)
    rhs = np.zeros(max(size, 1))
    node_step = np.zeros((N + 1, n))
    inner_step = np.zeros((N, max(s - 1, 1), n))
    node_sum = np.zeros((N + 1, n))
    X0 = X.copy()
    status = STATUS_MAX_ITERATIONS
    iterations = 0
    residual = np.inf
    for it in range(maxiter):
        iterations = it + 1
        # ---- element Jacobians, condensed, assembled into the band
        ab[:, :] = 0.0
        rhs[:] = 0.0
        node_sum[:, :] = 0.0
        merit = 0.0
        largest = 0.0
        for k in range(N):
            element_jacobian(fn, t_nodes[k], h, X[k], prm, b, c, Phi, D, C, Q, V, Lq, Lv,
                             Lqq, Lqv, Lvv, Fv, G, H, has_lqv, has_fv)  # fmt: skip
            for a in range(n):
                node_sum[k, a] += G[0, a]
                node_sum[k + 1, a] += G[s, a]
                for nu in range(1, s):
                    merit += G[nu, a] * G[nu, a]
                    largest = max(largest, abs(G[nu, a]))
            if not condense_element(H, G, n, Hii, piv, Y[k], K, r):
                status = STATUS_SINGULAR
                break
            for alpha in range(2):
                node_i = k + alpha
                if node_i == 0 or node_i == N:
                    continue
                for a in range(n):
                    row = (node_i - 1) * n + a
                    rhs[row] -= r[alpha * n + a]
                    for beta in range(2):
                        node_j = k + beta
                        if node_j == 0 or node_j == N:
                            continue
                        for cc in range(n):
                            col = (node_j - 1) * n + cc
                            ab[2 * kl + row - col, col] += K[alpha * n + a, beta * n + cc]
        if status == STATUS_SINGULAR:
            break
        for j in range(1, N):
            for a in range(n):
                merit += node_sum[j, a] * node_sum[j, a]
                largest = max(largest, abs(node_sum[j, a]))
        residual = largest
        if not np.isfinite(merit):
            status = STATUS_NONFINITE
            break
        # ---- the node chain: banded LU with partial pivoting
        if size > 0:
            if not band_lu_factor(ab, band_piv, kl, kl):
                status = STATUS_SINGULAR
                break
            band_lu_forward(ab, band_piv, kl, kl, rhs)
            band_lu_backward(ab, kl, kl, rhs)
        node_step[:, :] = 0.0
        for j in range(1, N):
            for a in range(n):
                node_step[j, a] = rhs[(j - 1) * n + a]
        # ---- interior steps: -(Y[:, 2n] + Y[:, :2n] (node_k, node_k+1))
        step_size = 0.0
        for k in range(N):
            for i in range(m):
                acc = Y[k, i, w2]
                for a in range(n):
                    acc += Y[k, i, a] * node_step[k, a] + Y[k, i, n + a] * node_step[k + 1, a]
                inner_step[k, i // n, i % n] = -acc
                step_size = max(step_size, abs(acc))
        scale = 1.0
        for k in range(N + 1):
            for a in range(n):
                step_size = max(step_size, abs(node_step[k, a]))
                node = X[k, 0, a] if k < N else X[N - 1, s, a]
                scale = max(scale, 1.0 + abs(node))
        if not np.isfinite(step_size):
            status = STATUS_NONFINITE
            break
        X0[:, :, :] = X
        alpha = 1.0
        move_path(X, X0, node_step, inner_step, alpha)
        if step_size > 1e-6 * scale:  # far out: backtrack on the sum of squares
            while True:
                trial, _ = path_merit(fn, t_nodes, h, X, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G,
                                      node_sum)  # fmt: skip
                if trial <= (1.0 - 2e-4 * alpha) * merit:
                    break
                alpha *= 0.5
                if alpha < 1e-4:
                    break
                move_path(X, X0, node_step, inner_step, alpha)
            if alpha < 1e-4:
                X[:, :, :] = X0
                status = STATUS_NO_DESCENT
                break
        if step_size <= tol * scale:
            status = STATUS_CONVERGED
            break
    info[0] = iterations
    info[1] = residual
    _, info[2] = path_merit(fn, t_nodes, h, X, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G, node_sum)
    info[3] = path_momenta_and_action(fn, t_nodes, h, X, prm, b, c, Phi, D, C, Q, V, Lq, Lv, G, P)
    node_velocities(fn, t_nodes, h, X, P, slope_start, slope_end, prm, W)
    return status
