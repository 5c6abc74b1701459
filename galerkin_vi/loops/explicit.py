r"""The explicit loop: symmetric compositions of Störmer–Verlet and splittings
(:mod:`galerkin_vi.method.composition`); Störmer–Verlet, the degree-1 two-point
Lobatto method, is the one-stage composition.

For a separable :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)` a sub-step with
drift :math:`a_i` and kicks :math:`\beta^\pm_i` (:class:`~galerkin_vi.method.composition.SubSteps`)
from :math:`\tau_{i-1}` to :math:`\tau_i = t_k + c_i h` (:math:`c_i = \sum_{j \le i} a_j`)
is solved in closed form, with :math:`M^{-1}` computed once:

.. math::

    v = M^{-1}\big(p + \beta^-_i h\,L_q(\tau_{i-1}, q) - \bar a\big),\quad
    q' = q + a_i h\,v,\quad
    p' = p + h\big(\beta^-_i L_q(\tau_{i-1}, q) + \beta^+_i L_q(\tau_i, q')\big),

with :math:`\bar a = \tfrac12(a(\tau_{i-1}) + a(\tau_i))` and :math:`a(t) = L_v(t, q, 0)`;
a Störmer–Verlet sub-step of length :math:`\eta = \gamma_i h` has
:math:`a_i = \gamma_i`, :math:`\beta^\pm_i = \gamma_i/2`. The force at the end of
sub-step i is the force at the start of sub-step i + 1 (first same as last): one
gradient call per sub-step.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .common import STATUS_NONFINITE, STATUS_OK, save_row, wrap_angles
from .on_demand import driver
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
    drift,
    kick_before,
    kick_after,
    nodes,
    t_out,
    q_out,
    p_out,
    turns_out,
):
    r"""Run ``n_steps`` steps of a composition or splitting from (q0, p0).

    ``drift``, ``kick_before`` and ``kick_after`` hold the sub-steps' fractions
    :math:`a_i`, :math:`\beta^-_i`, :math:`\beta^+_i` of the step, ``nodes`` their
    ends :math:`c_i = \sum_{j\le i} a_j` (``nodes[-1] = 1`` exactly, so that the
    step ends on :math:`t_0 + (k + 1)h`); Störmer–Verlet is ``drift = nodes = [1.0]``,
    ``kick_before = kick_after = [0.5]``. ``Minv`` is :math:`M^{-1}`; ``Minv_diagonal`` its
    diagonal when :math:`M` is diagonal (point masses: n, not :math:`n^2`, per
    sub-step), else ``None`` (a separate compiled variant, so that the dense
    product is not even in the diagonal one). ``periodic`` (the angles' mask, or
    ``None``) and ``time_dependent`` (``True``, or ``None`` for an autonomous
    system) are switches of the same kind: a run-time test of either would be a
    large share of a step that makes one gradient call. Returns the 5-tuple of
    :mod:`.abi` (largest residual 0.0, failing increment NaN: nothing iterates).
    """
    n = q0.shape[0]
    m = drift.shape[0]
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
    half = np.zeros(n)  # (a0 + a1) / 2, the gyroscopic term at the drift
    rhs = np.zeros(n)
    # the state before the step, restored on failure: the last good state is saved
    q_before = np.zeros(n)
    p_before = np.zeros(n)
    lost_before = np.zeros(n)
    turns_before = np.zeros(n)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    point_gradient(fn, t0, qk, zero, prm, lq, a0)
    point_gradient(fn, t0, qk, zero, prm, lq_next, a1)
    for a in range(n):
        half[a] = 0.5 * (a0[a] + a1[a])
    for k in range(n_steps):
        tk = t0 + k * h
        tk1 = t0 + (k + 1) * h
        for a in range(n):
            q_before[a] = qk[a]
            p_before[a] = pk[a]
        if periodic is not None:
            for a in range(n):
                lost_before[a] = q_lost[a]
                turns_before[a] = turns[a]
        for i in range(m):
            eta = drift[i] * h
            before = kick_before[i] * h
            after = kick_after[i] * h
            tau = t0 + (k + nodes[i]) * h
            if time_dependent is not None:
                # a(tau_i) before the drift; L_q(tau_{i-1}, q) is the last sub-step's
                point_gradient(fn, tau, qk, zero, prm, lq_next, a1)
                for a in range(n):
                    half[a] = 0.5 * (a0[a] + a1[a])
            # q += eta M^{-1} (p + before L_q - a), written out here in one pass per
            # sub-step: an inlined helper taking these arrays costs an atomic reference
            # count increment and decrement per array and call, and a pass that also
            # tests or copies does not vectorise
            if Minv_diagonal is None:
                for a in range(n):
                    rhs[a] = pk[a] + before * lq[a] - half[a]
            for a in range(n):
                if Minv_diagonal is None:
                    acc = 0.0
                    for b in range(n):
                        acc += Minv[a, b] * rhs[b]
                else:
                    acc = Minv_diagonal[a] * (pk[a] + before * lq[a] - half[a])
                if periodic is None:
                    qk[a] += eta * acc
                else:
                    # compensated, so that whole turns can be removed exactly
                    y = eta * acc - q_lost[a]
                    total = qk[a] + y
                    q_lost[a] = (total - qk[a]) - y
                    qk[a] = total
            if periodic is not None and i == m - 1:
                # once per step, before the last force: the inner sub-steps' angles stay
                # within a step's travel of [-pi, pi) (accurate forces still), and a wrap
                # at every sub-step doubles the cost of a one-stage step
                wrap_angles(qk, q_lost, turns, periodic)
            point_gradient(fn, tau, qk, zero, prm, lq_next, a1)
            for a in range(n):
                pk[a] += before * lq[a] + after * lq_next[a]
            # the force at this sub-step's end starts the next one
            lq, lq_next = lq_next, lq
            if time_dependent is not None:
                for a in range(n):
                    a0[a] = a1[a]  # autonomous: a is constant
        # an inf or NaN of any sub-step stays in the sums (and the wrap) to the step's
        # end: one test of the end state per step finds the step that overflowed (a
        # value past 1e300 that a later sub-step brings back is not a failure)
        finite = True
        for a in range(n):
            if not (abs(pk[a]) < 1e300 and abs(qk[a]) < 1e300):
                finite = False
                break
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
