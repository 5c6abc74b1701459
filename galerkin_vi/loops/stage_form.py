r"""The compiled time loop of the stage form, for separable Lagrangians.

For a system with :math:`L = \tfrac12 v^TMv + a(t)\cdot v + U(t, q)`, constant
:math:`M` and forces independent of :math:`v`. The tables are those of
:mod:`galerkin_vi.method.stage_form`: with :math:`F_j = (L_q + f)(t_k + c_j h, q_k + Z_j)`,
the unknowns are the increments :math:`Z_i` at the implicit points,

.. math::

    R_i = M Z_i - h\,\hat c_i\, p_k - h \sum_j \hat Y_{ij} a_j
          - h^2 \sum_j \hat W_{ij} F_j = 0,
    \qquad \frac{\partial R_i}{\partial Z_j} = \delta_{ij} M - h^2 \hat W_{ij} (L_{qq} + f_q)_j,

after which :math:`M C^\mu` follows from the same relation, :math:`q_{k+1} =
q_k + C^s` and :math:`p_{k+1} = p_k + h\sum_j b_j F_j`, both added with
compensated summation.
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
    advance_position,
    compensated_add,
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
from .traits import AUTONOMOUS

__all__ = ["stage_form_loop", "too_slow"]

# constant-mass iteration: switch to full Newton when an increment is more than
# MASS_CONTRACTION * (number of unknowns) times the one before, capped at
# MASS_CONTRACTION_MAX: a full Newton step costs relatively more with more unknowns,
# so the break-even contraction grows with them, and on large chains slow sweeps still
# beat Newton iterations (docs/design-notes.md)
MASS_CONTRACTION = 0.01
MASS_CONTRACTION_MAX = 0.9
# ... or when, at its contraction, it would not reach the tolerance within the
# iterations left but this many, which full Newton keeps for itself
NEWTON_RESERVE = 6
# contractions this fast need FAST_SWEEPS_LEFT sweeps at most from |dZ| ~ |q| to 1e-16
FAST_SWEEP = 0.05
FAST_SWEEPS_LEFT = 13
# after a switch, steps that start with full Newton before the cheap iteration is retried
MASS_RETRY = 64
# sums over the stages, sum_j w_j T[j, a] for all a: from this many coordinates on as
# whole-row updates (for j: for a: x[a] += w_j T[j, a], long independent inner loops),
# below as one dot product per coordinate (fewer loop set-ups): the row updates win on
# long rows, the dot products on short ones (docs/design-notes.md). The order of the
# additions is the same.
WIDE = 4


@kernel
def too_slow(increment, previous, its, contraction, budget, target):
    r"""Whether the constant-mass iteration should hand over to full Newton.

    After sweep ``its`` (1-based) with max-norm increments ``increment`` and
    ``previous``: true when it contracts by less than ``contraction``,
    :math:`\theta = |\delta_k| / |\delta_{k-1}| > \theta_{\max}`, or when at
    that rate it would not reach ``target`` within ``budget`` sweeps,
    :math:`k + \log(\text{target} / |\delta_k|) / \log\theta > \text{budget}`.
    Never after the first sweep (no rate yet) or once the increment is at the target.
    """
    if its < 2 or increment <= target:
        return False
    # the rate's tests as products, which answer as the division did for a previous
    # increment of 0 too (a rate of inf); the division is left to the prediction, which
    # fast contractions never reach
    if increment > contraction * previous:
        return True
    if increment <= 0.0:
        return False
    if increment <= FAST_SWEEP * previous and its + FAST_SWEEPS_LEFT <= budget:
        # at this rate a sweep gains 1.3 digits or more, and this many sweeps reach the
        # tolerance from an increment the size of q: no prediction needed (its two
        # logarithms per sweep would be a large share of a small system's step)
        return False
    theta = increment / previous
    return its + np.log(target / increment) / np.log(theta) > budget


@kernel
def mass_times(M, mass_diagonal, x, out, traits, pattern):
    """out = M x for the constant mass matrix stored flat (dense or pattern order).

    With a diagonal M (point masses, the common case) ``mass_diagonal`` is its
    diagonal, else ``None``: a separate compiled variant, so that the dense loop
    is not even compiled in (a run-time test here is a large share of a small step).
    """
    n = x.shape[0]
    if mass_diagonal is not None:
        for a in range(n):
            out[a] = mass_diagonal[a] * x[a]
    elif pattern is not None:
        for a in range(n):
            out[a] = 0.0
        for k in range(pattern.shape[0]):
            out[pattern[k, 0]] += M[k] * x[pattern[k, 1]]
    else:
        for a in range(n):
            acc = 0.0
            for cc in range(n):
                acc += M[a * n + cc] * x[cc]
            out[a] = acc


@kernel
def solve_mass(KM, pivM, mass_diagonal, inverse_mass, x, traits, pattern):
    """x <- M^{-1} x with the factors of :func:`stage_form_loop`'s mass matrix.

    A diagonal M (``mass_diagonal`` not None) multiplies by ``inverse_mass``:
    u + 1 multiplications per coordinate and step instead of divisions.
    """
    if mass_diagonal is not None:
        for a in range(x.shape[0]):
            x[a] *= inverse_mass[a]
    else:
        solve_jacobian(KM, pivM, 1, x, traits, pattern)


@kernel
def diagonal_of(M, n, traits, pattern, diagonal):
    """Write the diagonal of the flat-stored M (dense ``a n + a``, or the pattern's) into
    ``diagonal``."""
    if pattern is not None:
        for k in range(pattern.shape[0]):
            if pattern[k, 0] == pattern[k, 1]:
                diagonal[pattern[k, 0]] = M[k]
    else:
        for a in range(n):
            diagonal[a] = M[a * n + a]


@driver
def stage_form_loop(
    fn,
    traits,
    pattern,
    periodic,
    mass_diagonal,
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
    implicit,
    known,
    rest,
    stage_p,
    stage_a,
    stage_force,
    control_p,
    control_a,
    control_force,
    Phi1,
    X,
    reuse_endpoint,
    tol,
    maxiter,
    cheap_first,
    t_out,
    q_out,
    p_out,
    turns_out,
    iterations_out,
    iteration_total,
):
    r"""Run ``n_steps`` steps of the stage form from (q0, p0); as :func:`.general_loop`.

    ``mass_diagonal``: work space of length n when the constant mass matrix is
    diagonal (it receives the diagonal), else ``None``. ``cheap_first``: start
    each step with the constant-mass iteration. ``X``: the forces of one step
    extrapolated to the next step's implicit points
    (``SeparableTables.force_extrapolation``), from which each step after the
    first takes its first iterate: from the last step (shape (u, r)), or with a
    table of shape (u, 3 r) from the last two after the second step. Returns
    (status, steps completed, rows saved, max residual, failing increment).

    **The iteration.** Unknowns are the stage increments :math:`Z_i` at the
    implicit points. Three iterations share one stopping rule: with ``cheap``
    the iteration matrix is the block-diagonal :math:`I \otimes M` (fixed-point
    iteration on :math:`M Z = \text{offset} + h^2 \hat W F(Z)`: one gradient per
    implicit point and one solve with the constant :math:`M`, a division when it
    is diagonal), handing over to full Newton when it contracts by less than
    ``min(MASS_CONTRACTION_MAX, MASS_CONTRACTION u n)`` per sweep (a Newton
    iteration costs more sweeps the more unknowns there are), when at its
    contraction :math:`\theta` it would need more than the sweeps left,
    :math:`\log(\text{tol}\cdot\text{scale}/|\delta Z|)/\log\theta`
    against ``maxiter - NEWTON_RESERVE``, or when it fails; full Newton; and the LU factors
    frozen once an increment is below ``FREEZE``. The iteration ends when an
    update leaves every stage position :math:`q_k + Z_i` bit-identical: the
    forces, and with them everything the step computes, are then a fixed point
    in floating point, and the forces of that sweep are reused for the step.
    Otherwise :func:`.newton_status` decides (an increment that stops decreasing
    below the tolerance: round-off).

    **Why one flat loop.** Every array bound to a new name inside an inlined
    helper costs numba an atomic reference-count increment and decrement
    wherever its pruning pass cannot pair them: helpers with several exits, of
    several loop nests (the LU solve, the block assembly), or called with a
    conditional expression among their arguments. As separate helpers, the
    solve and the end of the step would cost 25 of each per step, a large share
    of a small system's step. Here the work arrays are bound once, before the first
    step, and the helpers left in the loop have one loop nest each: the
    optimised code has no reference count inside the step loop (counted in
    the LLVM IR of the compiled loop).
    """
    n = q0.shape[0]
    r = b.shape[0]
    s = control_p.shape[0]
    u = implicit.shape[0]
    autonomous = traits[AUTONOMOUS] != 0
    wide = n >= WIDE
    banded = pattern is not None
    nnz = block_size(n, pattern)
    Q = np.zeros(n)
    zero = np.zeros(n)
    Lq = np.zeros(n)
    Lv = np.zeros(n)
    Lqq = np.zeros(nnz)
    Lqv = np.zeros(nnz)
    Lvv = np.zeros(nnz)
    Fv = np.zeros(1)
    F = np.zeros((r, n))  # L_q + f at the quadrature points
    # ... at the implicit points, the iteration's own table: its sweeps read it row by row
    # without an index table, and the gradient writes it in place
    FI = np.zeros((u, n))
    A = np.zeros((r, n))  # a(t) = L_v(t, q, 0) at the quadrature points
    K = new_jacobian(u, n, traits, pattern)
    R = np.zeros(u * n)
    piv = np.zeros(u * n, dtype=np.int64)
    x = np.zeros(n)
    mz = np.zeros(n)
    Z = np.zeros((u, n))
    C = np.zeros((s, n))
    offset = np.zeros((u, n))
    F_next = np.zeros((u, n))  # the forces extrapolated to the next step's implicit points
    F_last = np.zeros((r, n))  # the last step's forces, for a two-step extrapolation
    two_step_start = X.shape[1] == 3 * r and u > 0
    stage_gauge = np.zeros((u, n))
    control_gauge = np.zeros((s, n))
    # the constant mass matrix, factorised once as a one-stage "Jacobian" (a diagonal
    # M is only divided by: no n x n storage, no LU)
    point_hessian(fn, t0, q0, zero, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
    M = Lvv.copy()
    KM = new_jacobian(1, 0 if mass_diagonal is not None else n, traits, pattern)
    pivM = np.zeros(0 if mass_diagonal is not None else n, dtype=np.int64)
    dp = np.zeros(n)  # the step's momentum change
    qk = q0.copy()
    q_lost = np.zeros(n)
    p_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    inverse_mass = np.zeros(n)
    if mass_diagonal is not None:
        diagonal_of(M, n, traits, pattern, mass_diagonal)
        regular = np.all(mass_diagonal != 0.0)
        for a in range(n):
            inverse_mass[a] = 1.0 / mass_diagonal[a]
    else:
        add_block(KM, 0, 1, 1, n, 1.0, M, 0.0, Lqq, 0.0, 0.0, Lqv, Fv, traits, pattern, None)
        regular = factor_jacobian(KM, pivM, 1, traits, pattern)
    if not regular:
        return STATUS_SINGULAR, 0, saved, 0.0, np.inf
    for il in range(u):
        for a in range(n):
            Z[il, a] = c[implicit[il]] * h * v0[a]
    h2 = h * h
    # the control points the step needs: C^s (q_{k+1}) and those that place the
    # explicit points (Gauss: C^s only)
    needed = np.zeros(s, dtype=np.bool_)
    needed[s - 1] = True
    for jr in range(rest.shape[0]):
        for mu in range(s):
            if Phi1[rest[jr], mu] != 0.0:
                needed[mu] = True
    W2 = np.zeros((u, u))  # h^2 W between the implicit points
    for il in range(u):
        for jl in range(u):
            W2[il, jl] = h2 * stage_force[il, implicit[jl]]
    contraction = min(MASS_CONTRACTION_MAX, MASS_CONTRACTION * u * n)
    budget = max(maxiter // 2, maxiter - NEWTON_RESERVE)  # sweeps of the cheap iteration
    worst = 0.0
    retry_in = 0
    have_start_force = False
    for k in range(n_steps):
        tk = t0 + k * h
        if k == 0 or not autonomous:
            for j in range(r):
                point_gradient(fn, 0.0 if autonomous else tk + c[j] * h, qk, zero, prm, Lq, Lv)
                for a in range(n):
                    A[j, a] = Lv[a]
        if not (autonomous and reuse_endpoint and have_start_force):
            for jk in range(known.shape[0]):
                j = known[jk]
                point_gradient(fn, 0.0 if autonomous else tk + c[j] * h, qk, zero, prm, Lq, Lv)
                for a in range(n):
                    F[j, a] = Lq[a]
        if k == 0 or not autonomous:
            # h sum_j Y_ij a_j (stages) and h sum_j Y_mu,j a_j (control points): with t
            # absent, a is constant and so are these
            for il in range(u):
                for a in range(n):
                    acc = 0.0
                    for j in range(r):
                        acc += stage_a[il, j] * A[j, a]
                    stage_gauge[il, a] = h * acc
            for mu in range(s):
                for a in range(n):
                    acc = 0.0
                    for j in range(r):
                        acc += control_a[mu, j] * A[j, a]
                    control_gauge[mu, a] = h * acc
        for il in range(u):
            for a in range(n):
                acc = h * stage_p[il] * pk[a] + stage_gauge[il, a]
                for jk in range(known.shape[0]):
                    acc += h2 * stage_force[il, known[jk]] * F[known[jk], a]
                offset[il, a] = acc
        if k > 0:
            # first iterate: Z_i = M^-1 (offset_i + h^2 sum_j W_ij F~_j), the stage
            # equations with the extrapolated forces F~
            for il in range(u):
                if wide:
                    for a in range(n):
                        x[a] = offset[il, a]
                    for jl in range(u):
                        w = W2[il, jl]
                        for a in range(n):
                            x[a] += w * F_next[jl, a]
                else:
                    for a in range(n):
                        acc = offset[il, a]
                        for jl in range(u):
                            acc += W2[il, jl] * F_next[jl, a]
                        x[a] = acc
                solve_mass(KM, pivM, mass_diagonal, inverse_mass, x, traits, pattern)
                for a in range(n):
                    Z[il, a] = x[a]
        # ---- the stage equations (see the docstring)
        cheap = cheap_first and retry_in == 0
        status = STATUS_OK
        its = 0
        increment = 0.0
        residual = 0.0
        switched = False
        current = False
        if u > 0:
            status = STATUS_NEWTON_FAILED
            previous = np.inf
            frozen = False
            base = 0.0
            for a in range(n):
                base = max(base, abs(qk[a]))
            # the size of the stage increments, for the tolerance's scale: that of the
            # first iterate (the diagonal fixed point does not track it per sweep)
            step_size = 0.0
            for il in range(u):
                for a in range(n):
                    step_size = max(step_size, abs(Z[il, a]))
            while its < maxiter:
                its += 1
                full = not (cheap or frozen)
                if full:
                    K[:, :] = 0.0
                for jl in range(u):
                    j = implicit[jl]
                    for a in range(n):
                        Q[a] = qk[a] + Z[jl, a]
                    tj = 0.0 if autonomous else tk + c[j] * h
                    if full:
                        point_hessian(fn, tj, Q, zero, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
                        for a in range(n):
                            FI[jl, a] = Lq[a]
                        for il in range(u):
                            # a conditional expression among the arguments would split
                            # the call over blocks, leaving reference counts in the loop
                            mass_weight = 1.0 if il == jl else 0.0
                            add_block(
                                K, il, jl + 1, u, n, mass_weight, M,
                                -h2 * stage_force[il, j], Lqq, 0.0, 0.0, Lqv, Fv, traits,
                                pattern, None,
                            )  # fmt: skip
                    else:
                        point_gradient_row(fn, tj, Q, zero, prm, FI, Lv, jl)
                residual = 0.0
                increment = 0.0
                size = step_size
                moved = False
                if cheap and mass_diagonal is not None:
                    # fixed point with a diagonal M, in one pass:
                    # Z_i <- (offset_i + h^2 sum_j W_ij F_j) / m (times 1/m: a division
                    # per entry would cost more than the rest of the entry). Its residual at the old
                    # iterate is m |dZ|; the stage positions moved iff the sum of their
                    # changes is not zero, a sum that NaN and inf reach too. (Two maxima
                    # and a sum per entry, no more bookkeeping: the sweep runs at the speed
                    # of a hand-written fixed-point kernel's.)
                    shift = 0.0
                    for il in range(u):
                        if wide:
                            for a in range(n):
                                x[a] = offset[il, a]
                            for jl in range(u):
                                w = W2[il, jl]
                                for a in range(n):
                                    x[a] += w * FI[jl, a]
                        for a in range(n):
                            # narrow: the dot product in this loop, not in a loop of its
                            # own ahead of it (one loop set-up less per stage and sweep; the
                            # control point and dp are formed alike)
                            if wide:
                                acc = x[a]
                            else:
                                acc = offset[il, a]
                                for jl in range(u):
                                    acc += W2[il, jl] * FI[jl, a]
                            old = Z[il, a]
                            updated = acc * inverse_mass[a]
                            dz = abs(updated - old)
                            if dz > increment:
                                increment = dz
                            if mass_diagonal[a] * dz > residual:
                                residual = mass_diagonal[a] * dz
                            shift += abs((qk[a] + updated) - (qk[a] + old))
                            Z[il, a] = updated
                    if not shift < 1e300:
                        status = STATUS_NONFINITE
                        increment = np.inf
                        break
                    moved = shift != 0.0
                else:
                    for il in range(u):
                        for a in range(n):
                            x[a] = Z[il, a]
                        mass_times(M, mass_diagonal, x, mz, traits, pattern)
                        for a in range(n):
                            acc = offset[il, a]
                            for jl in range(u):
                                acc += W2[il, jl] * FI[jl, a]
                            val = mz[a] - acc
                            R[unknown(il, a, u, n, banded)] = -val
                            if not abs(val) <= residual:  # also catches NaN
                                residual = abs(val)
                    if not residual < 1e300:
                        status = STATUS_NONFINITE
                        increment = np.inf
                        break
                    if cheap:
                        for il in range(u):
                            for a in range(n):
                                x[a] = R[unknown(il, a, u, n, banded)]
                            solve_mass(KM, pivM, mass_diagonal, inverse_mass, x, traits, pattern)
                            for a in range(n):
                                R[unknown(il, a, u, n, banded)] = x[a]
                    else:
                        if full and not factor_jacobian(K, piv, u, traits, pattern):
                            status = STATUS_SINGULAR
                            increment = np.inf
                            break
                        solve_jacobian(K, piv, u, R, traits, pattern)
                    for il in range(u):
                        for a in range(n):
                            delta = R[unknown(il, a, u, n, banded)]
                            updated = Z[il, a] + delta
                            if qk[a] + updated != qk[a] + Z[il, a]:
                                moved = True
                            Z[il, a] = updated
                            if abs(delta) > increment:
                                increment = abs(delta)
                            if abs(Z[il, a]) > size:
                                size = abs(Z[il, a])
                if not moved:
                    # every stage position q_k + Z_i is bit-identical: the forces, and so
                    # Z and the step, are a fixed point in floating point; the forces of
                    # this sweep are those at Z unless the Hessian's CSE gave them
                    status = STATUS_OK
                    current = not full
                    break
                scale = 1.0 + max(size, base)
                if cheap and too_slow(increment, previous, its, contraction, budget, tol * scale):
                    # too slow at this h (or diverging): exact Jacobian from here on
                    cheap = False
                    switched = True
                    previous = np.inf
                    continue
                decision = newton_status(increment, previous, scale, tol, its, maxiter)
                if decision == CONVERGED:
                    status = STATUS_OK
                    break
                if cheap and (decision != CONTINUE or its >= budget):
                    # the cheap iteration leaves full Newton NEWTON_RESERVE iterations
                    cheap = False
                    switched = True
                    previous = np.inf
                    continue
                if decision != CONTINUE:
                    break
                if not cheap and increment <= FREEZE * (1.0 + size):
                    frozen = True
                previous = increment
        if switched:
            retry_in = MASS_RETRY
        elif retry_in > 0:
            retry_in -= 1
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = its
        iteration_total[0] += its
        if status == STATUS_OK:
            # ---- the end of the step: forces at the solution (unless the last sweep
            # gave them), M C^mu = h c_mu p_k + h sum_j Y_mu,j a_j + h^2 sum_j W_mu,j F_j,
            # then the forces at the points that are explicit once C is known
            for jl in range(0 if current else u):
                j = implicit[jl]
                for a in range(n):
                    Q[a] = qk[a] + Z[jl, a]
                tj = 0.0 if autonomous else tk + c[j] * h
                point_gradient_row(fn, tj, Q, zero, prm, FI, Lv, jl)
            for jl in range(u):
                for a in range(n):
                    F[implicit[jl], a] = FI[jl, a]
            for mu in range(s):
                if not needed[mu]:
                    continue
                if wide:
                    for a in range(n):
                        x[a] = 0.0
                    for j in range(r):
                        w = control_force[mu, j]
                        for a in range(n):
                            x[a] += w * F[j, a]
                for a in range(n):
                    if wide:
                        acc = x[a]
                    else:
                        acc = 0.0
                        for j in range(r):
                            acc += control_force[mu, j] * F[j, a]
                    x[a] = h * control_p[mu] * pk[a] + control_gauge[mu, a] + h2 * acc
                solve_mass(KM, pivM, mass_diagonal, inverse_mass, x, traits, pattern)
                for a in range(n):
                    C[mu, a] = x[a]
            for jr in range(rest.shape[0]):
                j = rest[jr]
                for a in range(n):
                    acc = 0.0
                    for mu in range(s):
                        acc += Phi1[j, mu] * C[mu, a]
                    Q[a] = qk[a] + acc
                point_gradient(fn, 0.0 if autonomous else tk + c[j] * h, Q, zero, prm, Lq, Lv)
                for a in range(n):
                    F[j, a] = Lq[a]
            # p_{k+1} = p_k + h sum_j b_j F_j (added below, compensated like q); a
            # force that is not finite makes dp not finite
            if wide:
                for a in range(n):
                    dp[a] = 0.0
                for j in range(r):
                    w = b[j]
                    for a in range(n):
                        dp[a] += w * F[j, a]
            for a in range(n):
                if wide:
                    dp[a] *= h
                else:
                    acc = 0.0
                    for j in range(r):
                        acc += b[j] * F[j, a]
                    dp[a] = h * acc
                if not (abs(C[s - 1, a]) < 1e300 and abs(dp[a]) < 1e300):
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
        # the next step's forces extrapolated (SeparableTables.force_extrapolation): from
        # this step's, or, with a two-step table after the first step, from this step's
        # and the last step's (older first) when the next step starts with the cheap
        # iteration; a step after a hand-over starts Newton from the one-step forces,
        # whose roots past a singularity are fewer (tests/test_integrator.py, blow-up)
        two = two_step_start and k > 0 and cheap_first and retry_in == 0
        newer = 2 * r if two else 0
        for il in range(u):
            if wide:
                for a in range(n):
                    F_next[il, a] = 0.0
                if two:
                    for j in range(r):
                        w = X[il, r + j]
                        for a in range(n):
                            F_next[il, a] += w * F_last[j, a]
                for j in range(r):
                    w = X[il, newer + j]
                    for a in range(n):
                        F_next[il, a] += w * F[j, a]
            else:
                for a in range(n):
                    acc = 0.0
                    if two:
                        for j in range(r):
                            acc += X[il, r + j] * F_last[j, a]
                    for j in range(r):
                        acc += X[il, newer + j] * F[j, a]
                    F_next[il, a] = acc
        if two_step_start:
            for j in range(r):
                for a in range(n):
                    F_last[j, a] = F[j, a]
        if reuse_endpoint:
            for a in range(n):
                F[0, a] = F[r - 1, a]
            have_start_force = True
        # adds C[s - 1], the last row: C^s
        advance_position(qk, q_lost, C, turns, periodic)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
    return STATUS_OK, n_steps, saved, worst, 0.0
