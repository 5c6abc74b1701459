r"""The compiled time loop of the velocity-stage form, for a mass matrix that varies with q.

For :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v - U(t, q)` with Gauss quadrature
of :math:`s` points; the stage equations and tables are those of
:mod:`galerkin_vi.method.velocity_stages`:

.. math::

    Q_i = q_k + h\sum_j a_{ij} V_j, \quad P_i = p_k + h\sum_j \bar a_{ij} F_j, \quad
    V_i \leftarrow V_i + M(Q_i)^{-1}\big(P_i - L_v(Q_i, V_i)\big),
    \quad F_i = (L_q + f)(Q_i, V_i),

or, when the system has the velocity in closed form (``point_velocity``: a
diagonal :math:`M`, or at most two coordinates), the sweep of Hamilton's
equations of the hand-written kernels,

.. math::

    V_i = M(Q_i)^{-1}\big(P_i - a(Q_i)\big), \quad F_i = (L_q + f)(Q_i, V_i),

one call per stage, which solves the momentum equation exactly instead of
correcting :math:`V_i` and :math:`F_i` to first order (the residual reported
for those runs is then 0); both are
iterated to round-off like the hand-written fixed-point kernels
(``benchmarks/peers/strong.py``): the first iterate from the previous step's
stage velocities and forces extrapolated to this step's nodes, and the
iteration stops when a sweep leaves every stage position and momentum
bit-identical (or when the change stops decreasing at round-off level).
:math:`q_{k+1} = q_k + h\sum_j b_j V_j` and :math:`p_{k+1} = p_k + h\sum_j b_j F_j`
are added with compensated summation.

When the iteration contracts too slowly (stiff forces, a step too long for a
fixed point) the loop stops before the step and returns its status; the
integrator continues the run with the general Newton loop
(:meth:`galerkin_vi.Integrator.kernel_path`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .common import (
    STATUS_NEWTON_FAILED,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR,
    compensated_add,
    save_row,
    wrap_angles,
)
from .linalg import lu_factor_inplace, lu_solve_inplace
from .on_demand import driver
from .point import VELOCITY, point_mass_row, point_velocity_row
from .stage_form import too_slow

__all__ = [
    "ROUNDOFF_CHANGE",
    "SWEEP_MEMORY",
    "varying_mass_loop",
]

#: a change (relative to 1 + |x|) that stops decreasing below this is round-off
#: oscillation of the last bits, and the iteration has converged
ROUNDOFF_FLOOR = 1e-14
#: between ROUNDOFF_FLOOR and this, a change that stops decreasing is round-off only
#: when it is also no smaller than ROUNDOFF_STALL times the change two sweeps before
#: (ill-conditioned stage equations: a clock of size 600, a singular mass matrix)
ROUNDOFF_CHANGE = 1e-10
ROUNDOFF_STALL = 0.9
#: weight of the past in the running mean of the sweeps per step that ``allowance`` bounds
SWEEP_MEMORY = 0.75


@driver
def varying_mass_loop(
    fn,
    traits,
    pattern,
    periodic,
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
    A,
    Abar,
    X,
    tol,
    maxiter,
    contraction,
    allowance,
    t_out,
    q_out,
    p_out,
    turns_out,
    iterations_out,
    iteration_total,
):
    r"""Run ``n_steps`` steps of the velocity-stage form from (q0, p0); as :func:`.general_loop`.

    ``b, c, A, Abar, X`` are :class:`~galerkin_vi.method.velocity_stages.VaryingMassTables`;
    ``pattern`` must be ``None`` (the mass matrix is stored dense). ``v0`` starts the
    stage velocities of the first step. A step whose iteration fails (or whose sweeps
    shrink the change by a factor above ``contraction``, or would need more than
    ``maxiter`` sweeps by :func:`.too_slow`'s prediction), and the step after the sweeps
    per step have come to average more than ``allowance + r``, is not taken (an infinite
    ``contraction`` leaves only ``maxiter`` and divergence to overflow); the state
    before it is the last row (saved even when not due), from which the caller
    continues with Newton. ``contraction`` and ``allowance`` are run-time data
    (:class:`galerkin_vi.run.loop_choice.HandOver`): the ordinary runs hand over
    early, the adaptive ones keep the fixed point through slow sweeps. Returns
    (status, steps completed, rows saved, max momentum residual, last change).
    """
    n = q0.shape[0]
    r = b.shape[0]
    V = np.zeros((r, n))  # stage velocities
    F = np.zeros((r, n))  # (L_q + f) at the stages, of the last sweep
    V_prev = np.zeros((r, n))
    F_prev = np.zeros((r, n))
    Q = np.zeros((r, n))  # stage positions and momenta from V, F
    P = np.zeros((r, n))
    Qi = np.zeros(n)
    Vi = np.zeros(n)
    Lv = np.zeros(n)
    M = np.zeros(n * n)  # L_vv, flat; entries never written stay zero
    Lqv = np.zeros(n * n)  # d(L_q + f)/dv, flat
    LU = np.zeros((n, n))
    piv = np.zeros(n, dtype=np.int64)
    rhs = np.zeros(n)
    dq = np.zeros(n)
    dp = np.zeros(n)
    inv_scale_q = np.zeros(n)
    inv_scale_p = np.zeros(n)
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    p_lost = np.zeros(n)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    # the first step starts from v0 and the force at (q0, v0) at every stage
    for a in range(n):
        Qi[a] = qk[a]
        Vi[a] = v0[a]
    point_mass_row(fn, t0, Qi, Vi, prm, F, Lv, Lqv, M, 0)
    for i in range(r):
        for a in range(n):
            V[i, a] = v0[a]
            F[i, a] = F[0, a]
    worst = 0.0
    mean_sweeps = 0.0
    explicit = fn[VELOCITY] != 0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            # the last step's stage values, extrapolated to this step's nodes
            for i in range(r):
                for a in range(n):
                    V_prev[i, a] = V[i, a]
                    F_prev[i, a] = F[i, a]
            for i in range(r):
                for a in range(n):
                    accv = 0.0
                    accf = 0.0
                    for j in range(r):
                        accv += X[i, j] * V_prev[j, a]
                        accf += X[i, j] * F_prev[j, a]
                    V[i, a] = accv
                    F[i, a] = accf
        # each coordinate's change against its own size, 1/(1 + |q_a|): against the largest
        # |q|, the clock of an adaptive run (t up to 600 on Kepler) let the round-off test
        # below accept position changes of 1e-8 as converged
        for a in range(n):
            inv_scale_q[a] = 1.0 / (1.0 + abs(qk[a]))
            inv_scale_p[a] = 1.0 / (1.0 + abs(pk[a]))
        status = STATUS_NEWTON_FAILED
        its = 0
        change = np.inf
        previous = np.inf
        earlier = np.inf
        residual = 0.0
        while True:
            # the stage positions and momenta of the current V and F (the first iterate
            # when its = 0); after a sweep, whether and how far they moved, against each
            # coordinate's scale (a multiplication by the inverses formed once per step)
            change_q = 0.0
            change_p = 0.0
            moved = False
            for i in range(r):
                for a in range(n):
                    accq = 0.0
                    accp = 0.0
                    for j in range(r):
                        accq += A[i, j] * V[j, a]
                        accp += Abar[i, j] * F[j, a]
                    new_q = qk[a] + h * accq
                    new_p = pk[a] + h * accp
                    if new_q != Q[i, a] or new_p != P[i, a]:
                        moved = True
                        dq_abs = abs(new_q - Q[i, a]) * inv_scale_q[a]
                        dp_abs = abs(new_p - P[i, a]) * inv_scale_p[a]
                        if not dq_abs <= change_q:  # also catches NaN
                            change_q = dq_abs
                        if not dp_abs <= change_p:  # also catches NaN
                            change_p = dp_abs
                    Q[i, a] = new_q
                    P[i, a] = new_p
            if its > 0:
                change = max(change_q, change_p)
                if not moved:
                    status = STATUS_OK
                    break
                if not change < 1e300 or not residual < 1e300:
                    status = STATUS_NONFINITE
                    break
                # a change that stops decreasing has reached the round-off floor when
                # it is a few units of the last place, or when two sweeps have not
                # shrunk it either: sweeps whose contraction alternates (near a close
                # encounter) grow it for one sweep on their way down, still far from
                # the fixed point
                # (a change that still decreases is not accepted however small: stopping
                # there leaves a sub-ulp error of one sign each step, and the energy of
                # a long run drifts linearly instead of as a random walk)
                if (
                    its >= 2
                    and change >= previous
                    and (
                        change < ROUNDOFF_FLOOR
                        or (change < ROUNDOFF_CHANGE and change >= ROUNDOFF_STALL * earlier)
                    )
                ):
                    status = STATUS_OK
                    break
                if its >= maxiter:
                    break
                # an infinite contraction turns the slow-sweep test off: the sweeps of a
                # close encounter may stall or grow for one sweep and converge after it
                if contraction < np.inf and too_slow(
                    change, previous, its, contraction, maxiter, tol
                ):
                    break
                earlier = previous
                previous = change
            # a sweep: every stage's velocity from its momentum equation, and its force
            its += 1
            residual = 0.0
            singular = False
            if explicit:
                # the momentum equation solved in closed form: its residual is round-off
                # and reported as 0; a NaN or inf in V or F reaches Q or P, and the
                # change test above stops the iteration
                for i in range(r):
                    for a in range(n):
                        Qi[a] = Q[i, a]
                        Vi[a] = P[i, a]
                    point_velocity_row(fn, tk + c[i] * h, Qi, Vi, prm, F, V, i)
                continue
            for i in range(r):
                for a in range(n):
                    Qi[a] = Q[i, a]
                    Vi[a] = V[i, a]
                point_mass_row(fn, tk + c[i] * h, Qi, Vi, prm, F, Lv, Lqv, M, i)
                for a in range(n):
                    rhs[a] = P[i, a] - Lv[a]
                    if not abs(rhs[a]) <= residual:  # also catches NaN
                        residual = abs(rhs[a])
                # rhs <- M^-1 rhs (systems without point_velocity: a full M of three or
                # more coordinates, or repeated terms): up to two coordinates by the
                # adjugate (one division),
                # written here (a helper taking these arrays cost reference counts per
                # call: double pendulum 0.96-0.98 of the kernel inline, 1.11-1.42 as a
                # helper, 1.4 with the LU at every size); above from a copy (the point
                # function writes only M's nonzeros).
                # Only a preconditioner: its rounding changes the contraction, not the
                # fixed point
                if n == 1:
                    if M[0] == 0.0:
                        singular = True
                        break
                    rhs[0] = rhs[0] / M[0]
                elif n == 2:
                    det = M[0] * M[3] - M[1] * M[2]
                    if det == 0.0:
                        singular = True
                        break
                    inv_det = 1.0 / det
                    x0 = (M[3] * rhs[0] - M[1] * rhs[1]) * inv_det
                    rhs[1] = (M[0] * rhs[1] - M[2] * rhs[0]) * inv_det
                    rhs[0] = x0
                else:
                    # a diagonal M (a large system with repeated terms) by divisions,
                    # else a pivoted LU of a copy
                    diagonal = True
                    for a in range(n):
                        for cc in range(n):
                            LU[a, cc] = M[a * n + cc]
                            if cc != a and LU[a, cc] != 0.0:
                                diagonal = False
                    if diagonal:
                        for a in range(n):
                            if LU[a, a] == 0.0:
                                singular = True
                            else:
                                rhs[a] = rhs[a] / LU[a, a]
                        if singular:
                            break
                    else:
                        if not lu_factor_inplace(LU, piv):
                            singular = True
                            break
                        lu_solve_inplace(LU, piv, rhs)
                for a in range(n):
                    V[i, a] += rhs[a]
                # the force at the new velocity, to first order: lagging one sweep behind
                # V, it cost 2-4 sweeps per step more than the kernels' (double pendulum)
                for a in range(n):
                    acc = 0.0
                    for cc in range(n):
                        acc += Lqv[a * n + cc] * rhs[cc]
                    F[i, a] += acc
            if singular:
                status = STATUS_SINGULAR
                break
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK:
            for a in range(n):
                accv = 0.0
                accf = 0.0
                for j in range(r):
                    accv += b[j] * V[j, a]
                    accf += b[j] * F[j, a]
                dq[a] = h * accv
                dp[a] = h * accf
                if not (abs(dq[a]) < 1e300 and abs(dp[a]) < 1e300):
                    status = STATUS_NONFINITE
        if status == STATUS_OK:
            # the first step starts from constant stages and takes more sweeps: not counted
            mean_sweeps = its if k <= 1 else SWEEP_MEMORY * mean_sweeps + (1 - SWEEP_MEMORY) * its
            if k >= 1 and mean_sweeps > allowance + r:
                # this step is good, but the steps cost more than Newton's would: hand
                # over before it (the caller resumes from the state at step k)
                status = STATUS_NEWTON_FAILED
        if status != STATUS_OK:
            if k % save_every != 0:  # the state at step k, the last row, due or not
                saved = save_row(
                    saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                )
            return status, k, saved, worst, change
        if residual > worst:
            worst = residual
        compensated_add(pk, p_lost, dp)
        compensated_add(qk, q_lost, dq)
        if periodic is not None:
            wrap_angles(qk, q_lost, turns, periodic)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
    return STATUS_OK, n_steps, saved, worst, 0.0
