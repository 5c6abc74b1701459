r"""The time-stepping part of a contact run, compiled: step after step with no Python.

Each step is what :meth:`galerkin_vi.contact.runs._Run.time_steps` takes from Python
(:mod:`galerkin_vi.contact.runs` explains the run): the first guess from the
velocity (:func:`.contact_velocity.inverse_legendre`), the interior-point step
(:func:`.contact_step.interior_point_step`, again from the cones' centres when
the last forces do not start it), the constraint's momentum projection, the first
touch of a contact open at the step's start cut out of the step with its impact
(:func:`contact_impulse`), and the impact law at the velocity level for the
contacts that pushed: Newton's law for one still approaching at the step's end
(frictionless, sticking inside the friction cone, or sliding) and the stopped slip
of one that stuck.

The loop hands the step back to Python (status :data:`HANDED_BACK`, the rows before
it kept) where the run needs more than that: a step whose iteration fails from
both starts (Python halves it), a remainder after an impact at the step's very end
(Python's drift), more cuts than ``max_cuts``, a velocity not found. With
``until_release`` it stops after two steps in a row without contact force
(:data:`RELEASED`), where the run goes back to isolated impacts.
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

__all__ = [
    "BROAD_PHASE_MARGIN",
    "FINISHED",
    "HANDED_BACK",
    "IMPACT_FIELDS",
    "RELEASED",
    "contact_steps",
]

#: every step asked for was taken
FINISHED = 0
#: two steps in a row without contact force (``until_release``)
RELEASED = 1
#: the next step is Python's (a failed iteration, a drift, too many cuts, a failed Newton)
HANDED_BACK = 2
#: the broad phase keeps a contact apart whose gap exceeds this many times the distance
#: its normal velocity covers in the step (plus the coordinates' round-off)
BROAD_PHASE_MARGIN = 4.0
#: ``advance``'s ``kept`` for the first-touch trials: every contact open at the start
OPEN_APART = -2
#: the columns of ``impact_data``
IMPACT_FIELDS = ("row", "contact", "mode", "normal", "tangential 1", "tangential 2", "u-", "u+")


@kernel
def _stop(stats, k, status, free, total, rows, forces, impacts):
    """The piece ends before grid step k with ``status``: its statistics."""
    stats[0] = k
    stats[1] = status
    stats[2] = free
    stats[3] = total
    stats[4] = rows
    stats[5] = forces
    stats[6] = impacts
    return status


@kernel
def _add_row(row_t, row_q, row_p, row_grid, i, t, q, p, grid):
    """Row i of the run's output: (t, q, p), reached at a grid time or not."""
    row_t[i] = t
    row_grid[i] = grid
    for a in range(q.shape[0]):
        row_q[i, a] = q[a]
        row_p[i, a] = p[a]


@kernel
def _add_forces(force_t, normal_out, tangential_out, iterations_out, complementarity_out,
                i, t, y, normal, cone, cone_len, step_stats):  # fmt: skip
    """Record i of the contact forces: the sub-step from t's (normal, tangential)."""
    force_t[i] = t
    for j in range(normal.shape[0]):
        normal_out[i, j] = y[normal[j]]
        first = cone[j]
        for e in range(tangential_out.shape[2]):
            tangential_out[i, j, e] = 0.0
        if first >= 0:
            for e in range(cone_len[j] - 1):
                tangential_out[i, j, e] = y[first + 1 + e]
    iterations_out[i] = step_stats[0]
    complementarity_out[i] = step_stats[1]


@kernel
def _copy_step(q, p, y, z, stats, q_to, p_to, y_to, z_to, stats_to):
    """A step's solution (end state, duals, slacks, statistics) copied."""
    for a in range(q.shape[0]):
        q_to[a] = q[a]
        p_to[a] = p[a]
    for i in range(y.shape[0]):
        y_to[i] = y[i]
        z_to[i] = z[i]
    for i in range(stats.shape[0]):
        stats_to[i] = stats[i]


@driver
def contact_steps(
    fn, t0, k0, h, n_steps, q, p, y, has_duals, b, c, Phi, D, d, prm, n, s, mh, normal, cone,
    cone_len, slip_row, mu, restitution, n_slip, quadratic, until_release, free,
    open_gap, released, broad_phase, remainder, max_cuts, together, normal_floor, row_t,
    row_q, row_p, row_grid,
    force_t, normal_out, tangential_out, iterations_out, complementarity_out, impact_data,
    stats,
):  # fmt: skip
    r"""Time-stepping steps from grid node ``k0`` (time :math:`t_0 + k_0 h`, state q, p),
    at most ``n_steps``, each from :math:`t_0 + k h` to :math:`t_0 + (k + 1) h`, the
    impacts of contacts open at a step's start cut out of it
    (``_Run._through_stepping``): such a contact that pushes was hit inside the step,
    which is cut where its gap closes (on steps that keep every open contact apart, by Illinois
    regula falsi on their length), the impact law applied there
    (:func:`contact_impulse`), and the rest of the step taken again.

    ``q``, ``p`` and the duals ``y`` (used as the first step's start when ``has_duals``)
    are updated to the last row. The rows (``row_t``, ``row_q``, ``row_p``,
    ``row_grid``: reached at a grid time, or an impact's pair of rows), the forces of
    each step or part of a step (``force_t`` its start, ``normal_out``,
    ``tangential_out`` (contacts, 2), ``iterations_out``, ``complementarity_out``)
    and the impacts (``impact_data``: row of p-minus, contact, mode 0/1/2
    frictionless/stick/slide, normal impulse, two tangential, u-, u+) are written in
    order; the piece ends early (status :data:`FINISHED`) when another step might not
    fit. ``free`` counts the steps without contact force before the first;
    ``open_gap``, ``released``, ``remainder``, ``max_cuts`` and ``together`` are
    :mod:`galerkin_vi.contact.runs`' ``OPEN_GAP``, ``RELEASED_IMPULSE``, ``REMAINDER``,
    ``MAX_IMPACTS_PER_STEP`` and ``TOGETHER``; a cut where other contacts are hit with
    the first (:func:`hit_together`) hands the step back to Python's simultaneous law;
    a contact that pushes where its gradient's size is not above ``normal_floor`` hands
    the step back. ``stats`` receives (grid steps taken, status, the count of free
    steps, interior-point iterations, rows, force records, impacts).
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
    # the whole step's solution, kept while its first touches are looked for
    q_full = np.zeros(n)
    p_full = np.zeros(n)
    y_full = np.zeros(m)
    z_full = np.zeros(m)
    stats_full = np.zeros(3)
    q_hit = np.zeros(n)
    p_hit = np.zeros(n)
    y_hit = np.zeros(m)
    stats_hit = np.zeros(3)
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
    record = np.zeros(5)
    apart = np.zeros(nc, dtype=np.bool_)
    gap_start = np.zeros(nc)
    total = 0
    n_rows = 0
    n_forces = 0
    n_impacts = 0
    capacity = row_t.shape[0]
    for k in range(n_steps):
        # room for the step's rows: its end and two per impact
        if n_rows + 1 + 2 * max_cuts > capacity or n_impacts + max_cuts > impact_data.shape[0]:
            return _stop(stats, k, FINISHED, free, total, n_rows, n_forces, n_impacts)
        if n_forces + 2 * max_cuts + 1 > force_t.shape[0]:
            return _stop(stats, k, FINISHED, free, total, n_rows, n_forces, n_impacts)
        t = t0 + (k0 + k) * h
        t_next = t0 + (k0 + k + 1) * h
        cuts = 0
        while True:
            tau = t_next - t
            scale = 1.0
            for a in range(n):
                scale = max(scale, abs(q[a]))
            if tau <= remainder * h:
                # the remainder after an impact at the step's very end: Python's drift
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            point_contact(fn, t, q, zeros, prm, cg, cG, cH)
            for j in range(nc):
                gap_start[j] = cg[j]
            converged, its = advance(
                fn, t, tau, q, p, -1, v, x, y, y_try, z, has_duals, apart, gap_start, b, c,
                Phi, D, d, prm, n, s, mh, normal, cone, cone_len, slip_row, mu, n_slip,
                quadratic, open_gap, broad_phase, scale, q_end, p_end, step_stats, work, Lqq,
                Lqv, Lvv, Fv, cg, cG, cH, K, piv,
            )  # fmt: skip
            total += its
            if not converged:
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            # contacts open at the start that pushed: hit inside the step
            opened = False
            for j in range(nc):
                force[j] = y_try[normal[j]]
                if gap_start[j] > open_gap * scale and force[j] * tau > released:
                    opened = True
            if not opened:
                break
            _copy_step(q_end, p_end, y_try, z, step_stats, q_full, p_full, y_full, z_full,
                       stats_full)  # fmt: skip
            best = np.inf
            hit = -1
            resting = False
            for j in range(nc):
                if not (gap_start[j] > open_gap * scale and force[j] * tau > released):
                    continue
                # the step length alpha at whose end its gap is zero, on steps keeping the
                # open contacts apart (the earliest touch is on a step none of them has
                # touched in; a face's corners touch at one alpha): the whole step first
                # (no impact unless it closes there), then Illinois regula falsi
                lo = 0.0
                hi = tau
                f_lo = gap_start[j]
                f_hi = 0.0
                side = 0
                alpha = tau
                closes = False
                for trial in range(61):
                    if trial > 0:
                        alpha = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
                    converged, its = advance(
                        fn, t, alpha, q, p, OPEN_APART, v, x, y, y_try, z, has_duals, apart,
                        gap_start,
                        b, c, Phi, D, d, prm, n, s, mh, normal, cone, cone_len, slip_row, mu,
                        n_slip, quadratic, open_gap, broad_phase, scale, q_end, p_end,
                        step_stats, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, K, piv,
                    )  # fmt: skip
                    total += its
                    if not converged:
                        return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces,
                                     n_impacts)  # fmt: skip
                    point_contact(fn, t + alpha, q_end, zeros, prm, cg, cG, cH)
                    f = cg[j]
                    if trial == 0:
                        closes = f < 0.0
                        f_hi = f
                        if not closes:
                            break  # it would not have closed without its force: no impact
                        continue
                    if abs(f) <= 4 * 2.220446049250313e-16 * scale or hi - lo <= 4e-16 * tau:
                        break
                    if f > 0:
                        lo = alpha
                        f_lo = f
                        if side == 1:
                            f_hi /= 2
                        side = 1
                    else:
                        hi = alpha
                        f_hi = f
                        if side == -1:
                            f_lo /= 2
                        side = -1
                if not closes:
                    continue
                if alpha <= 1e-12 * tau:
                    resting = True  # closing at the step's start: a resting contact
                    break
                if alpha < best:
                    best = alpha
                    hit = j
                    for a in range(n):
                        q_hit[a] = q_end[a]
                        p_hit[a] = p_end[a]
                    for i in range(m):
                        y_hit[i] = y_try[i]
                    for i in range(3):
                        stats_hit[i] = step_stats[i]
            if resting or hit < 0:
                # no cut: the whole step stands
                _copy_step(q_full, p_full, y_full, z_full, stats_full, q_end, p_end, y_try, z,
                           step_stats)  # fmt: skip
                for j in range(nc):
                    force[j] = y_try[normal[j]]
                break
            if cuts >= max_cuts:
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            # the step is cut at the touch: its forces, then the impact there
            _add_forces(force_t, normal_out, tangential_out, iterations_out,
                        complementarity_out, n_forces, t, y_hit, normal, cone, cone_len,
                        stats_hit)  # fmt: skip
            n_forces += 1
            t_hit = t + best
            if not inverse_legendre(fn, t_hit, q_hit, p_hit, prm, n, quadratic, v, work, Lqq,
                                    Lqv, Lvv, Fv, K[:n, :n], piv[:n]):  # fmt: skip
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            point_contact(fn, t_hit, q_hit, zeros, prm, cg, cG, cH)
            u_minus = 0.0
            for a in range(n):
                u_minus += cG[hit * n + a] * v[a]
            if u_minus < 0.0 and hit_together(hit, u_minus, v, cg, cG, open_gap * scale,
                                              together, restitution, n):  # fmt: skip
                # a face landing flat: Python's simultaneous law, from the last row
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces - 1,
                             n_impacts)  # fmt: skip
            for a in range(n):
                q[a] = q_hit[a]
                p[a] = p_hit[a]
            t = t_hit
            cuts += 1
            if u_minus >= 0.0:
                continue  # grazed, not hit: the other contacts' forces turned it
            _add_row(row_t, row_q, row_p, row_grid, n_rows, t, q, p, False)
            n_rows += 1
            if not contact_impulse(
                fn, t, q, p, prm, n, mh, hit, u_minus, v, normal, cone, cone_len, slip_row, mu,
                restitution, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, w, Wq, Wv, Wvq, Gq, gt, Dm,
                targets, lam, K, piv, xs, record,
            ):  # fmt: skip
                n_rows -= 1
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv,
                                    Fv, K[:n, :n], piv[:n]):  # fmt: skip
                n_rows -= 1
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
            point_contact(fn, t, q, zeros, prm, cg, cG, cH)
            u_plus = 0.0
            for a in range(n):
                u_plus += cG[hit * n + a] * v[a]
            impact_data[n_impacts, 0] = n_rows - 1
            impact_data[n_impacts, 1] = hit
            for i in range(4):
                impact_data[n_impacts, 2 + i] = record[i]
            impact_data[n_impacts, 6] = u_minus
            impact_data[n_impacts, 7] = u_plus
            n_impacts += 1
            _add_row(row_t, row_q, row_p, row_grid, n_rows, t, q, p, False)
            n_rows += 1
        # the step's end: the forces of its last part, the impact law at the velocity level
        pushed = False
        point_contact(fn, t_next, q_end, zeros, prm, cg, cG, cH)
        for j in range(nc):
            if force[j] * tau > released:
                pushed = True
                size = 0.0
                for a in range(n):
                    size += cG[j * n + a] * cG[j * n + a]
                if not np.sqrt(size) > normal_floor[j]:
                    # no normal where it pushes: Python's step stops the run and says so
                    return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
        if pushed:
            if not velocity_law(
                fn, t_next, q_end, p_end, prm, n, mh, quadratic, force, tau, released,
                open_gap * scale, z,
                normal, cone, cone_len, slip_row, mu, restitution, v, work, Lqq, Lqv, Lvv, Fv,
                cg, cG, cH, w, Wq, Wv, Wvq, Gq, gt, Dm, targets, lam, K, piv, xs, record,
            ):  # fmt: skip
                return _stop(stats, k, HANDED_BACK, free, total, n_rows, n_forces, n_impacts)
        _add_forces(force_t, normal_out, tangential_out, iterations_out, complementarity_out,
                    n_forces, t, y_try, normal, cone, cone_len, step_stats)  # fmt: skip
        n_forces += 1
        for a in range(n):
            q[a] = q_end[a]
            p[a] = p_end[a]
        for i in range(m):
            y[i] = y_try[i]
        has_duals = True
        _add_row(row_t, row_q, row_p, row_grid, n_rows, t_next, q, p, True)
        n_rows += 1
        free = free + 1 if not pushed else 0
        if until_release and free >= 2:
            return _stop(stats, k + 1, RELEASED, free, total, n_rows, n_forces, n_impacts)
    return _stop(stats, n_steps, FINISHED, free, total, n_rows, n_forces, n_impacts)


@kernel
def hit_together(hit, u_hit, v, cg, cG, closed, together, restitution, n):
    """Whether other contacts are hit at the cut with contact ``hit`` (approaching at
    ``u_hit``): gap within ``closed`` of zero (``cg``, normals ``cG`` at the cut), and
    approaching at ``v`` faster than ``together`` times ``u_hit``, or plastic with
    ``hit`` plastic (``_Run._hit_together``). Python's law takes such a simultaneous
    impact (:func:`galerkin_vi.contact.impact.simultaneous_impulse`)."""
    plastic = restitution[hit] == 0.0
    for j in range(cg.shape[0]):
        if j == hit or cg[j] > closed:
            continue
        if plastic and restitution[j] == 0.0:
            return True
        u = 0.0
        for a in range(n):
            u += cG[j * n + a] * v[a]
        if u < together * u_hit:
            return True
    return False


@kernel
def held_apart(j, kept, gap_start, open_gap):
    """Whether contact j is kept apart: it is ``kept``, or ``kept`` is OPEN_APART and
    j is open at the step's start."""
    return j == kept or (kept == OPEN_APART and gap_start[j] > open_gap)


@called
def advance(
    fn, t, tau, q, p, kept, v, x, y, y_try, z, has_duals, apart, gap_start, b, c, Phi, D, d,
    prm, n, s, mh, normal, cone, cone_len, slip_row, mu, n_slip, quadratic, open_gap,
    broad_phase, scale, q_end, p_end, step_stats, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, K, piv,
):  # fmt: skip
    r"""One step of length tau from (t, q, p), contact ``kept`` kept apart (-1: none;
    OPEN_APART: every contact open at t, its gap above ``open_gap`` times ``scale``):
    the first guess from the velocity, the broad phase, the step from both starts
    (:func:`step_from_both_starts`; again with every contact where one kept apart by the
    broad phase ends closed) and the momentum projected onto the hidden constraint.
    ``gap_start`` holds the gaps at t. Returns (converged, iterations); the step's end
    in ``q_end``, ``p_end``, its duals in ``y_try``, slacks in ``z``."""
    nc = normal.shape[0]
    zeros = np.zeros(n)
    if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv,
                            K[:n, :n], piv[:n]):  # fmt: skip
        return False, 0
    # broad phase: a contact whose gap cannot close within the step (its gap above
    # BROAD_PHASE_MARGIN times the distance its normal velocity covers, and above the
    # coordinates' round-off) is kept apart; if it ends the step closed, the step is
    # taken again with every contact
    point_contact(fn, t, q, zeros, prm, cg, cG, cH)
    for j in range(nc):
        rate = 0.0
        for a in range(n):
            rate += cG[j * n + a] * v[a]
        reach = BROAD_PHASE_MARGIN * (abs(rate) * tau + open_gap * scale)
        apart[j] = held_apart(j, kept, gap_start, open_gap * scale) or (
            broad_phase and gap_start[j] > reach
        )
    converged, its = step_from_both_starts(
        fn, t, tau, q, p, v, x, y, y_try, z, has_duals, apart, b, c, Phi, D, d, prm, n, s,
        mh, normal, cone, cone_len, slip_row, mu, n_slip, p_end, step_stats,
    )  # fmt: skip
    if converged and broad_phase:
        closed = False
        for a in range(n):
            q_end[a] = q[a] + x[(s - 1) * n + a]
        point_contact(fn, t + tau, q_end, zeros, prm, cg, cG, cH)
        for j in range(nc):
            if apart[j] and not held_apart(j, kept, gap_start, open_gap * scale) and cg[j] < 0:
                closed = True
        if closed:
            for j in range(nc):
                apart[j] = held_apart(j, kept, gap_start, open_gap * scale)
            converged, more = step_from_both_starts(
                fn, t, tau, q, p, v, x, y, y_try, z, has_duals, apart, b, c, Phi, D, d, prm,
                n, s, mh, normal, cone, cone_len, slip_row, mu, n_slip, p_end, step_stats,
            )  # fmt: skip
            its += more
    if not converged:
        return False, its
    for a in range(n):
        q_end[a] = q[a] + x[(s - 1) * n + a]
    if mh > 0 and not project_momentum(fn, t + tau, q_end, p_end, prm, n, mh, quadratic):
        return False, its
    return True, its


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
def contact_impulse(
    fn, t, q, p, prm, n, mh, j, u_minus, v, normal, cone, cone_len, slip_row, mu, restitution,
    work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, w, Wq, Wv, Wvq, Gq, gt, Dm, targets, lam, K, piv, xs,
    record,
):  # fmt: skip
    r"""Newton's impact law :math:`u^+ = -e\,u^-` for contact j approaching at
    :math:`u^- < 0` with velocity ``v`` at (t, q) (:func:`galerkin_vi.contact.impact.impulse`):
    frictionless; or sticking, its slip stopped too, where the impulse lies in the
    friction cone; or else sliding (:func:`.contact_velocity.sliding_impulse`). ``p`` is
    updated in place; ``record`` receives (mode 0/1/2 frictionless/stick/slide, the
    normal impulse, two tangential ones). False where a Newton iteration fails."""
    zeros = np.zeros(n)
    v_minus = np.zeros(n)
    g = np.zeros(n)
    T = np.zeros((2, n))
    w0 = np.zeros(2)
    out = np.zeros(3)
    for a in range(n):
        v_minus[a] = v[a]
    point_contact(fn, t, q, zeros, prm, cg, cG, cH)
    first = cone[j]
    slips = cone_len[j] - 1 if first >= 0 else 0
    if slips > 0:
        point_slip(fn, t, q, zeros, prm, w, Wq, Wv, Wvq)
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
    for i in range(5):
        record[i] = 0.0
    if sticks:
        for a in range(n):
            for i in range(rows):
                p[a] += Dm[i, a] * lam[i]
        record[0] = 1.0 if slips > 0 else 0.0
        record[1] = lam[0]
        for e in range(slips):
            record[2 + e] = lam[1 + e]
        return True
    # it slides against the slip after: the sliding law, from v^-
    for a in range(n):
        g[a] = cG[j * n + a]
    for e in range(slips):
        row = slip_row[j] + e
        w0[e] = w[row]
        for a in range(n):
            T[e, a] = Wv[row * n + a]
    if not sliding_impulse(
        fn, t, q, p, prm, n, mh, v_minus, g, T, w0, slips, -restitution[j] * u_minus, mu[j],
        Gq, gt, out, work, Lqq, Lqv, Lvv, Fv,
    ):  # fmt: skip
        return False
    record[0] = 2.0
    for i in range(1 + slips):
        record[1 + i] = out[i]
    return True


@called
def velocity_law(
    fn, t, q, p, prm, n, mh, quadratic, force, h, released, closed, z, normal, cone,
    cone_len, slip_row, mu, restitution, v, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, w, Wq, Wv,
    Wvq, Gq, gt, Dm, targets, lam, K, piv, xs, record,
):  # fmt: skip
    r"""The impact law at the velocity level for the contacts that pushed in a step and
    are closed at its end, gap at most ``closed`` (``_Run._velocity_law``), ``p`` updated
    in place: Newton's law :math:`u^+ = -e u^-` for one still approaching at the step's
    end (:func:`contact_impulse`), then the slip stopped for one that stuck during the
    step. False where a Newton iteration fails (Python's law takes the step)."""
    nc = normal.shape[0]
    zeros = np.zeros(n)
    gap = np.zeros(nc)
    point_contact(fn, t, q, zeros, prm, cg, cG, cH)
    for j in range(nc):
        gap[j] = cg[j]
    for j in range(nc):
        if force[j] * h <= released or gap[j] > closed:
            continue
        if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv, Fv,
                                K[:n, :n], piv[:n]):  # fmt: skip
            return False
        point_contact(fn, t, q, zeros, prm, cg, cG, cH)
        u_minus = 0.0
        for a in range(n):
            u_minus += cG[j * n + a] * v[a]
        first = cone[j]
        slips = cone_len[j] - 1 if first >= 0 else 0
        if u_minus < 0.0 and not contact_impulse(
            fn, t, q, p, prm, n, mh, j, u_minus, v, normal, cone, cone_len, slip_row, mu,
            restitution, work, Lqq, Lqv, Lvv, Fv, cg, cG, cH, w, Wq, Wv, Wvq, Gq, gt, Dm,
            targets, lam, K, piv, xs, record,
        ):  # fmt: skip
            return False
        if slips > 0 and force[j] * h > RESIDUAL and z[first] * h <= RESIDUAL:
            # it stuck during the step: its slip stopped at the end (no constraint rows,
            # as impact.stop_slip)
            if not inverse_legendre(fn, t, q, p, prm, n, quadratic, v, work, Lqq, Lqv, Lvv,
                                    Fv, K[:n, :n], piv[:n]):  # fmt: skip
                return False
            point_slip(fn, t, q, zeros, prm, w, Wq, Wv, Wvq)
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
