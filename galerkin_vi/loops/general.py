r"""The general Newton loop: any regular Lagrangian, forces, time dependence.

With :math:`f` the external forces (discrete Lagrange–d'Alembert; the point
functions return :math:`L_q + f` and :math:`L_{qq} + f_q`, and :math:`f_v`
separately when it is not zero), the stage equations of one step are

.. math::

    G^\nu = \sum_i b_i \big[h\,\Phi_{i\nu} (L_q + f)^{(i)} + D_{i\nu} L_v^{(i)}\big],
    \qquad R^0 = p_k + G^0,\quad R^\nu = G^\nu\ (1 \le \nu < s),
    \qquad p_{k+1} = G^s = p_k + h \sum_i b_i (L_q + f)^{(i)},

solved by simplified Newton with the exact Jacobian (notation of :mod:`.common`).
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
from .on_demand import driver
from .point import point_gradient, point_gradient_row, point_hessian
from .traits import HAS_FV

__all__ = [
    "SIMPLIFIED_CONTRACTION",
    "STALE_RETRY",
    "assemble_gradient",
    "assemble_newton",
    "general_loop",
    "make_work",
    "momentum_increment",
]

#: simplified Newton keeps its factors while each increment is at most this times the
#: one before (an exact Newton iteration costs one Hessian per point and an LU more)
SIMPLIFIED_CONTRACTION = 0.01
#: after factors carried over from an earlier step contracted too slowly, the next
#: steps assemble their Jacobian at their first iterate before stale factors are tried
STALE_RETRY = 16


@kernel
def assemble_gradient(fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G):
    """G[nu] = dL_d/dq^nu for all nu = 0..s."""
    r = b.shape[0]
    inv_h = 1.0 / h
    s1, n = C.shape
    G[:, :] = 0.0
    for i in range(r):
        interpolate(i, inv_h, qk, C, Phi, D, Q, V)
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
    the rounding of its addition to the next step, so long runs keep their
    energy to round-off (docs/design-notes.md, "Accuracy over long runs").
    """
    r = b.shape[0]
    n = qk.shape[0]
    inv_h = 1.0 / h
    for a in range(n):
        out[a] = 0.0
    for i in range(r):
        interpolate(i, inv_h, qk, C, Phi, D, Q, V)
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
    inv_h = 1.0 / h
    G[:, :] = 0.0
    K[:, :] = 0.0
    for i in range(r):
        interpolate(i, inv_h, qk, C, Phi, D, Q, V)
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
    r"""Run ``n_steps`` steps of the position–momentum map from (q0, p0).

    ``fn`` holds the point functions' addresses (:mod:`.point`), ``traits``,
    ``pattern`` (``None``: dense) and ``periodic`` the system's structure,
    ``couplings`` the switch of :math:`L_{qv}` and :math:`f_v` (:mod:`.traits`).
    ``iterations_out[j]`` receives the largest Newton iteration count of steps
    ``j*save_every .. (j+1)*save_every - 1`` (every step when save_every = 1) and
    ``iteration_total[0]`` their sum: a long run with ``save_every`` stores
    nothing per step.

    **Simplified Newton.** The stage equations :math:`R(C) = 0` are solved with
    the LU factors of the exact Jacobian :math:`K` kept across iterations *and
    steps* (as Hairer's RADAU5 and GNI codes do): an iteration is one gradient
    per quadrature point and one solve with the stored factors. The Jacobian is
    assembled afresh (one Hessian per quadrature point and an LU) on the first
    step, whenever the increments contract by less than ``SIMPLIFIED_CONTRACTION``
    from one iteration to the next (and then at the first iterate of the next
    ``STALE_RETRY`` steps too: the Jacobian drifts too fast for the step size), or
    when the iteration fails with factors from an earlier iterate. The iteration ends when
    an update leaves every position :math:`q_k + C^\nu` bit-identical (the gradients
    of that sweep are then the gradients at the solution, and the momentum update
    reuses them), or by :func:`.newton_status` applied to the increments relative
    to their own coordinates, :math:`\max_{\nu,a} |\delta C^\nu_a| /
    (1 + |q_{k,a}| + |C^\nu_a|)`.

    The residual rows are summed from tables of the gradients at the quadrature
    points with weights computed once per run (``WQ``, ``WV``), and the
    gradients are written into those tables in place.

    The new momentum is :math:`p_k` plus :func:`momentum_increment`, added
    with compensated summation like the positions. Saves rows at steps k with
    k % save_every == 0 and at the last step. The solve is written into the step
    loop, its work arrays bound once (see :func:`.stage_form_loop`: no
    reference counts per step). Returns (status, steps completed, rows saved,
    max residual, failing increment).
    """
    n = q0.shape[0]
    s1 = d.shape[0]
    s = s1 - 1
    r = b.shape[0]
    banded = pattern is not None
    # unpacked once, before the first step: no tuple and no reference counts per step
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = make_work(s, n, traits, pattern)
    F = np.zeros((r, n))  # L_q + f at the quadrature points, of the last gradient sweep
    FV = np.zeros((r, n))  # L_v at the quadrature points
    # G^nu = sum_i WQ[nu, i] (L_q + f)^(i) + WV[nu, i] L_v^(i), nu < s: the residual's rows
    WQ = np.zeros((s, r))
    WV = np.zeros((s, r))
    for nu in range(s):
        for i in range(r):
            WQ[nu, i] = b[i] * h * Phi[i, nu]
            WV[nu, i] = b[i] * D[i, nu]
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
    factored = False  # K holds LU factors (of some earlier iterate)
    fresh_for = 0  # steps that start with a fresh Jacobian before stale factors are tried
    inv_h = 1.0 / h
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        # ---- the stage equations (see the docstring)
        status = STATUS_NEWTON_FAILED
        its = 0
        increment = np.inf
        residual = np.inf
        previous = np.inf
        fresh = not factored or fresh_for > 0  # assemble and factorise K in this iteration
        if fresh_for > 0:
            fresh_for -= 1
        refreshed = False  # K was assembled in this step
        current = False
        # increments are judged against the size of their coordinate of q = q_k + C:
        # far from the origin the round-off floor of C is that of q
        while its < maxiter:
            its += 1
            if fresh:
                K[:, :] = 0.0
            for i in range(r):
                interpolate(i, inv_h, qk, C, Phi, D, Q, V)
                ti = tk + c[i] * h
                if fresh:
                    point_hessian(fn, ti, Q, V, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
                    for a in range(n):
                        F[i, a] = Lq[a]
                        FV[i, a] = Lv[a]
                    for nu in range(s):
                        for mu in range(1, s1):
                            add_block(
                                K, nu, mu, s, n, b[i] * D[i, nu] * D[i, mu] / h, Lvv,
                                b[i] * h * Phi[i, nu] * Phi[i, mu], Lqq,
                                b[i] * Phi[i, nu] * D[i, mu], b[i] * D[i, nu] * Phi[i, mu],
                                Lqv, Fv, traits, pattern, couplings,
                            )  # fmt: skip
                else:
                    point_gradient_row(fn, ti, Q, V, prm, F, FV, i)
            # R^0 = p_k + G^0, R^nu = G^nu, summed in registers from the tables
            residual = 0.0
            for nu in range(s):
                for a in range(n):
                    val = pk[a] if nu == 0 else 0.0
                    for i in range(r):
                        val += WQ[nu, i] * F[i, a] + WV[nu, i] * FV[i, a]
                    R[unknown(nu, a, s, n, banded)] = -val
                    if not abs(val) <= residual:  # also catches NaN
                        residual = abs(val)
            if not residual < 1e300:
                status = STATUS_NONFINITE
                increment = np.inf
                break
            if fresh:
                factored = factor_jacobian(K, piv, s, traits, pattern)
                if not factored:
                    status = STATUS_SINGULAR
                    increment = np.inf
                    break
            solve_jacobian(K, piv, s, R, traits, pattern)
            increment = 0.0  # the largest |delta| (reported when the step fails)
            # the largest |delta| relative to its own coordinate: against the largest |q|
            # (a clock at t = 500 beside positions of size 1) the increments of the small
            # coordinates passed for converged, and stale factors were never refreshed
            scaled = 0.0
            moved = False
            for nu in range(1, s1):
                for a in range(n):
                    delta = R[unknown(nu - 1, a, s, n, banded)]
                    updated = C[nu, a] + delta
                    # the positions q_k + C decide: C, an increment, has bits far below
                    # those of q, which a linearly converging iteration takes many
                    # sweeps to settle (a Kepler orbit's clock: 16 instead of 4)
                    if qk[a] + updated != qk[a] + C[nu, a]:
                        moved = True
                    C[nu, a] = updated
                    if abs(delta) > increment:
                        increment = abs(delta)
                    relative = abs(delta) / (1.0 + abs(qk[a]) + abs(updated))
                    if relative > scaled:
                        scaled = relative
            if fresh:
                refreshed = True
            if not moved:
                # the control points are a fixed point in floating point; the gradients
                # of this sweep are those at C unless the Hessian's CSE gave them
                status = STATUS_OK
                current = not fresh
                break
            fresh = False
            decision = newton_status(scaled, previous, 1.0, tol, its, maxiter)
            if decision == CONVERGED:
                status = STATUS_OK
                break
            if decision != CONTINUE:
                if refreshed:
                    break
                # factors of an earlier step: retry with the exact Jacobian
                fresh = True
                previous = np.inf
                continue
            if its >= 2 and scaled > SIMPLIFIED_CONTRACTION * previous and scaled > tol:
                # contracting too slowly: the exact Jacobian at this iterate, and at the
                # start of the next steps
                fresh = True
                if not refreshed:
                    fresh_for = STALE_RETRY
            previous = scaled
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK:
            # the step's momentum change h sum_i b_i (L_q + f)^(i) (as momentum_increment,
            # written out: a helper taking arrays here costs reference counts per step);
            # the last sweep's gradients are those at the solution when it moved nothing
            if not current:
                for i in range(r):
                    interpolate(i, inv_h, qk, C, Phi, D, Q, V)
                    ti = tk + c[i] * h
                    point_gradient_row(fn, ti, Q, V, prm, F, FV, i)
            for a in range(n):
                acc = 0.0
                for i in range(r):
                    acc += b[i] * F[i, a]
                dp[a] = h * acc
                if not abs(dp[a]) < 1e300:
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
