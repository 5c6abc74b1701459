r"""The stage-form loop generated for one small system: its coordinates as scalars, its
force inline, the constant-mass fixed point only.

For a separable :math:`L = \tfrac12 v^TMv - V(t, q)` with constant diagonal
:math:`M` (the systems of :func:`.explicit_steps.has_generated_loops` whose mass is
diagonal), the stage form's unknowns are the increments :math:`Z_i` at the
implicit quadrature points (:mod:`galerkin_vi.loops.stage_form`), and the
cheap iteration is the fixed point

.. math::

    Z_i \leftarrow M^{-1}\Big(h\,\hat c_i\,p_k + h^2\sum_{j\ \text{known}} \hat W_{ij} F_j
        + h^2 \sum_{j\ \text{implicit}} \hat W_{ij}\,F(t_k + c_j h,\ q_k + Z_j)\Big).

The generated function runs the shared loop's steps with that iteration (the
same first iterate from extrapolated forces, the same stopping rule, the same
end of step and compensated sums, so the same states bit for bit), with the
coordinates and momenta as local scalars and the force and the mass as the
point functions' own text (:func:`.source.at_rest`) written where they are
used, for every Gauss or Lobatto method at once: the stage loops run over the
method's tables, which stay arguments. Where the shared loop would hand a step
over to full Newton (the fixed point contracts too slowly, or fails), the
generated one stops before that step and leaves its state as the last saved
row; the shared loop runs the rest of the segment from there
(:func:`galerkin_vi.run.segment.continue_from_last_row`).
"""

from __future__ import annotations

import re

from .explicit_steps import (
    compensated_lines,
    indented,
    initial_state_lines,
    saved_row_lines,
    wrap_lines,
)

__all__ = ["IMPORTS", "SWEEP_END", "force_at", "render_stage_steps"]

# the loops' status codes (galerkin_vi.loops.abi), written into the generated text
_STATUS_OK = 0
_STATUS_NEWTON_FAILED = 1
_STATUS_SINGULAR = 2
_STATUS_NONFINITE = 3

#: the imports of the generated module that the stage loop reads: the shared loop's
#: stopping rule and constants, so that both take the same sweeps
IMPORTS = [
    "from galerkin_vi.loops.linalg import CONTINUE, CONVERGED, newton_status",
    "from galerkin_vi.loops.stage_form import (",
    "    MASS_CONTRACTION, MASS_CONTRACTION_MAX, NEWTON_RESERVE, too_slow,",
    ")",
]


#: the end of a sweep of the constant-mass fixed point: a bit-identical sweep has
#: converged, else the shared stopping rule (its hand-over to Newton included)
SWEEP_END = [
    "if not shift < 1e300:",
    f"    status = {_STATUS_NONFINITE}",
    "    increment = np.inf",
    "    break",
    "if shift == 0.0:",
    f"    status = {_STATUS_OK}",
    "    current = True",
    "    break",
    "scale = 1.0 + max(size, base)",
    "if too_slow(increment, previous, its, contraction, budget, tol * scale):",
    "    break",
    "decision = newton_status(increment, previous, scale, tol, its, maxiter)",
    "if decision == CONVERGED:",
    f"    status = {_STATUS_OK}",
    "    break",
    "if decision != CONTINUE or its >= budget:",
    "    break",
    "previous = increment",
]


def render_stage_steps(
    force: list[str],
    mass: list[str],
    n: int,
    periodic: tuple[bool, ...],
    autonomous: bool,
) -> list[str]:
    """Source lines of ``stage_steps``, the stage-form loop of one system.

    Its arguments are those of :func:`galerkin_vi.loops.stage_form.stage_form_loop`
    less the point functions, traits, pattern, angle mask and mass work space:
    ``(q0, p0, v0, t0, h, n_steps, save_every, prm, b, c, implicit, known, rest,
    stage_p, stage_a, stage_force, control_p, control_a, control_force, Phi1, X,
    reuse_endpoint, tol, maxiter, cheap_first, t_out, q_out, p_out, turns_out,
    iterations_out, iteration_total)``; its result is the loop's 5-tuple, with
    status 1 (``STATUS_NEWTON_FAILED``) where it hands the run over. ``force`` holds
    the unindented lines that set ``g_a`` from ``t``, ``q_a`` and ``prm``, ``mass``
    those that set the diagonal ``m_a`` of the constant :math:`M` (the point
    functions' text, :func:`.source.at_rest`).
    """
    angles = [a for a in range(n) if periodic[a]]
    coords = range(n)
    time = "0.0" if autonomous else "tk + c[j] * h"
    lines = [
        "",
        "",
        "def stage_steps(q0, p0, v0, t0, h, n_steps, save_every, prm, b, c, implicit, known,"
        " rest, stage_p, stage_a, stage_force, control_p, control_a, control_force, Phi1, X,"
        " reuse_endpoint, tol, maxiter, cheap_first, t_out, q_out, p_out, turns_out,"
        " iterations_out, iteration_total):",
    ]
    body = ["r = b.shape[0]", "s = control_p.shape[0]", "u = implicit.shape[0]"]
    # M as the shared loop forms it: the Hessian point function at (t0, q0, 0)
    body += initial_state_lines(n, periodic, ["t = t0", *mass])
    regular = " and ".join(f"m_{a} != 0.0" for a in coords)
    body += [f"if not ({regular}):", f"    return {_STATUS_SINGULAR}, 0, saved, 0.0, np.inf"]
    body += [f"w_{a} = 1.0 / m_{a}" for a in coords]
    body += [
        f"Z = np.zeros((u, {n}))",
        f"FI = np.zeros((u, {n}))",
        f"F = np.zeros((r, {n}))",
        f"offset = np.zeros((u, {n}))",
        f"F_next = np.zeros((u, {n}))",
        f"F_last = np.zeros((r, {n}))",
        "two_step_start = X.shape[1] == 3 * r and u > 0",
        f"C = np.zeros((s, {n}))",
        "for il in range(u):",
    ]
    body += [f"    Z[il, {a}] = c[implicit[il]] * h * v0[{a}]" for a in coords]
    body += [
        "h2 = h * h",
        "needed = np.zeros(s, dtype=np.bool_)",
        "needed[s - 1] = True",
        "for jr in range(rest.shape[0]):",
        "    for mu in range(s):",
        "        if Phi1[rest[jr], mu] != 0.0:",
        "            needed[mu] = True",
        "W2 = np.zeros((u, u))",
        "for il in range(u):",
        "    for jl in range(u):",
        "        W2[il, jl] = h2 * stage_force[il, implicit[jl]]",
        f"contraction = min(MASS_CONTRACTION_MAX, MASS_CONTRACTION * u * {n})",
        "budget = max(maxiter // 2, maxiter - NEWTON_RESERVE)",
        "worst = 0.0",
        "have_start_force = False",
        "for k in range(n_steps):",
    ]
    step = ["tk = t0 + k * h"]
    # the forces at the points known at the step's start (Lobatto's first)
    reused = "reuse_endpoint and have_start_force" if autonomous else "False"
    step += [f"if not ({reused}):"]
    known = ["j = known[jk]", f"t = {time}"]
    known += [f"Q_{a} = q_{a}" for a in coords] + force_at("Q", force)
    known += [f"F[j, {a}] = g_{a}" for a in coords]
    step += indented(["for jk in range(known.shape[0]):", *indented(known, 1)], 1)
    offset = _sums(
        "jk", "known.shape[0]", "h2 * stage_force[il, known[jk]]", "F[known[jk], {a}]", n,
        start="h * stage_p[il] * p_{a}",
    )  # fmt: skip
    offset += [f"offset[il, {a}] = acc_{a}" for a in coords]
    step += ["for il in range(u):", *indented(offset, 1)]
    first = _sums("jl", "u", "W2[il, jl]", "F_next[jl, {a}]", n, start="offset[il, {a}]")
    first += [f"Z[il, {a}] = acc_{a} * w_{a}" for a in coords]
    step += ["if k > 0:", "    for il in range(u):", *indented(first, 2)]
    step += [
        "its = 0",
        "increment = 0.0",
        "residual = 0.0",
        "current = False",
        # no implicit point (two Lobatto points): nothing to iterate, as in the shared loop
        f"status = {_STATUS_NEWTON_FAILED} if u > 0 else {_STATUS_OK}",
        "previous = np.inf",
        "base = 0.0",
    ]
    step += [f"base = max(base, abs(q_{a}))" for a in coords]
    step += ["step_size = 0.0", "for il in range(u):"]
    step += [f"    step_size = max(step_size, abs(Z[il, {a}]))" for a in coords]
    sweep = ["its += 1", "for jl in range(u):"]
    stage = ["j = implicit[jl]", f"t = {time}"]
    stage += [f"Q_{a} = q_{a} + Z[jl, {a}]" for a in coords] + force_at("Q", force)
    stage += [f"FI[jl, {a}] = g_{a}" for a in coords]
    sweep += indented(stage, 1)
    sweep += ["residual = 0.0", "increment = 0.0", "size = step_size", "shift = 0.0"]
    update = _sums("jl", "u", "W2[il, jl]", "FI[jl, {a}]", n, start="offset[il, {a}]")
    for a in coords:
        update += [
            f"old = Z[il, {a}]",
            f"updated = acc_{a} * w_{a}",
            "dz = abs(updated - old)",
            "if dz > increment:",
            "    increment = dz",
            f"if m_{a} * dz > residual:",
            f"    residual = m_{a} * dz",
            f"shift += abs((q_{a} + updated) - (q_{a} + old))",
            f"Z[il, {a}] = updated",
        ]
    sweep += ["for il in range(u):", *indented(update, 1), *SWEEP_END]
    step += ["while u > 0 and its < maxiter:", *indented(sweep, 1)]
    # a step the fixed point cannot take (or that fails): the state before it is the
    # last row, due for saving or not
    kept = saved_row_lines("k % save_every != 0", "tk", "q", "p", n, periodic, "l", "r")
    kept.append("return status, k, saved, worst, increment")
    step += [f"if status == {_STATUS_NEWTON_FAILED}:", *indented(kept, 1)]
    step += [
        "slot = k // save_every",
        "if its > iterations_out[slot]:",
        "    iterations_out[slot] = its",
        "iteration_total[0] += its",
        f"if status == {_STATUS_OK}:",
    ]
    # the end of the step: forces at the solution (unless the last sweep gave them),
    # the control points, the forces at the points explicit once C is known, dp
    end = ["if not current:", "    for jl in range(u):"]
    refresh = ["j = implicit[jl]", f"t = {time}"]
    refresh += [f"Q_{a} = q_{a} + Z[jl, {a}]" for a in coords] + force_at("Q", force)
    refresh += [f"FI[jl, {a}] = g_{a}" for a in coords]
    end += indented(refresh, 2)
    end += ["for jl in range(u):"]
    end += [f"    F[implicit[jl], {a}] = FI[jl, {a}]" for a in coords]
    control = ["if not needed[mu]:", "    continue"]
    control += _sums("j", "r", "control_force[mu, j]", "F[j, {a}]", n)
    control += [f"C[mu, {a}] = (h * control_p[mu] * p_{a} + h2 * acc_{a}) * w_{a}" for a in coords]
    end += ["for mu in range(s):", *indented(control, 1)]
    rest = ["j = rest[jr]", f"t = {time}"]
    rest += _sums("mu", "s", "Phi1[j, mu]", "C[mu, {a}]", n)
    rest += [f"Q_{a} = q_{a} + acc_{a}" for a in coords]
    rest += force_at("Q", force) + [f"F[j, {a}] = g_{a}" for a in coords]
    end += ["for jr in range(rest.shape[0]):", *indented(rest, 1)]
    end += _sums("j", "r", "b[j]", "F[j, {a}]", n)
    end += [f"d_{a} = h * acc_{a}" for a in coords]
    finite = " and ".join(f"abs(C[s - 1, {a}]) < 1e300 and abs(d_{a}) < 1e300" for a in coords)
    end += [f"if not ({finite}):", f"    status = {_STATUS_NONFINITE}"]
    step += indented(end, 1)
    step += [f"if status != {_STATUS_OK}:", *indented(kept, 1)]
    step += ["if residual > worst:", "    worst = residual"]
    step += compensated_lines("p", "e", "d", n)
    # the next step's forces from this step's, or with a two-step table after the first
    # step from this step's and the last step's (older first): the shared loop's sums
    extrapolate = [f"acc_{a} = 0.0" for a in coords]
    extrapolate += ["if two:", "    for j in range(r):", "        _w = X[il, r + j]"]
    extrapolate += [f"        acc_{a} += _w * F_last[j, {a}]" for a in coords]
    extrapolate += ["for j in range(r):", "    _w = X[il, newer + j]"]
    extrapolate += [f"    acc_{a} += _w * F[j, {a}]" for a in coords]
    extrapolate += [f"F_next[il, {a}] = acc_{a}" for a in coords]
    step += ["two = two_step_start and k > 0", "newer = 2 * r if two else 0"]
    step += ["for il in range(u):", *indented(extrapolate, 1)]
    step += ["if two_step_start:", "    for j in range(r):"]
    step += [f"        F_last[j, {a}] = F[j, {a}]" for a in coords]
    step += ["if reuse_endpoint:"]
    step += [f"    F[0, {a}] = F[r - 1, {a}]" for a in coords]
    step += ["    have_start_force = True"]
    step += [f"dq_{a} = C[s - 1, {a}]" for a in coords] + compensated_lines("q", "l", "dq", n)
    for a in angles:
        step += wrap_lines(a)
    due = "(k + 1) % save_every == 0 or k + 1 == n_steps"
    step += saved_row_lines(due, "t0 + (k + 1) * h", "q", "p", n, periodic, "l", "r")
    body += indented(step, 1)
    body.append(f"return {_STATUS_OK}, n_steps, saved, worst, 0.0")
    return lines + indented(body, 1)


def _sums(index: str, count: str, weight: str, term: str, n: int, start: str = "0.0") -> list[str]:
    """Lines setting ``acc_a = start + sum_index weight * term`` for every coordinate a, in
    one loop over ``index`` (``start`` and ``term`` are formats of ``a``).

    Each sum adds its terms in the shared loop's order, so the values are its own bit
    for bit; one loop for all coordinates, not one per coordinate, keeps numba's
    compile time short.
    """
    lines = [f"acc_{a} = {start.format(a=a)}" for a in range(n)]
    lines += [f"for {index} in range({count}):", f"    _w = {weight}"]
    lines += [f"    acc_{a} += _w * {term.format(a=a)}" for a in range(n)]
    return lines


def force_at(point: str, force: list[str]) -> list[str]:
    """The force's lines evaluated at the scalars ``{point}_a`` instead of ``q_a`` (the
    identifiers ``q_0``, ``q_1``, ... are whole words of the lines)."""
    pattern = re.compile(r"\bq_(\d+)\b")
    return [pattern.sub(rf"{point}_\1", line) for line in force]
