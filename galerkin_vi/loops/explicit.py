r"""The explicit loop: Störmer–Verlet, the degree-1 two-point Lobatto method.

For a separable :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)` the stage
equation is linear in :math:`q_{k+1}` and solved in closed form, with
:math:`M^{-1}` computed once:

.. math::

    v = M^{-1}\big(p_k + \tfrac h2 L_q(t_k, q_k) - \bar a\big),\quad
    q_{k+1} = q_k + h v,\quad
    p_{k+1} = p_k + \tfrac h2 \big(L_q(t_k, q_k) + L_q(t_{k+1}, q_{k+1})\big),

with :math:`\bar a = \tfrac12(a(t_k) + a(t_{k+1}))` and :math:`a(t) = L_v(t, q, 0)`.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import driver
from .common import STATUS_NONFINITE, STATUS_OK, save_row, wrap_angles
from .point import point_gradient

__all__ = ["explicit_loop"]


@driver
def explicit_loop(
    fn,
    periodic,
    time_dependent,
    q0,
    p0,
    t0,
    h,
    n_steps,
    save_every,
    prm,
    Minv,
    Minv_diagonal,
    t_out,
    q_out,
    p_out,
    turns_out,
):
    r"""Run ``n_steps`` Störmer–Verlet steps from (q0, p0).

    ``Minv`` is :math:`M^{-1}`; ``Minv_diagonal`` its diagonal when :math:`M`
    is diagonal (point masses: n, not :math:`n^2`, per step), else ``None``
    (a separate compiled variant, so that the dense product is not even in the
    diagonal one). ``periodic`` (the angles' mask, or ``None``) and
    ``time_dependent`` (``True``, or ``None`` for an autonomous system) are
    switches of the same kind: a run-time test of either would be a large
    share of a step that makes one gradient call. Returns the 5-tuple of
    :mod:`.abi` (largest residual 0.0, failing increment NaN: nothing iterates).
    """
    n = q0.shape[0]
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
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
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    point_gradient(fn, t0, qk, zero, prm, lq, a0)
    point_gradient(fn, t0, qk, zero, prm, lq_next, a1)
    for k in range(n_steps):
        tk = t0 + k * h
        tk1 = t0 + (k + 1) * h
        if time_dependent is not None:
            point_gradient(fn, tk, qk, zero, prm, lq, a0)
            point_gradient(fn, tk1, qk, zero, prm, lq_next, a1)
        for a in range(n):
            q_before[a] = qk[a]
            p_before[a] = pk[a]
            lost_before[a] = q_lost[a]
            turns_before[a] = turns[a]
            rhs[a] = pk[a] + 0.5 * h * lq[a] - 0.5 * (a0[a] + a1[a])
        # q += h M^{-1} rhs, written out here: an inlined helper taking these arrays
        # costs an atomic reference count increment and decrement per array and call,
        # a large share of a step this short
        for a in range(n):
            if Minv_diagonal is None:
                acc = 0.0
                for b in range(n):
                    acc += Minv[a, b] * rhs[b]
            else:
                acc = Minv_diagonal[a] * rhs[a]
            if periodic is None:
                qk[a] += h * acc
            else:
                # compensated, so that whole turns can be removed exactly
                y = h * acc - q_lost[a]
                total = qk[a] + y
                q_lost[a] = (total - qk[a]) - y
                qk[a] = total
        if periodic is not None:
            wrap_angles(qk, q_lost, turns, periodic)
        point_gradient(fn, tk1, qk, zero, prm, lq_next, a1)
        finite = True
        for a in range(n):
            pk[a] += 0.5 * h * (lq[a] + lq_next[a])
            lq[a] = lq_next[a]
            if not abs(pk[a]) < 1e300 or not abs(qk[a]) < 1e300:
                finite = False
        if not finite:
            if k % save_every != 0:
                saved = save_row(
                    saved, tk, q_before, lost_before, turns_before, p_before, t_out, q_out,
                    p_out, turns_out, periodic,
                )  # fmt: skip
            return STATUS_NONFINITE, k, saved, 0.0, np.nan
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            saved = save_row(
                saved, tk1, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
            )
    return STATUS_OK, n_steps, saved, 0.0, np.nan
