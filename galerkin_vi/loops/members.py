"""Many members of an ensemble in one compiled call.

:meth:`galerkin_vi.Integrator.integrate_many` runs members (initial states,
parameter sets) of one system, method and step size. Called one by one from
Python, each member pays about 0.2 ms of Python around its compiled loop;
here one call runs a block of members, each through the very loop a single
run calls (same compiled function, same arguments), so every member's result
is bitwise the one-by-one run's. Blocks run in threads at once: the drivers
release the GIL.

Which loop is called is a switch (:mod:`.traits`): exactly one of ``general``,
``stage_form``, ``linear``, ``constrained`` and ``varying_mass`` is not ``None``, and numba
compiles only that branch.
"""

from __future__ import annotations

import numpy as np

from .constrained import constrained_loop
from .constrained_tangent import constrained_tangent_loop
from .general import general_loop
from .linear import linear_loop
from .on_demand import driver
from .point import point_hessian
from .stage_form import stage_form_loop
from .tangent import tangent_loop
from .varying_mass import varying_mass_loop

__all__ = ["legendre_members", "members_loop", "tangent_members"]


@driver
def members_loop(
    general,
    stage_form,
    linear,
    constrained,
    varying_mass,
    before,
    q0s,
    p0s,
    v0s,
    t0,
    h,
    n_steps,
    save_every,
    prms,
    after,
    t_out,
    q_out,
    p_out,
    turns_out,
    iterations_out,
    iteration_totals,
    results,
):
    """Run member ``i`` from ``(q0s[i], p0s[i], v0s[i])`` with parameters ``prms[i]``.

    The loop is called as ``loop(*before, q0, p0, v0, t0, h, n_steps, save_every,
    prm, *after, t, q, p, turns, iterations, iteration_total)`` on member ``i``'s
    rows of the outputs (``iteration_totals`` has shape (m, 1)). ``results[i]``
    receives the loop's 5-tuple (:data:`.abi.RESULT_FIELDS`) as it returns it;
    a failed member does not stop the others.
    """
    # the switches leave one of these assignments (numba prunes the others)
    if general is not None:
        loop = general_loop
    if stage_form is not None:
        loop = stage_form_loop
    if linear is not None:
        loop = linear_loop
    if constrained is not None:
        loop = constrained_loop
    if varying_mass is not None:
        loop = varying_mass_loop
    for i in range(q0s.shape[0]):
        status, done, saved, worst, increment = loop(
            *before, q0s[i], p0s[i], v0s[i], t0, h, n_steps, save_every, prms[i], *after,
            t_out[i], q_out[i], p_out[i], turns_out[i], iterations_out[i], iteration_totals[i],
        )  # fmt: skip
        results[i, 0] = status
        results[i, 1] = done
        results[i, 2] = saved
        results[i, 3] = worst
        results[i, 4] = increment
    return 0


@driver
def legendre_members(fn, t0, q0s, v0s, prms, Lv_out, Lvv_out):
    r""":math:`L_v` and the stored :math:`L_{vv}` entries at ``(t0, q0s[i], v0s[i])``.

    Every member's momenta :math:`p_0 = L_v(t_0, q_0, v_0)` in one call, through
    the same compiled point function a single run's Legendre transform calls
    (:class:`galerkin_vi.run.legendre.PointLegendre`), so the values are the
    same. ``Lv_out`` and ``Lvv_out`` must be zero on entry: entries that are
    identically zero are never written.
    """
    n = q0s.shape[1]
    size = Lvv_out.shape[1]
    Lq = np.zeros(n)
    Lqq = np.zeros(size)
    Lqv = np.zeros(size)
    Fv = np.zeros(size)
    for i in range(q0s.shape[0]):
        point_hessian(fn, t0, q0s[i], v0s[i], prms[i], Lq, Lv_out[i], Lqq, Lqv, Lvv_out[i], Fv)
    return 0


@driver
def tangent_members(
    general,
    constrained,
    before,
    fnp,
    q0s,
    p0s,
    v0s,
    t0,
    h,
    n_steps,
    save_every,
    prms,
    after,
    frames,
    sensitivities,
    renormalize_every,
    t_origin,
    chaos,
    stages,
    t_out,
    q_out,
    p_out,
    turns_out,
    T_out,
    S_out,
    growth_out,
    megno_out,
    iterations_out,
    iteration_totals,
    results,
):
    """:func:`members_loop` for runs with the tangent map: member ``i`` through the tangent
    loop (``general``) or the constrained one (``constrained``, switches as there) with its
    own frame ``frames[i]``, sensitivities ``sensitivities[i]`` and chaos sums ``chaos[i]``,
    into its rows of the outputs; ``stages`` has no rows (no record)."""
    if general is not None:
        loop = tangent_loop
    if constrained is not None:
        loop = constrained_tangent_loop
    for i in range(q0s.shape[0]):
        status, done, saved, worst, increment = loop(
            *before, fnp, q0s[i], p0s[i], v0s[i], t0, h, n_steps, save_every, prms[i], *after,
            frames[i], sensitivities[i], renormalize_every, t_origin, chaos[i], stages,
            t_out[i], q_out[i], p_out[i], turns_out[i], T_out[i], S_out[i], growth_out[i],
            megno_out[i], iterations_out[i], iteration_totals[i],
        )  # fmt: skip
        results[i, 0] = status
        results[i, 1] = done
        results[i, 2] = saved
        results[i, 3] = worst
        results[i, 4] = increment
    return 0
