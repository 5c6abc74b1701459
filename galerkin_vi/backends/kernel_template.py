r"""The compiled time loop of the Galerkin integrator.

Everything below the ``# ---- kernel ----`` marker is copied into each
generated module after the system's point functions and jitted there as a
whole, so that one file holds all the code numba caches. The header imports the
documented stubs of :mod:`.pointwise_interface` only to make this file valid
Python on its own.

Notation (see the theory page): control points :math:`q^\nu = q_k + C^\nu`
stored as increments :math:`C^\nu` from the step's start (:math:`C^0 = 0`),
quadrature weights :math:`b_i`, tables :math:`\Phi_{i\nu} = \ell_\nu(c_i)` and
:math:`D_{i\nu} = \ell'_\nu(c_i)`. At quadrature point :math:`i`,
:math:`Q_i = q_k + \sum_\nu \Phi_{i\nu} C^\nu` and
:math:`V_i = \tfrac1h\sum_\nu D_{i\nu} C^\nu`;

.. math::

    G^\nu = \sum_i b_i \big[h\,\Phi_{i\nu} (L_q + f)^{(i)} + D_{i\nu} L_v^{(i)}\big],
    \qquad R^0 = p_k + G^0,\quad R^\nu = G^\nu\ (1 \le \nu < s),
    \qquad p_{k+1} = G^s = p_k + h \sum_i b_i (L_q + f)^{(i)},

where :math:`f` are the external forces (discrete Lagrange–d'Alembert; the
point functions already return :math:`L_q + f` and :math:`L_{qq} + f_q`, and
:math:`f_v` separately when it is not zero).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ..newton import (
    CONTINUE,
    CONVERGED,
    band_lu_factor,
    band_lu_solve,
    lu_factor_inplace,
    lu_solve_inplace,
    newton_status,
)
from .pointwise_interface import (
    AUTONOMOUS,
    BAND,
    BANDED,
    DIAGONAL_MASS,
    HAS_FV,
    HAS_LQV,
    HAS_PERIODIC,
    NNZ,
    PATTERN_COL,
    PATTERN_ROW,
    PATTERN_T,
    PERIODIC,
    TWO_PI_HI,
    TWO_PI_LO,
    kernel,
    point_gradient,
    point_hessian,
)

# ---- kernel ----
STATUS_OK = 0
STATUS_NEWTON_FAILED = 1
STATUS_SINGULAR = 2
STATUS_NONFINITE = 3
# below this relative increment Newton has converged to a few ulps after one more step
FREEZE = 1e-8


@kernel
def interpolate(i, h, qk, C, Phi, D, Q, V):
    """Q = q_k + sum_nu Phi[i, nu] C[nu] and V = sum_nu D[i, nu] C[nu] / h at quadrature point i."""
    s1, n = C.shape
    for a in range(n):
        qa = 0.0
        va = 0.0
        for nu in range(1, s1):
            if Phi[i, nu] != 0.0:  # collocated nodes: Phi is the identity
                qa += Phi[i, nu] * C[nu, a]
            va += D[i, nu] * C[nu, a]
        Q[a] = qk[a] + qa
        V[a] = va / h


@kernel
def band_half_width(s):
    """Half-bandwidth of the stage Jacobian ordered coordinate-major, (BAND + 1) s - 1."""
    return (BAND + 1) * s - 1


@kernel
def unknown(nu, a, s, n):
    """Position of coordinate a of control point nu (0-based among the unknowns).

    Node-major (nu n + a) for dense storage; coordinate-major (a s + nu) for
    banded storage, which keeps coupled coordinates' unknowns close together.
    """
    if BANDED:
        return a * s + nu
    return nu * n + a


@kernel
def add_block(K, nu, mu, s, n, w_vv, Lvv, w_qq, Lqq, w_qv, w_vq, Lqv, Fv):
    r"""Add to block (equation nu, control point mu) of K the point-wise second derivatives.

    Block :math:`(\nu, \mu)` gains
    :math:`w_{vv} L_{vv} + w_{qq} (L_{qq} + f_q) + w_{qv} (L_{qv} + f_v) + w_{vq} L_{qv}^T`,
    with the blocks stored flat (``a n + c``, or the pattern position when banded).
    """
    if BANDED:
        kb = band_half_width(s)
        for k in range(NNZ):
            a = PATTERN_ROW[k]
            cc = PATTERN_COL[k]
            value = w_vv * Lvv[k]
            if w_qq != 0.0:
                value += w_qq * Lqq[k]
            if HAS_LQV:
                value += w_qv * Lqv[k] + w_vq * Lqv[PATTERN_T[k]]
            if HAS_FV:
                value += w_qv * Fv[k]
            i = a * s + nu
            j = cc * s + mu - 1
            K[2 * kb + i - j, j] += value
        return
    row0 = nu * n
    col0 = (mu - 1) * n
    if w_vv != 0.0:
        for a in range(n):
            for cc in range(n):
                K[row0 + a, col0 + cc] += w_vv * Lvv[a * n + cc]
    # collocated Lobatto nodes (Phi = I): L_qq only on the diagonal blocks
    if w_qq != 0.0:
        for a in range(n):
            for cc in range(n):
                K[row0 + a, col0 + cc] += w_qq * Lqq[a * n + cc]
    if HAS_LQV and (w_qv != 0.0 or w_vq != 0.0):
        for a in range(n):
            for cc in range(n):
                K[row0 + a, col0 + cc] += w_qv * Lqv[a * n + cc] + w_vq * Lqv[cc * n + a]
    if HAS_FV and w_qv != 0.0:
        for a in range(n):
            for cc in range(n):
                K[row0 + a, col0 + cc] += w_qv * Fv[a * n + cc]


@kernel
def factor_jacobian(K, piv, s):
    """LU-factorise K in place (banded or dense); False if singular."""
    if BANDED:
        kb = band_half_width(s)
        return band_lu_factor(K, piv, kb, kb)
    return lu_factor_inplace(K, piv)


@kernel
def solve_jacobian(K, piv, s, R):
    """Overwrite R with K^{-1} R from :func:`factor_jacobian`'s factors."""
    if BANDED:
        kb = band_half_width(s)
        band_lu_solve(K, piv, kb, kb, R)
    else:
        lu_solve_inplace(K, piv, R)


@kernel
def assemble_gradient(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G):
    """G[nu] = dL_d/dq^nu for all nu = 0..s."""
    r = b.shape[0]
    s1, n = C.shape
    G[:, :] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_gradient(0.0 if AUTONOMOUS else t0 + c[i] * h, Q, V, prm, Lq, Lv)
        for nu in range(s1):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                G[nu, a] += wq * Lq[a] + wv * Lv[a]


@kernel
def momentum_increment(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, out):
    r"""out = h \sum_i b_i (L_q + f)^{(i)}, the step's momentum change; False if not finite.

    Summing :math:`G^\nu` over all :math:`\nu` (:math:`\sum_\nu \ell_\nu = 1`,
    :math:`\sum_\nu \ell_\nu' = 0`) shows that :math:`p_k` plus this is
    :math:`G^s = p_{k+1}` once the stage equations hold. Formed as :math:`G^s`
    directly, the new momentum is a sum of terms of the size of :math:`p` that
    cancel down to it, with a rounding error of order :math:`\varepsilon|p|`
    in every step; the increment is small, and :func:`compensated_add` carries
    the rounding of its addition to the next step. Measured over 1e6 steps
    (outer solar system, s = 3, h = 10 d): relative energy error in the last
    tenth 5.2e-12 through :math:`G^s`, 9e-15 this way.
    """
    r = b.shape[0]
    n = qk.shape[0]
    for a in range(n):
        out[a] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_gradient(0.0 if AUTONOMOUS else t0 + c[i] * h, Q, V, prm, Lq, Lv)
        for a in range(n):
            out[a] += b[i] * Lq[a]
    finite = True
    for a in range(n):
        out[a] *= h
        if not abs(out[a]) < 1e300:
            finite = False
    return finite


@kernel
def compensated_add(x, x_lost, y):
    """x += y with Kahan compensation; ``x_lost`` carries each rounding error to the next."""
    for a in range(x.shape[0]):
        z = y[a] - x_lost[a]
        total = x[a] + z
        x_lost[a] = (total - x[a]) - z
        x[a] = total


@kernel
def assemble_newton(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K):
    """G as above and K[(nu, a), (mu, c)] = dG^nu_a / dq^mu_c, nu = 0..s-1, mu = 1..s.

    K is stored as :func:`new_jacobian` allocates it, rows and columns placed by
    :func:`unknown`.
    """
    r = b.shape[0]
    s1, n = C.shape
    s = s1 - 1
    G[:, :] = 0.0
    K[:, :] = 0.0
    for i in range(r):
        interpolate(i, h, qk, C, Phi, D, Q, V)
        point_hessian(0.0 if AUTONOMOUS else t0 + c[i] * h, Q, V, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
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
                )


@kernel
def first_guess(C, d, h, v0):
    """Increments q^nu - q_0 = d_nu h v_0 on the first step (no previous polynomial)."""
    s1, n = C.shape
    for nu in range(s1):
        for a in range(n):
            C[nu, a] = d[nu] * h * v0[a]


@kernel
def advance_position(qk, q_lost, C, turns):
    """q_{k+1} = q_k + C[s] with compensated (Kahan) summation, angles kept in [-pi, pi).

    ``q_lost`` carries the rounding error of each addition into the next one;
    measured over 1e6 Kepler steps (s = 4, h = T/500): max|dH| in the last tenth
    1.3e-12 -> 3.5e-13, energy trend 5.3e-16 -> 1.2e-16 per period.
    """
    s = C.shape[0] - 1
    for a in range(qk.shape[0]):
        y = C[s, a] - q_lost[a]
        total = qk[a] + y
        q_lost[a] = (total - qk[a]) - y
        qk[a] = total
    if HAS_PERIODIC:
        wrap_angles(qk, q_lost, turns)


@kernel
def wrap_angles(qk, q_lost, turns):
    r"""Translate periodic coordinates (angles) by whole turns into :math:`[-\pi, \pi)`.

    :math:`L`, the forces and the constraints are :math:`2\pi`-periodic in
    them, so the map commutes with the shift; evaluating them at a small
    angle keeps the absolute accuracy :math:`\varepsilon`, where an angle of
    :math:`10^4` would lose :math:`10^4\varepsilon` in every sine. The shift
    subtracts :math:`2\pi = ` ``TWO_PI_HI + TWO_PI_LO`` exactly (Sterbenz: the
    high part cancels without rounding, the low part joins ``q_lost``);
    ``turns`` counts the whole turns removed, for the output.
    """
    for a in range(qk.shape[0]):
        if PERIODIC[a]:
            if not -np.pi <= qk[a] < np.pi:
                # many turns at once (a start far out): one rounding of k 2 pi, the
                # precision of such an angle anyway; one turn (every step) is exact
                k = np.floor((qk[a] + np.pi) / TWO_PI_HI)
                qk[a] -= k * TWO_PI_HI
                q_lost[a] += k * TWO_PI_LO
                turns[a] += k
            while qk[a] >= np.pi:
                qk[a] -= TWO_PI_HI
                q_lost[a] += TWO_PI_LO
                turns[a] += 1.0
            while qk[a] < -np.pi:
                qk[a] += TWO_PI_HI
                q_lost[a] -= TWO_PI_LO
                turns[a] -= 1.0


@kernel
def extrapolate(C, C_prev, E):
    """Initial guess: the previous step's polynomial at this step's nodes, re-based.

    On entry C holds the previous step's increments; on exit the guess for this
    step as increments from q_k = q_{k-1} + C_prev[s] (C_prev is work space).
    """
    s1, n = C.shape
    s = s1 - 1
    for nu in range(s1):
        for a in range(n):
            C_prev[nu, a] = C[nu, a]
    for nu in range(s1):
        for a in range(n):
            acc = 0.0
            for mu in range(1, s1):
                acc += E[nu, mu] * C_prev[mu, a]
            C[nu, a] = acc - C_prev[s, a]
    for a in range(n):
        C[0, a] = 0.0


@kernel
def solve_stages(t0, h, qk, C, pk, prm, b, c, Phi, D, tol, maxiter, work):
    r"""Newton on the stage equations; C[1:] holds the guess on entry, the solution on exit.

    Full Newton with the exact Jacobian, assembled and factorised, until an
    increment is below ``FREEZE * (1 + |C|)``: the next one is then at
    round-off level, so the remaining iterations reuse the last LU factors and
    evaluate only the gradient. The stopping rule: increment zero, or no longer
    decreasing once below ``tol`` (:func:`newton_status`).

    Returns (status, iterations, last increment, last residual max-norm).
    """
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    s1, n = C.shape
    s = s1 - 1
    previous = np.inf
    residual = np.inf
    frozen = False
    # increments are judged against the size of q = q_k + C: far from the origin the
    # round-off floor of C is that of q
    base = 0.0
    for a in range(n):
        base = max(base, abs(qk[a]))
    for it in range(1, maxiter + 1):
        if frozen:
            assemble_gradient(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        else:
            assemble_newton(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K)
        residual = 0.0
        for nu in range(s):
            for a in range(n):
                val = G[nu, a] + (pk[a] if nu == 0 else 0.0)
                R[unknown(nu, a, s, n)] = -val
                if not abs(val) <= residual:  # also catches NaN
                    residual = abs(val)
        if not residual < 1e300:
            return STATUS_NONFINITE, it, np.inf, residual
        if not frozen and not factor_jacobian(K, piv, s):
            return STATUS_SINGULAR, it, np.inf, residual
        solve_jacobian(K, piv, s, R)
        increment = 0.0
        size = 0.0
        for nu in range(1, s1):
            for a in range(n):
                delta = R[unknown(nu - 1, a, s, n)]
                C[nu, a] += delta
                if abs(delta) > increment:
                    increment = abs(delta)
                if abs(C[nu, a]) > size:
                    size = abs(C[nu, a])
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
def make_work(s, n):
    """Preallocated work arrays of one step (allocated once per run)."""
    Q = np.zeros(n)
    V = np.zeros(n)
    Lq = np.zeros(n)
    Lv = np.zeros(n)
    Lqq = np.zeros(NNZ)
    Lqv = np.zeros(NNZ)
    Lvv = np.zeros(NNZ)
    G = np.zeros((s + 1, n))
    K = new_jacobian(s, n)
    R = np.zeros(s * n)
    piv = np.zeros(s * n, dtype=np.int64)
    Fv = np.zeros(NNZ if HAS_FV else 1)
    return (Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv)


@kernel
def new_jacobian(s, n):
    """Zero stage Jacobian: banded storage (3 kb + 1, s n) or dense (s n, s n)."""
    if BANDED:
        return np.zeros((3 * band_half_width(s) + 1, s * n))
    return np.zeros((s * n, s * n))


@kernel
def integrate_kernel(
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
    """Run ``n_steps`` steps of the position–momentum map from (q0, p0).

    ``iterations_out[j]`` receives the largest Newton iteration count of steps
    ``j*save_every .. (j+1)*save_every - 1`` (every step when save_every = 1) and
    ``iteration_total[0]`` their sum: a long run with ``save_every`` stores
    nothing per step.

    The new momentum is :math:`p_k` plus :func:`momentum_increment`, added
    with compensated summation like the positions. Saves rows at steps k with
    k % save_every == 0 and at the last step.
    Returns (status, steps completed, rows saved, max residual, failing increment).
    """
    n = q0.shape[0]
    out = (t_out, q_out, p_out, turns_out)
    s1 = d.shape[0]
    s = s1 - 1
    work = make_work(s, n)
    dp = np.zeros(n)  # the step's momentum change
    p_lost = np.zeros(n)  # compensated summation of the momenta
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)  # compensated summation: low-order bits of q lost so far
    turns = np.zeros(n)  # whole turns removed from periodic coordinates
    if HAS_PERIODIC:
        wrap_angles(qk, q_lost, turns)
    pk = p0.copy()
    first_guess(C, d, h, v0)
    saved = save_row(0, t0, qk, q_lost, turns, pk, out)
    worst = 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        status, its, increment, residual = solve_stages(
            tk, h, qk, C, pk, prm, b, c, Phi, D, tol, maxiter, work
        )
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK and not momentum_increment(
            tk, h, qk, C, prm, b, c, Phi, D, work[0], work[1], work[2], work[3], dp
        ):
            status = STATUS_NONFINITE
        if status != STATUS_OK:
            if k % save_every != 0:  # keep the last good state, even if not due for saving
                saved = save_row(saved, tk, qk, q_lost, turns, pk, out)
            return status, k, saved, worst, increment
        if residual > worst:
            worst = residual
        compensated_add(pk, p_lost, dp)
        advance_position(qk, q_lost, C, turns)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, out)
    return STATUS_OK, n_steps, saved, worst, 0.0


@kernel
def save_row(saved, t, qk, q_lost, turns, pk, out):
    r"""Store (t, q, p) in row ``saved`` of ``out = (t, q, p, turns)``; return the next row.

    With periodic coordinates the state is saved as it is kept, in
    :math:`[-\pi, \pi)` with its compensation ``q_lost`` applied, and the whole
    turns removed so far go to the fourth output (the caller adds them back:
    saving the continuous angle itself would round it to the precision of its
    size).
    """
    t_out, q_out, p_out, turns_out = out
    t_out[saved] = t
    for a in range(qk.shape[0]):
        if HAS_PERIODIC and PERIODIC[a]:
            q_out[saved, a] = qk[a] - q_lost[a]
            turns_out[saved, a] = turns[a]
        else:
            q_out[saved, a] = qk[a]
        p_out[saved, a] = pk[a]
    return saved + 1


@kernel
def verlet_kernel(q0, p0, t0, h, n_steps, save_every, prm, Minv, t_out, q_out, p_out, turns_out):
    r"""Degree 1, two Lobatto points, separable :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)`.

    The stage equation is linear in :math:`q_{k+1}` and solved in closed form
    (Störmer–Verlet), with :math:`M^{-1}` computed once:

    .. math::

        v = M^{-1}\big(p_k + \tfrac h2 L_q(t_k, q_k) - \bar a\big),\quad
        q_{k+1} = q_k + h v,\quad
        p_{k+1} = p_k + \tfrac h2 \big(L_q(t_k, q_k) + L_q(t_{k+1}, q_{k+1})\big),

    with :math:`\bar a = \tfrac12(a(t_k) + a(t_{k+1}))` and :math:`a(t) = L_v(t, q, 0)`.
    Returns (status, steps completed, rows saved).
    """
    n = q0.shape[0]
    out = (t_out, q_out, p_out, turns_out)
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if HAS_PERIODIC:
        wrap_angles(qk, q_lost, turns)
    pk = p0.copy()
    zero = np.zeros(n)
    lq = np.zeros(n)
    lq_next = np.zeros(n)
    a0 = np.zeros(n)
    a1 = np.zeros(n)
    rhs = np.zeros(n)
    # the state before the step, restored on failure: the last good state is saved
    q_before = np.zeros(n)
    p_before = np.zeros(n)
    lost_before = np.zeros(n)
    turns_before = np.zeros(n)
    saved = save_row(0, t0, qk, q_lost, turns, pk, out)
    point_gradient(t0, qk, zero, prm, lq, a0)
    point_gradient(t0, qk, zero, prm, lq_next, a1)
    for k in range(n_steps):
        tk = t0 + k * h
        tk1 = t0 + (k + 1) * h
        if not AUTONOMOUS:
            point_gradient(tk, qk, zero, prm, lq, a0)
            point_gradient(tk1, qk, zero, prm, lq_next, a1)
        for a in range(n):
            q_before[a] = qk[a]
            p_before[a] = pk[a]
            lost_before[a] = q_lost[a]
            turns_before[a] = turns[a]
            rhs[a] = pk[a] + 0.5 * h * lq[a] - 0.5 * (a0[a] + a1[a])
        for a in range(n):
            if DIAGONAL_MASS:  # point masses: n, not n^2, per step
                acc = Minv[a, a] * rhs[a]
            else:
                acc = 0.0
                for b in range(n):
                    acc += Minv[a, b] * rhs[b]
            if HAS_PERIODIC:
                # compensated, so that whole turns can be removed exactly
                y = h * acc - q_lost[a]
                total = qk[a] + y
                q_lost[a] = (total - qk[a]) - y
                qk[a] = total
            else:
                qk[a] += h * acc
        if HAS_PERIODIC:
            wrap_angles(qk, q_lost, turns)
        point_gradient(tk1, qk, zero, prm, lq_next, a1)
        finite = True
        for a in range(n):
            pk[a] += 0.5 * h * (lq[a] + lq_next[a])
            lq[a] = lq_next[a]
            if not abs(pk[a]) < 1e300 or not abs(qk[a]) < 1e300:
                finite = False
        if not finite:
            if k % save_every != 0:
                saved = save_row(saved, tk, q_before, lost_before, turns_before, p_before, out)
            return STATUS_NONFINITE, k, saved
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(saved, tk1, qk, q_lost, turns, pk, out)
    return STATUS_OK, n_steps, saved


@kernel
def linear_kernel(
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
    t_out,
    q_out,
    p_out,
    turns_out,
):
    """Quadratic L: the stage equations are linear with a constant matrix.

    The Jacobian K is assembled and LU-factorised once per run; each step is
    one residual evaluation at the extrapolated guess and one triangular solve,
    exact up to round-off, then :func:`momentum_increment` for the new
    momentum. Returns (status, steps completed, rows saved).
    """
    n = q0.shape[0]
    out = (t_out, q_out, p_out, turns_out)
    s1 = d.shape[0]
    s = s1 - 1
    work = make_work(s, n)
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    dp = np.zeros(n)
    p_lost = np.zeros(n)
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if HAS_PERIODIC:
        wrap_angles(qk, q_lost, turns)
    pk = p0.copy()
    first_guess(C, d, h, v0)
    assemble_newton(t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K)
    if not factor_jacobian(K, piv, s):
        return STATUS_SINGULAR, 0, save_row(0, t0, qk, q_lost, turns, pk, out)
    saved = save_row(0, t0, qk, q_lost, turns, pk, out)
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        assemble_gradient(tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        for nu in range(s):
            for a in range(n):
                R[unknown(nu, a, s, n)] = -(G[nu, a] + (pk[a] if nu == 0 else 0.0))
        solve_jacobian(K, piv, s, R)
        for nu in range(1, s1):
            for a in range(n):
                C[nu, a] += R[unknown(nu - 1, a, s, n)]
        finite = momentum_increment(tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, dp)
        for a in range(n):
            if not finite or not abs(C[s, a]) < 1e300:
                # keep the last good state (q_k, p_k), whether or not it was due for saving
                if k % save_every != 0:
                    saved = save_row(saved, tk, qk, q_lost, turns, pk, out)
                return STATUS_NONFINITE, k, saved
        compensated_add(pk, p_lost, dp)
        advance_position(qk, q_lost, C, turns)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, out)
    return STATUS_OK, n_steps, saved
