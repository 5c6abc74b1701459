r"""The time-stepping part of a contact run, compiled: step after step with no Python.

Each step is what :meth:`galerkin_vi.contact.runs._Run.time_steps` takes from Python
(:mod:`galerkin_vi.contact.runs` explains the run): the first guess from the
velocity (:func:`.contact_velocity.inverse_legendre`), the interior-point step
(:func:`.contact_step.interior_point_step`, again from the cones' centres when
the last forces do not start it), the constraint's momentum projection, and the
impact law at the velocity level for the contacts that pushed: Newton's law for
one still approaching at the step's end (frictionless, or sticking inside the
friction cone) and the stopped slip of one that stuck.

The loop hands the step back to Python (status :data:`HANDED_BACK`, the step not
taken) where the run needs more than that: a step whose iteration fails from both
starts (Python halves it), a contact open at the step's start that pushed (Python
cuts the step at its first touch), an impact that slides (Python's sliding law), a
velocity not found. With ``until_release`` it stops after two steps in a row
without contact force (:data:`RELEASED`), where the run goes back to isolated impacts.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ..interior_point import RESIDUAL
from ._jit import called, kernel
from .contact_step import interior_point_step
from .contact_velocity import (
    inverse_legendre,
    project_momentum,
    saddle_velocity,
    sliding_impulse,
)
from .on_demand import driver
from .point import point_constraint_jacobian, point_constraint_rate, point_contact, point_slip

__all__ = ["BROAD_PHASE_MARGIN", "FINISHED", "HANDED_BACK", "RELEASED", "contact_steps"]

#: every step asked for was taken
FINISHED = 0
#: two steps in a row without contact force (``until_release``)
RELEASED = 1
#: the next step is Python's (a failed iteration, a first touch, a sliding impact)
HANDED_BACK = 2
#: the broad phase keeps a contact apart whose gap exceeds this many times the distance
#: its normal velocity covers in the step (plus the coordinates' round-off)
BROAD_PHASE_MARGIN = 4.0


@kernel
def _handed_back(stats, k, free, total):
    """Step k is Python's: the statistics of the steps before it."""
    stats[0] = k
    stats[1] = HANDED_BACK
    stats[2] = free
    stats[3] = total
    return HANDED_BACK


@driver
def contact_steps(
    fn, t0, k0, h, n_steps, q, p, y, has_duals, b, c, Phi, D, d, prm, n, s, mh, normal, cone,
    cone_len, slip_row, mu, restitution, n_slip, quadratic, until_release, free,
    open_gap, released, broad_phase, q_out, p_out, normal_out, tangential_out, iterations_out,
    complementarity_out, stats,
):  # fmt: skip
    r"""Time-stepping steps from grid node ``k0`` (time :math:`t_0 + k_0 h`, state q, p),
    at most ``n_steps``, each from :math:`t_0 + k h` to :math:`t_0 + (k + 1) h`.

    ``q``, ``p`` and the duals ``y`` (used as the first step's start when ``has_duals``)
    are updated to the last step taken; row k of ``q_out``, ``p_out``, ``normal_out``,
    ``tangential_out`` (contacts, 2), ``iterations_out`` and ``complementarity_out``
    receive step k's end. ``free`` counts the steps without contact force before the
    first; ``open_gap`` and ``released`` are :data:`galerkin_vi.contact.runs.OPEN_GAP`
    and ``RELEASED_IMPULSE``. ``stats`` receives (steps taken, status, the count of
    free steps, interior-point iterations).
    """
    nc = normal.shape[0]
    m = y.shape[0]
    sn = s * n
    nx = sn + s * mh
    x = np.zeros(nx)
    y_try = np.zeros(m)
    z = np.zeros(m)
    p_end = np.zeros(n)
    q_end = np.zeros(n)
    v = np.zeros(n)
    zeros = np.zeros(n)
    step_stats = np.zeros(3)
    width = max(n, nc * n, n_slip * n, mh * n, 1)
    work = np.zeros((6, width))
    Lqq = np.zeros(n * n)
    Lqv = np.zeros(n * n)
    Lvv = np.zeros(n * n)
    Fv = np.zeros(n * n)
    cg = np.zeros(nc)
    cG = np.zeros(nc * n)
    cH = np.zeros(nc * n * n)
    w = np.zeros(max(n_slip, 1))
    Wq = np.zeros(max(n_slip, 1) * n)
    Wv = np.zeros(max(n_slip, 1) * n)
    Wvq = np.zeros(max(n_slip, 1) * n * n)
    Gq = np.zeros(max(mh, 1) * n)
    gt = np.zeros(max(mh, 1))
    rows = 1 + 2 + mh  # a gap's row, at most two slip rows, the constraints
    Dm = np.zeros((rows, n))
    targets = np.zeros(rows)
    lam = np.zeros(rows)
    K = np.zeros((n + rows, n + rows))
    piv = np.zeros(n + rows, dtype=np.int64)
    xs = np.zeros(n + rows)
    force = np.zeros(nc)
    total = 0
    # the contacts kept apart by the broad phase
    apart = np.zeros(nc, dtype=np.bool_)
    gap_start = np.zeros(nc)
    for k in range(n_steps):
        t = t0 + (k0 + k) * h
        t_next = t0 + (k0 + k + 1) * h
        tau = t_next - t
        # the first guess: a straight motion at the current velocity
        if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv,
                                K[:n, :n], piv[:n]):  # fmt: skip
            return _handed_back(stats, k, free, total)
        # broad phase: a contact whose gap cannot close within the step (its gap above
        # BROAD_PHASE_MARGIN times the distance its normal velocity covers, and above the
        # coordinates' round-off) is kept apart; if it ends the step closed, the step is
        # taken again with every contact
        scale = 1.0
        for a in range(n):
            scale = max(scale, abs(q[a]))
        point_contact(fn, t, q, zeros, prm, cg, cG, cH)
        for j in range(nc):
            gap_start[j] = cg[j]  # also for the first touch's test below
            rate = 0.0
            for a in range(n):
                rate += cG[j * n + a] * v[a]
            reach = BROAD_PHASE_MARGIN * (abs(rate) * tau + open_gap * scale)
            apart[j] = broad_phase and cg[j] > reach
        converged, its = step_from_both_starts(
            fn, t, tau, q, p, v, x, y, y_try, z, has_duals, apart, b, c, Phi, D, d, prm, n, s,
            mh, normal, cone, cone_len, slip_row, mu, n_slip, p_end, step_stats,
        )  # fmt: skip
        total += its
        if converged:
            # a contact kept apart that ends the step closed: again with every contact
            closed = False
            for a in range(n):
                q_end[a] = q[a] + x[(s - 1) * n + a]
            point_contact(fn, t_next, q_end, zeros, prm, cg, cG, cH)
            for j in range(nc):
                if apart[j] and cg[j] < 0.0:
                    closed = True
                    apart[j] = False
            if closed:
                for j in range(nc):
                    apart[j] = False
                converged, its = step_from_both_starts(
                    fn, t, tau, q, p, v, x, y, y_try, z, has_duals, apart, b, c, Phi, D, d,
                    prm, n, s, mh, normal, cone, cone_len, slip_row, mu, n_slip, p_end,
                    step_stats,
                )  # fmt: skip
                total += its
        if not converged:
            return _handed_back(stats, k, free, total)
        for a in range(n):
            q_end[a] = q[a] + x[(s - 1) * n + a]
        # the momentum onto the hidden constraint at the step's end
        if mh > 0 and not project_momentum(fn, t_next, q_end, p_end, prm, n, mh, quadratic):
            return _handed_back(stats, k, free, total)
        # a contact open at the step's start that pushed was hit inside the step
        pushed = False
        for j in range(nc):
            force[j] = y_try[normal[j]]
            if force[j] * tau > released:
                pushed = True
                if gap_start[j] > open_gap * scale:
                    return _handed_back(stats, k, free, total)
        if pushed:
            if not velocity_law(
                fn, t_next, q_end, p_end, prm, n, mh, quadratic, force, tau, released, z,
                normal, cone, cone_len, slip_row, mu, restitution, v, work, Lqq, Lqv, Lvv, Fv,
                cg, cG, cH, w, Wq, Wv, Wvq, Gq, gt, Dm, targets, lam, K, piv, xs,
            ):  # fmt: skip
                return _handed_back(stats, k, free, total)
        # the step is taken
        for a in range(n):
            q[a] = q_end[a]
            p[a] = p_end[a]
            q_out[k, a] = q_end[a]
            p_out[k, a] = p_end[a]
        for i in range(m):
            y[i] = y_try[i]
        has_duals = True
        for j in range(nc):
            normal_out[k, j] = force[j]
            first = cone[j]
            for e in range(tangential_out.shape[2]):
                tangential_out[k, j, e] = 0.0
            if first >= 0:
                for e in range(cone_len[j] - 1):
                    tangential_out[k, j, e] = y[first + 1 + e]
        iterations_out[k] = step_stats[0]
        complementarity_out[k] = step_stats[1]
        free = free + 1 if not pushed else 0
        if until_release and free >= 2:
            stats[0] = k + 1
            stats[1] = RELEASED
            stats[2] = free
            stats[3] = total
            return RELEASED
    stats[0] = n_steps
    stats[1] = FINISHED
    stats[2] = free
    stats[3] = total
    return FINISHED


@called
def step_from_both_starts(
    fn, t, tau, q, p, v, x, y, y_try, z, has_duals, apart, b, c, Phi, D, d, prm, n, s, mh,
    normal, cone, cone_len, slip_row, mu, n_slip, p_end, step_stats,
):  # fmt: skip
    """The step from (q, p) over tau, guessed as a straight motion at velocity v: from the
    last step's duals ``y`` (when ``has_duals``), and failing that from the cones'
    centres. Returns (converged, interior-point iterations of every attempt); the step's
    solution in ``x``, ``y_try``, ``z``, ``p_end`` and ``step_stats``."""
    m = y.shape[0]
    nx = x.shape[0]
    iterations = 0
    for attempt in range(2):
        if attempt == 1 and not has_duals:
            break  # the first attempt started from the centres already
        for a in range(nx):
            x[a] = 0.0
        for nu in range(1, s + 1):
            for a in range(n):
                x[(nu - 1) * n + a] = d[nu] * (tau * v[a])
        for i in range(m):
            y_try[i] = y[i]
        interior_point_step(
            fn, t, tau, q, p, x, y_try, z, has_duals and attempt == 0, apart, b, c, Phi, D, d,
            prm, n, s, mh, normal, cone, cone_len, slip_row, mu, n_slip, p_end, step_stats,
        )  # fmt: skip
        iterations += int(step_stats[0])
        if step_stats[2] > 0.0:
            return True, iterations
    return False, iterations


@called
def velocity_law(
    fn, t, q, p, prm, n, mh, quadratic, force, h, released, z, normal, cone, cone_len,
    slip_row, mu, restitution, v, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, w, Wq, Wv, Wvq, Gq,
    gt, Dm, targets, lam, K, piv, xs,
):  # fmt: skip
    r"""The impact law at the velocity level for the contacts that pushed in a step
    (``_Run._velocity_law``), ``p`` updated in place: Newton's law
    :math:`u^+ = -e u^-` for one still approaching at the step's end (frictionless, or
    sticking: its slip stopped too; or sliding, :func:`.contact_velocity.sliding_impulse`),
    then the slip stopped for one that stuck during the step. False where a Newton
    iteration fails (Python's law takes the step)."""
    nc = normal.shape[0]
    zeros = np.zeros(n)
    v_minus = np.zeros(n)
    g = np.zeros(n)
    T = np.zeros((2, n))
    w0 = np.zeros(2)
    out = np.zeros(3)
    for j in range(nc):
        if force[j] * h <= released:
            continue
        if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv,
                                K[:n, :n], piv[:n]):  # fmt: skip
            return False
        point_contact(fn, t, q, zeros, prm, cg, cG, cH)
        u_minus = 0.0
        for a in range(n):
            u_minus += cG[j * n + a] * v[a]
            v_minus[a] = v[a]
        first = cone[j]
        slips = cone_len[j] - 1 if first >= 0 else 0
        if slips > 0:
            point_slip(fn, t, q, zeros, prm, w, Wq, Wv, Wvq)
        if u_minus < 0.0:
            # the gap's row, the slip rows (sticking), the constraints'
            rows = 1 + slips + mh
            for a in range(n):
                Dm[0, a] = cG[j * n + a]
            targets[0] = -restitution[j] * u_minus
            for e in range(slips):
                row = slip_row[j] + e
                for a in range(n):
                    Dm[1 + e, a] = Wv[row * n + a]
                targets[1 + e] = -w[row]
            if mh > 0:
                point_constraint_jacobian(fn, t, q, prm, Gq)
                point_constraint_rate(fn, t, q, prm, gt)
                for i in range(mh):
                    for a in range(n):
                        Dm[1 + slips + i, a] = Gq[i * n + a]
                    targets[1 + slips + i] = -gt[i]
            if not saddle_velocity(fn, t, q, p, prm, n, v, Dm, Dm, targets,
                                   rows, lam, work, Lqq, Lqv, Lvv, Fv, K, piv, xs):  # fmt: skip
                return False
            sticks = True
            if slips > 0:
                size = 0.0
                for e in range(slips):
                    size += lam[1 + e] * lam[1 + e]
                sticks = np.sqrt(size) <= mu[j] * lam[0]
            if sticks:
                for a in range(n):
                    for i in range(rows):
                        p[a] += Dm[i, a] * lam[i]
            else:
                # it slides against the slip after: the sliding law, from v^-
                for a in range(n):
                    g[a] = cG[j * n + a]
                for e in range(slips):
                    row = slip_row[j] + e
                    w0[e] = w[row]
                    for a in range(n):
                        T[e, a] = Wv[row * n + a]
                if not sliding_impulse(
                    fn, t, q, p, prm, n, mh, v_minus, g, T, w0, slips,
                    -restitution[j] * u_minus, mu[j], Gq, gt, out, work, Lqq, Lqv, Lvv, Fv,
                ):  # fmt: skip
                    return False
        if slips > 0 and force[j] * h > RESIDUAL and z[first] * h <= RESIDUAL:
            # it stuck during the step: its slip stopped at the end (no constraint rows,
            # as impact.stop_slip)
            if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv,
                                    Fv, K[:n, :n], piv[:n]):  # fmt: skip
                return False
            for e in range(slips):
                row = slip_row[j] + e
                for a in range(n):
                    Dm[e, a] = Wv[row * n + a]
                targets[e] = -w[row]
            if not saddle_velocity(fn, t, q, p, prm, n, v, Dm, Dm, targets,
                                   slips, lam, work, Lqq, Lqv, Lvv, Fv, K, piv, xs):  # fmt: skip
                return False
            for a in range(n):
                for e in range(slips):
                    p[a] += Dm[e, a] * lam[e]
    return True
