"""The linear loop: a Lagrangian quadratic in (q, v) has linear stage equations.

The stage Jacobian is constant: assembled and LU-factorised once per run; each
step is one residual at the extrapolated guess and one triangular solve, exact
up to round-off (notation of :mod:`.general`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .common import (
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR,
    advance_position,
    compensated_add,
    extrapolate,
    first_guess,
    save_row,
    wrap_angles,
)
from .general import assemble_gradient, assemble_newton, make_work, momentum_increment
from .linalg import factor_jacobian, solve_jacobian, unknown
from .on_demand import driver
from .traits import HAS_FV, HAS_LQV

__all__ = ["linear_loop"]


@driver
def linear_loop(
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
    d,
    Phi,
    D,
    E,
    t_out,
    q_out,
    p_out,
    turns_out,
    iterations_out,
    iteration_total,
):
    """Run ``n_steps`` steps of a quadratic Lagrangian; arguments as :func:`.general_loop`.

    Each step is one solve with the factors of the constant Jacobian: one
    iteration in ``iterations_out`` and ``iteration_total``. Returns the 5-tuple
    of :mod:`.abi` (largest residual 0.0, failing increment NaN: nothing iterates).
    """
    n = q0.shape[0]
    banded = pattern is not None
    # the Jacobian is assembled once: the couplings are run-time flags here, not variants
    couplings = (traits[HAS_LQV] != 0, traits[HAS_FV] != 0)
    s1 = d.shape[0]
    s = s1 - 1
    work = make_work(s, n, traits, pattern)
    Q, V, Lq, Lv, Lqq, Lqv, Lvv, G, K, R, piv, Fv = work
    dp = np.zeros(n)
    p_lost = np.zeros(n)
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    first_guess(C, d, h, v0)
    assemble_newton(
        fn, t0, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, Lqq, Lqv, Lvv, Fv, G, K, traits, pattern,
        couplings,
    )  # fmt: skip
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    if not factor_jacobian(K, piv, s, traits, pattern):
        return STATUS_SINGULAR, 0, saved, 0.0, np.nan
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        assemble_gradient(fn, tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, G)
        for nu in range(s):
            for a in range(n):
                R[unknown(nu, a, s, n, banded)] = -(G[nu, a] + (pk[a] if nu == 0 else 0.0))
        solve_jacobian(K, piv, s, R, traits, pattern)
        for nu in range(1, s1):
            for a in range(n):
                C[nu, a] += R[unknown(nu - 1, a, s, n, banded)]
        finite = momentum_increment(fn, tk, h, qk, C, prm, b, c, Phi, D, Q, V, Lq, Lv, dp)
        for a in range(n):
            if not finite or not abs(C[s, a]) < 1e300:
                # keep the last good state (q_k, p_k), whether or not it was due for saving
                if k % save_every != 0:
                    saved = save_row(
                        saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                    )
                return STATUS_NONFINITE, k, saved, 0.0, np.nan
        iterations_out[k // save_every] = 1
        iteration_total[0] += 1
        compensated_add(pk, p_lost, dp)
        advance_position(qk, q_lost, C, turns, periodic)
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
    return STATUS_OK, n_steps, saved, 0.0, np.nan
