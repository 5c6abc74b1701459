r"""The time-stepping contact step, compiled: a primal–dual interior point reduced blockwise.

The step of :mod:`galerkin_vi.contact.time_stepping` (its docstring has the
equations): the Galerkin stage equations with constant contact forces
:math:`y` (normal forces :math:`\lambda_c`, and per frictional contact the cone
:math:`(\mu\lambda_c, \beta_c)`), the slacks' definitions :math:`E(x, y, z) = 0`
(gaps at the step's end, the step's mean slips), and the complementarity of
slacks and duals, :math:`z \circ y = \kappa e`, solved by Mehrotra's
predictor–corrector in Nesterov–Todd scaled variables, with the fraction to the
boundary and backtracking. The iterates are those of the NumPy step; only the
linear algebra differs.

**Blockwise reduction.** The Newton system in :math:`(dx, dy, dz)` is

.. math::

    F_x\,dx + F_y\,dy = r_F, \qquad
    E_x\,dx + E_y\,dy + E_z\,dz = r_E, \qquad
    A_y\,dy + A_z\,dz = r_C,

with :math:`A_y = (P z)\circ(Q\,\cdot)`, :math:`A_z = (Q y)\circ(P\,\cdot)`.
:math:`E_y`, :math:`E_z`, :math:`A_y`, :math:`A_z` couple only the entries of one
contact (its gap and its cone), and the slacks' definitions are unit rows (a gap's
slack, a cone's bound :math:`y_f = \mu\lambda`, its slips), so each contact's
:math:`(dy_c, dz_c) = a_c - M_c\,dx` follows from its gap's complementarity row (a
scalar) and its cone's rows (a system of the cone's size, at most 3;
:func:`factor_blocks`), and the stage unknowns solve :math:`(F_x - \sum_c F_{y,c}
M^y_c)\,dx = r_F - \sum_c F_{y,c} a^y_c`: a system of the size of the stage
equations (8 unknowns for a cube in quaternions at Galerkin(1)) instead of the
full one (72 with eight frictional corners). The corrector reuses every
factorisation; its direction gets one step of iterative refinement (:func:`refine`).

The gaps, slips and their derivatives come from the system's generated point
functions (``point_contact``, ``point_slip``), the stage equations from
``point_hessian`` and the holonomic constraints from the constraint point
functions, all called by address (:mod:`.point`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numpy as np

from ..interior_point import (
    ACCEPTABLE,
    CENTRING,
    COMPLEMENTARITY,
    DEGENERATE,
    FRACTION_TO_BOUNDARY,
    LINE_SEARCH,
    MAX_ITERATIONS,
    POLISHED,
    RESIDUAL,
    TO_BOUNDARY,
)
from ._jit import called, kernel
from .contact_velocity import project_momentum
from .linalg import lu_factor_inplace as lu_factor
from .linalg import lu_solve_inplace as lu_solve
from .on_demand import driver
from .point import (
    point_constraint,
    point_constraint_hessian,
    point_constraint_jacobian,
    point_contact,
    point_hessian,
    point_slip,
)

__all__ = ["contact_step", "contact_equations", "factor_blocks", "solve_blocks"]


# ------------------------------------------------------------------ the equations
@kernel
def add_point_force(F, Fy, Fx, p_end, directions, derivatives, row, multiplier, column,
                    weight, Phi, i, n, s):  # fmt: skip
    r"""Add a force :math:`y_k\,\partial_v` at quadrature point i (weight :math:`h b_i`):
    ``multiplier`` :math:`y_k` times the direction ``directions[row n + a]`` (a gap's
    gradient, a slip's :math:`\partial w/\partial v`) into the stage equations F (the
    step's end's share into ``p_end``), the direction into column ``column`` of
    :math:`F_y`, and :math:`y_k` times its derivative in q
    (``derivatives[(row n + a) n + c]``) into :math:`F_x`."""
    for nu in range(s + 1):
        node = weight * Phi[i, nu]
        for a in range(n):
            force = node * directions[row * n + a]
            if nu < s:
                F[nu * n + a] += multiplier * force
                Fy[nu * n + a, column] += force
            else:
                p_end[a] += multiplier * force
    for nu in range(s):
        for mu_ in range(1, s + 1):
            bend = weight * Phi[i, nu] * Phi[i, mu_] * multiplier
            if bend != 0.0:
                for a in range(n):
                    for cc in range(n):
                        Fx[nu * n + a, (mu_ - 1) * n + cc] += (
                            bend * derivatives[(row * n + a) * n + cc]
                        )


@called
def contact_equations(
    fn, t0, h, qk, pk, x, y, z, b, c, Phi, D, d, prm, n, s, mh, normal, cone, cone_len,
    slip_row, mu, fixed, F, Fx, Fy, E, Ex, p_end, work, Lqq, Lqv, Lvv, Fv, cH, Wvq, Hg,
):  # fmt: skip
    r"""The residuals F (stage equations with the contact forces, then the constraints),
    E (the slacks' definitions) and their Jacobians :math:`F_x`, :math:`F_y` (dense),
    :math:`E_x`; :math:`p_{k+1}` without the constraint's projection.

    ``work`` holds the vectors of one point (rows: Q, V, L_q, L_v, the gaps, their
    flat gradients, the slips' w, W_q, W_v; 10-12 the constraints' g, G_q and
    impulses), filled here.
    """
    r = b.shape[0]
    nc = normal.shape[0]
    F[:] = 0.0
    Fx[:, :] = 0.0
    Fy[:, :] = 0.0
    Ex[:, :] = 0.0
    p_end[:] = 0.0
    Q = work[0, :n]
    V = work[1, :n]
    Lq = work[2, :n]
    Lv = work[3, :n]
    cg = work[4, :nc]
    cG = work[5, : nc * n]
    n_slip = Wvq.shape[0] // (n * n)
    w = work[6, :n_slip]
    Wq = work[7, : n_slip * n]
    Wv = work[8, : n_slip * n]
    for j in range(nc):
        first = cone[j]
        if first >= 0:
            for e in range(1, cone_len[j]):
                E[first + e] = z[first + e]
    for i in range(r):
        ti = t0 + c[i] * h
        for a in range(n):
            qa = qk[a]
            va = 0.0
            for mu_ in range(1, s + 1):
                qa += Phi[i, mu_] * x[(mu_ - 1) * n + a]
                va += D[i, mu_] * x[(mu_ - 1) * n + a]
            Q[a] = qa
            V[a] = va / h
        point_hessian(fn, ti, Q, V, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
        point_contact(fn, ti, Q, V, prm, cg, cG, cH)
        if n_slip > 0:
            point_slip(fn, ti, Q, V, prm, w, Wq, Wv, Wvq)
        bi = b[i]
        # the discrete Lagrangian's gradient and Hessian (numpy reference: discrete_hessian)
        for nu in range(s + 1):
            wq = h * bi * Phi[i, nu]
            wv = bi * D[i, nu]
            for a in range(n):
                value = wq * Lq[a] + wv * Lv[a]
                if nu < s:
                    F[nu * n + a] += value
                else:
                    p_end[a] += value
        for nu in range(s):
            for mu_ in range(1, s + 1):
                hpp = h * bi * Phi[i, nu] * Phi[i, mu_]
                hpd = bi * Phi[i, nu] * D[i, mu_]
                hdp = bi * D[i, nu] * Phi[i, mu_]
                hdd = bi * D[i, nu] * D[i, mu_] / h
                col = (mu_ - 1) * n
                for a in range(n):
                    row = nu * n + a
                    for cc in range(n):
                        Fx[row, col + cc] += (
                            hpp * Lqq[a * n + cc]
                            + hpd * (Lqv[a * n + cc] + Fv[a * n + cc])
                            + hdp * Lqv[cc * n + a]
                            + hdd * Lvv[a * n + cc]
                        )
        # the contact forces at the point: lambda grad(phi) and beta^T dw/dv
        for j in range(nc):
            k = normal[j]
            add_point_force(F, Fy, Fx, p_end, cG, cH, j, y[k], k, h * bi, Phi, i, n, s)
            first = cone[j]
            if first < 0:
                continue
            for e in range(cone_len[j] - 1):
                row = slip_row[j] + e
                yk = first + 1 + e
                add_point_force(F, Fy, Fx, p_end, Wv, Wvq, row, y[yk], yk, h * bi, Phi, i, n, s)
                # the mean slip over the step and its derivatives in the control points
                E[yk] -= bi * w[row]
                for mu_ in range(1, s + 1):
                    dq = bi * Phi[i, mu_]
                    dv = bi * D[i, mu_] / h
                    for a in range(n):
                        Ex[yk, (mu_ - 1) * n + a] -= dq * Wq[row * n + a] + dv * Wv[row * n + a]
    for k in range(n):
        F[k] += pk[k]
    # the gaps at the step's end, q_{k+1} = q_k + C^s (at v = 0: the gaps have no v)
    t_end = t0 + h
    for a in range(n):
        Q[a] = qk[a] + x[(s - 1) * n + a]
        V[a] = 0.0
    point_contact(fn, t_end, Q, V, prm, cg, cG, cH)
    for j in range(nc):
        k = normal[j]
        E[k] = z[k] - cg[j]
        for a in range(n):
            Ex[k, (s - 1) * n + a] = -cG[j * n + a]
        first = cone[j]
        if first >= 0:
            E[first] = y[first] - mu[j] * y[k]
    if mh > 0:
        constraint_rows(fn, t0, h, qk, x, d, prm, n, s, mh, F, Fx, work, Hg)
    for k in range(E.shape[0]):
        if fixed[k]:
            E[k] = 0.0


@called
def constraint_rows(fn, t0, h, qk, x, d, prm, n, s, mh, F, Fx, work, Hg):
    r"""The holonomic constraints' impulses :math:`-\mathcal G(q^\nu)^{\mathsf T}\Lambda^\nu`
    (:math:`\nu < s`) in the stage equations and the constraints :math:`g(q^\nu) = 0`
    (:math:`\nu \ge 1`) as further rows (as :mod:`galerkin_vi.loops.constrained`)."""
    sn = s * n
    Qn = work[0, :n]
    g = work[10, :mh]
    Gq = work[11, : mh * n]
    lam = work[12, :mh]
    for nu in range(s + 1):
        tn = t0 + d[nu] * h
        for a in range(n):
            Qn[a] = qk[a] + (x[(nu - 1) * n + a] if nu >= 1 else 0.0)
        point_constraint_jacobian(fn, tn, Qn, prm, Gq)
        if nu < s:
            for j in range(mh):
                lam[j] = x[sn + nu * mh + j]
            for a in range(n):
                acc = 0.0
                for j in range(mh):
                    acc += Gq[j * n + a] * lam[j]
                    Fx[nu * n + a, sn + nu * mh + j] = -Gq[j * n + a]
                F[nu * n + a] -= acc
            if nu >= 1:
                point_constraint_hessian(fn, tn, Qn, lam, prm, Hg)
                for a in range(n):
                    for cc in range(n):
                        Fx[nu * n + a, (nu - 1) * n + cc] -= Hg[a * n + cc]
        if nu >= 1:
            point_constraint(fn, tn, Qn, prm, g)
            for j in range(mh):
                F[sn + (nu - 1) * mh + j] = g[j]
                for a in range(n):
                    Fx[sn + (nu - 1) * mh + j, (nu - 1) * n + a] = Gq[j * n + a]


# ------------------------------------------------------------------- the cones
@kernel
def jordan_norm(v, start, length):
    """sqrt((v0 - |v1|)(v0 + |v1|)) of the cone block at ``start``."""
    size = 0.0
    for e in range(1, length):
        size += v[start + e] * v[start + e]
    size = math.sqrt(size)
    value = (v[start] - size) * (v[start] + size)
    return math.sqrt(value) if value > 0.0 else 0.0


@called
def scaling(z, y, normal, cone, cone_len, fixed, P, Q):
    r"""The block-diagonal scalings P of z and Q of y, stored per entry row: on a gap
    :math:`w = \sqrt{y/z}` (P = w, Q = 1/w); on a cone Nesterov–Todd's W and
    :math:`W^{-1}` (:func:`galerkin_vi.contact.time_stepping._nesterov_todd`); the
    identity where they cannot be formed. ``P[k, :]`` holds row k within its block."""
    P[:, :] = 0.0
    Q[:, :] = 0.0
    limit = math.sqrt(DEGENERATE)
    for j in range(normal.shape[0]):
        k = normal[j]
        P[k, 0] = 1.0
        Q[k, 0] = 1.0
        if not fixed[k] and z[k] != 0.0:
            ratio = y[k] / z[k]
            if ratio >= 0.0:
                wk = math.sqrt(ratio)
                if 0.0 < wk < np.inf and 1.0 / wk < np.inf:
                    P[k, 0] = wk
                    Q[k, 0] = 1.0 / wk
        first = cone[j]
        if first < 0:
            continue
        L = cone_len[j]
        for e in range(L):
            P[first + e, e] = 1.0
            Q[first + e, e] = 1.0
        if fixed[first]:
            continue
        zz = jordan_norm(z, first, L)
        yy = jordan_norm(y, first, L)
        if not (zz > limit * z[first] and yy > limit * y[first]):
            continue
        dot = 0.0
        for e in range(L):
            dot += (z[first + e] / zz) * (y[first + e] / yy)
        gamma = math.sqrt((1.0 + dot) / 2.0)
        eta = math.sqrt(yy / zz)
        wv = np.empty(L)
        for e in range(L):
            zb = z[first + e] / zz
            wv[e] = (y[first + e] / yy + (zb if e == 0 else -zb)) / (2.0 * gamma)
        ok = True
        for a in range(L):
            for bb in range(L):
                if a == 0 and bb == 0:
                    entry = wv[0]
                    inverse = wv[0]
                elif a == 0 or bb == 0:
                    entry = wv[a + bb]
                    inverse = -wv[a + bb]
                else:
                    entry = wv[a] * wv[bb] / (1.0 + wv[0]) + (1.0 if a == bb else 0.0)
                    inverse = entry
                P[first + a, bb] = eta * entry
                Q[first + a, bb] = inverse / eta
                if not (abs(eta * entry) < np.inf and abs(inverse / eta) < np.inf):
                    ok = False
        if not ok:
            for a in range(L):
                for bb in range(L):
                    P[first + a, bb] = 1.0 if a == bb else 0.0
                    Q[first + a, bb] = 1.0 if a == bb else 0.0


@called
def scaled(P, v, out, normal, cone, cone_len):
    """out = P v with the block-diagonal P of :func:`scaling`."""
    for j in range(normal.shape[0]):
        k = normal[j]
        out[k] = P[k, 0] * v[k]
        first = cone[j]
        if first >= 0:
            L = cone_len[j]
            for a in range(L):
                acc = 0.0
                for bb in range(L):
                    acc += P[first + a, bb] * v[first + bb]
                out[first + a] = acc


@called
def jordan(u, v, out, normal, cone, cone_len):
    """out = u o v: products on the gaps, the Jordan product on the cones."""
    for j in range(normal.shape[0]):
        k = normal[j]
        out[k] = u[k] * v[k]
        first = cone[j]
        if first >= 0:
            L = cone_len[j]
            acc = 0.0
            for e in range(L):
                acc += u[first + e] * v[first + e]
            out[first] = acc
            for e in range(1, L):
                out[first + e] = u[first] * v[first + e] + v[first] * u[first + e]


# --------------------------------------------------------------- step lengths
@kernel
def cone_step(v, dv, first, L):
    """Largest alpha with v + alpha dv in the cone {a >= |b|} (v inside), or inf."""
    qa = dv[first] * dv[first]
    qb = 2.0 * v[first] * dv[first]
    size = 0.0
    for e in range(1, L):
        qa -= dv[first + e] * dv[first + e]
        qb -= 2.0 * v[first + e] * dv[first + e]
        size += v[first + e] * v[first + e]
    size = math.sqrt(size)
    qc = (v[first] - size) * (v[first] + size)
    best = np.inf
    if dv[first] < 0:
        best = -v[first] / dv[first]
    if abs(qa) > 1e-300:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0:
            sq = math.sqrt(disc)
            r1 = (-qb - sq) / (2.0 * qa)
            r2 = (-qb + sq) / (2.0 * qa)
            if 0.0 < r1 < best:
                best = r1
            if 0.0 < r2 < best:
                best = r2
    elif qb < 0:
        root = -qc / qb
        if 0.0 < root < best:
            best = root
    if not best > 0.0:
        return np.inf
    return best


@called
def to_boundary(v, dv, tau, normal, cone, cone_len):
    """Largest alpha <= 1 keeping v + alpha dv inside every orthant and cone, by tau."""
    alpha = 1.0
    for j in range(normal.shape[0]):
        k = normal[j]
        if dv[k] < 0:
            alpha = min(alpha, -v[k] / dv[k])
        first = cone[j]
        if first >= 0:
            alpha = min(alpha, cone_step(v, dv, first, cone_len[j]))
    return min(1.0, tau * alpha)


@called
def interior(v, floor, margin, normal, cone, cone_len):
    """``v`` moved strictly inside its orthants and cones, in place (a spatial cone's
    scalar at least ``margin`` inside, relative to its vector part's size)."""
    for j in range(normal.shape[0]):
        k = normal[j]
        v[k] = max(v[k], floor)
        first = cone[j]
        if first >= 0:
            L = cone_len[j]
            size = 0.0
            for e in range(1, L):
                size += v[first + e] * v[first + e]
            size = math.sqrt(size)
            inside = margin if L > 2 else 0.0
            v[first] = max(v[first], size * (1.0 + inside) + floor)


@called
def measures(F, E, z, y, normal, cone, cone_len, fixed, scale, tolerance, out, work):
    """(residual, largest |z o y| / tolerance, largest block gap / tolerance, largest
    block gap) into ``out``; ``work`` a vector of the duals' size."""
    residual = 0.0
    for k in range(F.shape[0]):
        residual = max(residual, abs(F[k]) / scale)
    for k in range(E.shape[0]):
        residual = max(residual, abs(E[k]))
    if not residual == residual:
        residual = np.inf
    jordan(z, y, work, normal, cone, cone_len)
    largest_jordan = 0.0
    for k in range(work.shape[0]):
        if not fixed[k]:
            value = abs(work[k])
            if not value == value:
                value = np.inf
            largest_jordan = max(largest_jordan, value)
    largest = 0.0
    for j in range(normal.shape[0]):
        k = normal[j]
        if not fixed[k]:
            largest = max(largest, z[k] * y[k])
        first = cone[j]
        if first >= 0 and not fixed[first]:
            acc = 0.0
            for e in range(cone_len[j]):
                acc += z[first + e] * y[first + e]
            largest = max(largest, acc)
    out[0] = residual
    out[1] = largest_jordan / tolerance
    out[2] = largest / tolerance
    out[3] = largest


# ------------------------------------------------------------ the Newton system
@called
def factor_blocks(
    Fx, Fy, Ex, z, y, P, Q, normal, cone, cone_len, mu, fixed, K, Kpiv, M, R, Rpiv, u, v, nx
):  # fmt: skip
    r"""Eliminate each contact's :math:`(dy_c, dz_c) = a_c - M_c\,dx` and factorise the
    reduced matrix :math:`R = F_x - \sum_c F_{y,c} M^y_c`. False when a block or R is
    singular.

    The slacks' definitions are unit rows: the gap's :math:`dz_k = -E_k - E_{x,k}\,dx`,
    a cone's :math:`dy_f = \mu\,dy_k - E_f` (its bound) and
    :math:`dz_{f+e} = -E_{f+e} - E_{x,f+e}\,dx` (its slips). The gap's
    complementarity row then gives :math:`dy_k = (r_k + v_k P_k E_k)/(u_k Q_k) +
    g_k E_{x,k}\,dx`, :math:`g_k = v_k P_k / (u_k Q_k)`, and the cone's rows
    :math:`A_y\,dy + A_z\,dz = r` (:math:`A_y = \operatorname{arrow}(u) Q`,
    :math:`A_z = \operatorname{arrow}(v) P`) leave the unknowns
    :math:`w = (dy_{f+1}, \dots, dz_f)` in a system :math:`K w = \dots` of the
    cone's size (at most 3), :math:`K = (A_y[:, 1:], A_z[:, 0])`, factorised in
    ``K[j, :, :L]``; ``K[j, :, L]`` keeps :math:`A_y[:, 0]` and ``K[j, :, L+1:]``
    :math:`A_z[:, 1:]` for :func:`solve_blocks`. ``M[j]`` holds the rows of
    :math:`M_c` in the block's order (gap, cone entries; dy, then dz)."""
    scaled(P, z, u, normal, cone, cone_len)
    scaled(Q, y, v, normal, cone, cone_len)
    for a in range(nx):
        for bb in range(nx):
            R[a, bb] = Fx[a, bb]
    for j in range(normal.shape[0]):
        k = normal[j]
        if fixed[k]:
            continue
        first = cone[j]
        Lc = cone_len[j] if first >= 0 else 0
        L = 1 + Lc
        Mj = M[j]
        dk = u[k] * Q[k, 0]
        if not (dk != 0.0 and abs(dk) < np.inf):
            return False
        gk = v[k] * P[k, 0] / dk
        for col in range(nx):
            Mj[0, col] = -gk * Ex[k, col]
            Mj[L, col] = Ex[k, col]
        if first >= 0:
            Kj = K[j]
            for a in range(Lc):
                for bb in range(Lc):
                    # (arrow(u) Q)[a, bb] and (arrow(v) P)[a, bb]
                    if a == 0:
                        ay = 0.0
                        az = 0.0
                        for e in range(Lc):
                            ay += u[first + e] * Q[first + e, bb]
                            az += v[first + e] * P[first + e, bb]
                    else:
                        ay = u[first + a] * Q[first, bb] + u[first] * Q[first + a, bb]
                        az = v[first + a] * P[first, bb] + v[first] * P[first + a, bb]
                    if bb == 0:
                        Kj[a, Lc - 1] = az
                        Kj[a, Lc] = ay
                    else:
                        Kj[a, bb - 1] = ay
                        Kj[a, Lc + bb] = az
            if not lu_factor(Kj[:Lc, :Lc], Kpiv[j, :Lc]):
                return False
            column = Kj[:Lc, 7]
            for col in range(nx):
                Mj[1, col] = mu[j] * Mj[0, col]  # the bound: dy_f = mu dy_k - E_f
                for a in range(Lc):
                    acc = Kj[a, Lc] * Mj[1, col]
                    for e in range(1, Lc):
                        acc += Kj[a, Lc + e] * Ex[first + e, col]
                    column[a] = -acc
                lu_solve(Kj[:Lc, :Lc], Kpiv[j, :Lc], column)
                for e in range(1, Lc):
                    Mj[1 + e, col] = column[e - 1]
                    Mj[L + 1 + e, col] = Ex[first + e, col]
                Mj[L + 1, col] = column[Lc - 1]
        for a in range(L):
            if a == 1:
                continue  # the bound's column of F_y is zero
            ka = k if a == 0 else first + a - 1
            for row in range(nx):
                f = Fy[row, ka]
                if f != 0.0:
                    for col in range(nx):
                        R[row, col] -= f * Mj[a, col]
    return lu_factor(R[:nx, :nx], Rpiv[:nx])


@called
def solve_blocks(
    F, E, rC, Fy, u, v, P, Q, normal, cone, cone_len, mu, fixed, K, Kpiv, M, R, Rpiv, dx, dy,
    dz, nx, rhs,
):  # fmt: skip
    r"""The Newton direction for the right-hand sides :math:`-F`, :math:`-E`, ``rC`` (the
    complementarity rows) with the factors of :func:`factor_blocks`: each block's
    :math:`a_c` (its gap's and cone's rows solved at dx = 0), then dx from R, then
    :math:`(dy_c, dz_c) = a_c - M_c\,dx`; False if not finite."""
    for a in range(nx):
        dx[a] = -F[a]
    for j in range(normal.shape[0]):
        k = normal[j]
        if fixed[k]:
            continue
        first = cone[j]
        Lc = cone_len[j] if first >= 0 else 0
        L = 1 + Lc
        aj = rhs[j]
        aj[0] = (rC[k] + v[k] * P[k, 0] * E[k]) / (u[k] * Q[k, 0])
        aj[L] = -E[k]
        if first >= 0:
            Kj = K[j]
            aj[1] = mu[j] * aj[0] - E[first]
            for e in range(1, Lc):
                aj[L + 1 + e] = -E[first + e]
            column = Kj[:Lc, 7]
            for a in range(Lc):
                acc = rC[first + a] - Kj[a, Lc] * aj[1]
                for e in range(1, Lc):
                    acc -= Kj[a, Lc + e] * aj[L + 1 + e]
                column[a] = acc
            lu_solve(Kj[:Lc, :Lc], Kpiv[j, :Lc], column)
            for e in range(1, Lc):
                aj[1 + e] = column[e - 1]
            aj[L + 1] = column[Lc - 1]
        for a in range(L):
            if a == 1:
                continue
            ka = k if a == 0 else first + a - 1
            for row in range(nx):
                dx[row] -= Fy[row, ka] * aj[a]
    lu_solve(R[:nx, :nx], Rpiv[:nx], dx)
    finite = True
    for a in range(nx):
        if not abs(dx[a]) < np.inf:
            finite = False
    dy[:] = 0.0
    dz[:] = 0.0
    for j in range(normal.shape[0]):
        k = normal[j]
        if fixed[k]:
            continue
        first = cone[j]
        L = 1 + (cone_len[j] if first >= 0 else 0)
        aj = rhs[j]
        Mj = M[j]
        for a in range(L):
            ka = k if a == 0 else first + a - 1
            vy = aj[a]
            vz = aj[L + a]
            for col in range(nx):
                vy -= Mj[a, col] * dx[col]
                vz -= Mj[L + a, col] * dx[col]
            dy[ka] = vy
            dz[ka] = vz
            if not (abs(vy) < np.inf and abs(vz) < np.inf):
                finite = False
    return finite


@called
def refine(
    F, E, rC, Fx, Fy, Ex, P, Q, u, v, normal, cone, cone_len, mu, fixed, N, Npiv, M, R, Rpiv,
    dx, dy, dz, nx, rhs, rF, rE, rR, cx, cy, cz, t1, t2, t3,
):  # fmt: skip
    r"""One step of iterative refinement of the direction (dx, dy, dz): the residual of
    the full Newton system, solved with the same factors and added. The blockwise
    elimination divides by the blocks :math:`N_c`, whose entries part by many orders of
    magnitude near a cone's boundary; the refinement restores the full system's
    accuracy (a sliding puck's friction force 7e-10 off its exact value without)."""
    m = dy.shape[0]
    # rF = -F - (Fx dx + Fy dy)
    for a in range(nx):
        acc = -F[a]
        for bb in range(nx):
            acc -= Fx[a, bb] * dx[bb]
        for k in range(m):
            acc -= Fy[a, k] * dy[k]
        rF[a] = -acc  # solve_blocks takes the negated right-hand side of the F rows
    # rE = -E - (Ex dx + Ey dy + Ez dz), entry by entry of each contact's block
    for k in range(m):
        acc = -E[k]
        for bb in range(nx):
            acc -= Ex[k, bb] * dx[bb]
        rE[k] = acc
    for j in range(normal.shape[0]):
        k = normal[j]
        rE[k] -= dz[k]
        first = cone[j]
        if first >= 0:
            rE[first] -= dy[first] - mu[j] * dy[k]
            for e in range(1, cone_len[j]):
                rE[first + e] -= dz[first + e]
    # rR = rC - ((P z) o (Q dy) + (Q y) o (P dz))
    scaled(Q, dy, t1, normal, cone, cone_len)
    jordan(u, t1, t2, normal, cone, cone_len)
    scaled(P, dz, t1, normal, cone, cone_len)
    jordan(v, t1, t3, normal, cone, cone_len)
    for k in range(m):
        rE[k] = 0.0 if fixed[k] else -rE[k]
        rR[k] = 0.0 if fixed[k] else rC[k] - t2[k] - t3[k]
    if not solve_blocks(
        rF, rE, rR, Fy, u, v, P, Q, normal, cone, cone_len, mu, fixed, N, Npiv, M, R, Rpiv,
        cx, cy, cz, nx, rhs,
    ):  # fmt: skip
        return False
    for a in range(nx):
        dx[a] += cx[a]
    for k in range(m):
        dy[k] += cy[k]
        dz[k] += cz[k]
    return True


@called
def direction(
    F, E, rC, Fx, Fy, Ex, P, Q, u, v, normal, cone, cone_len, mu, fixed, N, Npiv, M, R, Rpiv,
    dx, dy, dz, nx, rhs, rF, rE, rR, cx, cy, cz, t1, t2, t3, refined,
):  # fmt: skip
    """The Newton direction for the complementarity right-hand side ``rC``: the blockwise
    solve (:func:`solve_blocks`) and, when ``refined``, one refinement (:func:`refine`; the
    predictor, which only sets the centring, goes without); False if not finite."""
    if not solve_blocks(
        F, E, rC, Fy, u, v, P, Q, normal, cone, cone_len, mu, fixed, N, Npiv, M, R, Rpiv,
        dx, dy, dz, nx, rhs,
    ):  # fmt: skip
        return False
    if not refined:
        return True
    return refine(
        F, E, rC, Fx, Fy, Ex, P, Q, u, v, normal, cone, cone_len, mu, fixed, N, Npiv, M, R,
        Rpiv, dx, dy, dz, nx, rhs, rF, rE, rR, cx, cy, cz, t1, t2, t3,
    )  # fmt: skip


# --------------------------------------------------------------------- the step
@driver
def contact_step(
    fn, t0, h, qk, pk, x, y, z, has_duals, apart, b, c, Phi, D, d, prm, n, s, mh,
    normal, cone, cone_len, slip_row, mu, n_slip, quadratic, p_end, stats,
):  # fmt: skip
    """One step (:func:`interior_point_step`) from Python: a run's first step, the
    event-driven mode's steps through an impact, and the halved steps, which the
    compiled run (:func:`galerkin_vi.loops.contact_run.contact_steps`) hands back. With constraints
    (``mh`` > 0) a converged step's ``p_end`` is projected onto the hidden constraint
    (:func:`.contact_velocity.project_momentum`); ``stats[2]`` is 0 where that fails.
    ``apart`` marks the contacts kept apart."""
    iterations = interior_point_step(
        fn, t0, h, qk, pk, x, y, z, has_duals, apart, b, c, Phi, D, d, prm, n, s, mh,
        normal, cone, cone_len, slip_row, mu, n_slip, p_end, stats,
    )  # fmt: skip
    if mh > 0 and stats[2] > 0.0:
        q_end = np.empty(n)
        for a in range(n):
            q_end[a] = qk[a] + x[(s - 1) * n + a]
        if not project_momentum(fn, t0 + h, q_end, p_end, prm, n, mh, quadratic):
            stats[2] = 0.0
    return iterations


@called
def interior_point_step(
    fn, t0, h, qk, pk, x, y, z, has_duals, apart, b, c, Phi, D, d, prm, n, s, mh,
    normal, cone, cone_len, slip_row, mu, n_slip, p_end, stats,
):  # fmt: skip
    r"""One time-stepping step of length h from :math:`(q_k, p_k)`.

    ``x`` holds the first guess of the stage unknowns (the control points'
    increments :math:`C^1..C^s` node-major, then the constraints' impulses) and
    receives the solution; ``y`` the starting duals when ``has_duals`` (else the
    cones' centres are taken) and receives the final duals, ``z`` the final
    slacks; ``apart`` marks the contacts kept apart (no force: their y stays 0 and their
    rows drop out: the first touch's search, the broad phase). ``p_end``
    receives :math:`p_{k+1}` before the constraint's momentum projection;
    ``stats`` (iterations, complementarity, converged).

    The layout of y and z: contact j's normal entry ``normal[j]``; with friction
    its cone's ``cone_len[j]`` entries from ``cone[j]`` (else ``cone[j] = -1``),
    whose slips are rows ``slip_row[j]..`` of the point function ``point_slip``.
    """
    nc = normal.shape[0]
    m = y.shape[0]
    sn = s * n
    nx = sn + s * mh
    fixed = np.zeros(m, dtype=np.bool_)
    e = np.zeros(m)
    blocks = 0
    for j in range(nc):
        k = normal[j]
        e[k] = 1.0
        first = cone[j]
        if first >= 0:
            e[first] = 1.0
        if apart[j]:
            fixed[k] = True
            if first >= 0:
                for a in range(cone_len[j]):
                    fixed[first + a] = True
        else:
            blocks += 1 + (1 if first >= 0 else 0)
    if blocks < 1:
        blocks = 1
    width = max(n * n, nc * n, n_slip * n, m, mh * n, 1)
    work = np.zeros((13, width))
    Lqq = np.zeros(n * n)
    Lqv = np.zeros(n * n)
    Lvv = np.zeros(n * n)
    Fv = np.zeros(n * n)
    cH = np.zeros(nc * n * n)
    Wvq = np.zeros(n_slip * n * n)
    Hg = np.zeros(n * n)
    F = np.zeros(nx)
    Fx = np.zeros((nx, nx))
    Fy = np.zeros((nx, m))
    E = np.zeros(m)
    Ex = np.zeros((m, nx))
    pe = np.zeros(n)
    F_t = np.zeros(nx)
    Fx_t = np.zeros((nx, nx))
    Fy_t = np.zeros((nx, m))
    E_t = np.zeros(m)
    Ex_t = np.zeros((m, nx))
    pe_t = np.zeros(n)
    P = np.zeros((m, 4))
    Qs = np.zeros((m, 4))
    N = np.zeros((nc, 4, 8))
    Npiv = np.zeros((nc, 4), dtype=np.int64)
    M = np.zeros((nc, 8, nx))
    rhs = np.zeros((nc, 8))
    R = np.zeros((nx, nx))
    Rpiv = np.zeros(nx, dtype=np.int64)
    u = np.zeros(m)
    v = np.zeros(m)
    rC = np.zeros(m)
    tmp = np.zeros(m)
    tmp2 = np.zeros(m)
    dx_a = np.zeros(nx)
    dy_a = np.zeros(m)
    dz_a = np.zeros(m)
    dx = np.zeros(nx)
    dy = np.zeros(m)
    dz = np.zeros(m)
    xt = np.zeros(nx)
    yt = np.zeros(m)
    zt = np.zeros(m)
    now = np.zeros(4)
    trial = np.zeros(4)
    second = np.zeros(m)
    rF = np.zeros(nx)
    rE = np.zeros(m)
    rR = np.zeros(m)
    cx = np.zeros(nx)
    cy = np.zeros(m)
    cz = np.zeros(m)

    if not has_duals:
        for k in range(m):
            y[k] = e[k]
    interior(y, 1e-6, 1.0, normal, cone, cone_len)
    for k in range(m):
        if fixed[k]:
            y[k] = 0.0
    if not has_duals:
        for k in range(m):
            z[k] = y[k]
    else:
        for k in range(m):
            zt[k] = 0.0
        contact_equations(
            fn, t0, h, qk, pk, x, y, zt, b, c, Phi, D, d, prm, n, s, mh, normal, cone,
            cone_len, slip_row, mu, fixed, F, Fx, Fy, E, Ex, pe, work, Lqq, Lqv, Lvv, Fv,
            cH, Wvq, Hg,
        )  # fmt: skip
        for k in range(m):
            z[k] = -E[k]
        interior(z, 1e-6, 1.0, normal, cone, cone_len)
    for k in range(m):
        if fixed[k]:
            z[k] = e[k]
            e[k] = 0.0
    biggest = 0.0
    for a in range(n):
        biggest = max(biggest, abs(pk[a]))
    scale = 1.0 + biggest
    length = 1.0
    for a in range(n):
        length = max(length, abs(qk[a]))
    tolerance = COMPLEMENTARITY * length
    contact_equations(
        fn, t0, h, qk, pk, x, y, z, b, c, Phi, D, d, prm, n, s, mh, normal, cone, cone_len,
        slip_row, mu, fixed, F, Fx, Fy, E, Ex, pe, work, Lqq, Lqv, Lvv, Fv, cH, Wvq, Hg,
    )  # fmt: skip
    measures(F, E, z, y, normal, cone, cone_len, fixed, scale, tolerance, now, tmp)
    iterations = 0
    converged = False
    while iterations < MAX_ITERATIONS:
        iterations += 1
        if now[0] <= RESIDUAL and now[1] <= 1.0:
            if converged or now[0] <= POLISHED:
                break
            converged = True
        if not (now[0] + now[1] < np.inf):
            break
        gap = 0.0
        for k in range(m):
            gap += z[k] * y[k]
        gap /= blocks
        scaling(z, y, normal, cone, cone_len, fixed, P, Qs)
        if not factor_blocks(
            Fx, Fy, Ex, z, y, P, Qs, normal, cone, cone_len, mu, fixed, N, Npiv, M, R, Rpiv,
            u, v, nx,
        ):  # fmt: skip
            break
        # predictor: the affine-scaling direction (kappa = 0)
        jordan(u, v, rC, normal, cone, cone_len)
        for k in range(m):
            rC[k] = 0.0 if fixed[k] else -rC[k]
        if not direction(
            F, E, rC, Fx, Fy, Ex, P, Qs, u, v, normal, cone, cone_len, mu, fixed, N, Npiv, M,
            R, Rpiv, dx_a, dy_a, dz_a, nx, rhs, rF, rE, rR, cx, cy, cz, tmp, tmp2, second, False,
        ):  # fmt: skip
            break
        alpha = min(
            to_boundary(y, dy_a, 1.0, normal, cone, cone_len),
            to_boundary(z, dz_a, 1.0, normal, cone, cone_len),
        )
        gap_aff = 0.0
        for k in range(m):
            gap_aff += (z[k] + alpha * dz_a[k]) * (y[k] + alpha * dy_a[k])
        gap_aff /= blocks
        sigma = 0.0
        if gap > 0:
            sigma = min(1.0, max(gap_aff, 0.0) / gap) ** 3
        # corrector: centred towards kappa = sigma mu, never below CENTRING times the
        # tolerance, with the predictor's second-order term
        kappa = max(sigma * gap, CENTRING * tolerance)
        scaled(P, dz_a, tmp, normal, cone, cone_len)
        scaled(Qs, dy_a, tmp2, normal, cone, cone_len)
        jordan(tmp, tmp2, second, normal, cone, cone_len)
        for k in range(m):
            rC[k] = 0.0 if fixed[k] else rC[k] - (second[k] - kappa * e[k])
        if not direction(
            F, E, rC, Fx, Fy, Ex, P, Qs, u, v, normal, cone, cone_len, mu, fixed, N, Npiv, M,
            R, Rpiv, dx, dy, dz, nx, rhs, rF, rE, rR, cx, cy, cz, tmp, tmp2, second, True,
        ):  # fmt: skip
            break
        complementarity = now[3]
        tau = max(FRACTION_TO_BOUNDARY, 1.0 - max(now[0], complementarity) ** 2)
        tau = min(tau, 1.0 - TO_BOUNDARY)
        alpha = min(
            to_boundary(y, dy, tau, normal, cone, cone_len),
            to_boundary(z, dz, tau, normal, cone, cone_len),
        )
        # backtracking (as Dojo's): halved while both measures grow
        for _ in range(LINE_SEARCH):
            for a in range(nx):
                xt[a] = x[a] + alpha * dx[a]
            for k in range(m):
                yt[k] = y[k] + alpha * dy[k]
                zt[k] = z[k] + alpha * dz[k]
            contact_equations(
                fn, t0, h, qk, pk, xt, yt, zt, b, c, Phi, D, d, prm, n, s, mh, normal, cone,
                cone_len, slip_row, mu, fixed, F_t, Fx_t, Fy_t, E_t, Ex_t, pe_t, work, Lqq,
                Lqv, Lvv, Fv, cH, Wvq, Hg,
            )  # fmt: skip
            measures(F_t, E_t, zt, yt, normal, cone, cone_len, fixed, scale, tolerance, trial, tmp)
            if trial[0] <= now[0] or trial[1] <= now[1]:
                break
            alpha /= 2
        if not (alpha > 1e-12 and trial[0] + trial[1] < np.inf):
            break
        if converged and not (trial[0] <= RESIDUAL and trial[1] <= 1.0):
            break
        # accepted: the trial's equations become the iterate's (swapped, not copied: an
        # array copy costs numba seconds of compile for its shape checks)
        for a in range(nx):
            x[a] = xt[a]
        for k in range(m):
            y[k] = yt[k]
            z[k] = zt[k]
        F, F_t = F_t, F
        Fx, Fx_t = Fx_t, Fx
        Fy, Fy_t = Fy_t, Fy
        E, E_t = E_t, E
        Ex, Ex_t = Ex_t, Ex
        pe, pe_t = pe_t, pe
        now, trial = trial, now
    if not converged:
        converged = now[0] <= RESIDUAL and now[2] <= ACCEPTABLE / COMPLEMENTARITY
    for a in range(n):
        p_end[a] = pe[a]
    stats[0] = iterations
    stats[1] = now[3]
    stats[2] = 1.0 if converged else 0.0
    return iterations
