r"""The velocity-stage loop generated for one small system and one method: the sweep of
Hamilton's equations with every stage value a scalar.

For :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v - U(t, q)` whose velocity has a
closed form (``point_velocity``: a diagonal :math:`M`, or at most two coordinates),
:func:`galerkin_vi.loops.varying_mass_loop` iterates, with Gauss collocation of
:math:`r` points (:mod:`galerkin_vi.method.velocity_stages`),

.. math::

    Q_i = q_k + h\sum_j a_{ij} V_j, \quad P_i = p_k + h\sum_j \bar a_{ij} F_j, \quad
    V_i = M(Q_i)^{-1}\big(P_i - a(Q_i)\big), \quad F_i = (L_q + f)(Q_i, V_i),

to round-off. Here the same loop is written once more for one system and one method:
the loops over the stages and coordinates are unrolled, the stage values
:math:`Q_i, P_i, V_i, F_i` are local scalars, the velocity and force are the
``point_velocity`` function's own text at the stage's scalars (so the same rounding),
and each table entry is a literal (its shortest round-trip decimal, so the same
double). A term whose table entry is exactly zero is left out and a sum starts from
its first term, not ``0.0``; every other sum adds its terms in the shared loop's
order, so the states, sweeps and rows are the shared loop's bit for bit, up to the
sign of an exact zero. The hand-over rule (``contraction``, ``allowance``) stays an argument: a step
the shared loop would not take ends the function with its status, and the run
continues with Newton from the last row, as after the shared loop
(:func:`galerkin_vi.run.segment.run_segment`).
"""

from __future__ import annotations

import numpy as np

from .explicit_steps import compensated_lines, indented, initial_state_lines
from .method_steps import (
    METHOD_UNROLLED,
    RETURN_LINES,
    kept_row_lines,
    literal,
    step_end_lines,
    weighted_sum,
)

__all__ = [
    "VELOCITY_LOOP_TEXT",
    "has_velocity_steps",
    "render_velocity_module",
    "velocity_text_lines",
]

#: the name of the point module's record of what its velocity-stage loops are written from
VELOCITY_LOOP_TEXT = "VELOCITY_LOOP_TEXT"

_STATUS_OK = 0
_STATUS_NEWTON_FAILED = 1
_STATUS_NONFINITE = 3

IMPORTS = [
    "from galerkin_vi.loops.stage_form import too_slow",
    "from galerkin_vi.loops.varying_mass import (",
    "    ROUNDOFF_CHANGE, ROUNDOFF_FLOOR, ROUNDOFF_STALL, SWEEP_MEMORY,",
    ")",
]


def has_velocity_steps(n: int, tables) -> bool:
    """Whether a system of ``n`` coordinates gets a loop written for the method of
    ``tables`` (its stages times ``n`` at most :data:`.method_steps.METHOD_UNROLLED`)."""
    return len(tables.b) * n <= METHOD_UNROLLED


def velocity_text_lines(
    velocity: list[str], force: list[str], n: int, periodic: tuple[bool, ...]
) -> list[str]:
    """Lines of the point module recording what its velocity-stage loops are written
    from: ``velocity``, the lines setting ``V_a`` and ``F_a`` from ``q_a``, ``p_a``
    (``point_velocity``), and ``force``, those setting ``F_a`` from ``q_a``, ``v_a``
    (the ``L_q + f`` of ``point_mass``), with ``t`` and ``prm``."""
    record = {
        "velocity": tuple(velocity),
        "force": tuple(force),
        "n": n,
        "periodic": tuple(bool(x) for x in periodic),
    }
    return [f"{VELOCITY_LOOP_TEXT} = {record!r}"]


def _at(lines: tuple[str, ...], names: dict[str, str]) -> list[str]:
    """``lines`` with each whole-word scalar ``x_a`` (``x`` a key of ``names``) renamed
    ``names[x]_a``, and the temporaries ``_xN`` kept."""
    import re

    pattern = re.compile(r"\b(" + "|".join(names) + r")_(\d+)\b")
    return [pattern.sub(lambda m: f"{names[m.group(1)]}_{m.group(2)}", line) for line in lines]


def render_velocity_steps(text: dict, b, c, A, Abar, X) -> list[str]:  # noqa: N803
    """Source lines of ``velocity_steps`` for the system of ``text``
    (:func:`velocity_text_lines`) and the method of tables ``b, c, A, Abar, X``
    (:class:`~galerkin_vi.method.velocity_stages.VaryingMassTables`).

    Its arguments are those of :func:`galerkin_vi.loops.varying_mass_loop` less the
    point functions, traits, pattern and angle mask (the tables are accepted and not
    read); its result is the loop's 5-tuple.
    """
    n, periodic = text["n"], text["periodic"]
    b, c = [float(x) for x in b], [float(x) for x in c]
    A, Abar, X = (np.asarray(x, dtype=float) for x in (A, Abar, X))  # noqa: N806
    r = len(b)
    coords = range(n)
    stages = range(r)
    lines = [
        "",
        "",
        "def velocity_steps(q0, p0, v0, t0, h, n_steps, save_every, prm, b, c, A, Abar, X,"
        " tol, maxiter, contraction, allowance, t_out, q_out, p_out, turns_out,"
        " iterations_out, iteration_total):",
    ]
    body = initial_state_lines(n, periodic, [])
    # the first step starts from v0 and the force at (q0, v0) at every stage
    body += [f"v_{a} = v0[{a}]" for a in coords]
    body += ["t = t0"] + [f"F_{a} = 0.0" for a in coords] + list(text["force"])
    for i in stages:
        body += [f"V_{i}_{a} = v_{a}" for a in coords] + [f"F_{i}_{a} = F_{a}" for a in coords]
    body += [f"Q_{i}_{a} = 0.0" for i in stages for a in coords]
    body += [f"P_{i}_{a} = 0.0" for i in stages for a in coords]
    body += [
        "worst = 0.0",
        "mean_sweeps = 0.0",
        "change = np.inf",
        "countdown = save_every",
        "row_its = 0",
        "total = 0",
        "for k in range(n_steps):",
    ]
    step = ["tk = t0 + k * h"]

    def combination(weights, values: str, a: int) -> str:
        """``sum_j weights[j] values_j_a`` over the nonzero weights, in order."""
        return weighted_sum([(literal(w), f"{values}_{j}_{a}") for j, w in enumerate(weights) if w])

    extrapolate = []
    for i in stages:
        for a in coords:
            extrapolate.append(f"xv_{i}_{a} = {combination(X[i], 'V', a)}")
            extrapolate.append(f"xf_{i}_{a} = {combination(X[i], 'F', a)}")
    extrapolate += [f"V_{i}_{a} = xv_{i}_{a}" for i in stages for a in coords]
    extrapolate += [f"F_{i}_{a} = xf_{i}_{a}" for i in stages for a in coords]
    step += ["if k > 0:", *indented(extrapolate, 1)]
    step += [f"sq_{a} = 1.0 / (1.0 + abs(q_{a}))" for a in coords]
    step += [f"sp_{a} = 1.0 / (1.0 + abs(p_{a}))" for a in coords]
    step += [
        f"status = {_STATUS_NEWTON_FAILED}",
        "its = 0",
        "change = np.inf",
        "previous = np.inf",
        "earlier = np.inf",
    ]

    def stage_values(compare: bool) -> list[str]:
        out = []
        for i in stages:
            for a in coords:
                accq, accp = combination(A[i], "V", a), combination(Abar[i], "F", a)
                if not compare:
                    out.append(f"Q_{i}_{a} = q_{a} + h * ({accq})")
                    out.append(f"P_{i}_{a} = p_{a} + h * ({accp})")
                    continue
                out += [
                    f"new_q = q_{a} + h * ({accq})",
                    f"new_p = p_{a} + h * ({accp})",
                    f"if new_q != Q_{i}_{a} or new_p != P_{i}_{a}:",
                    "    moved = True",
                    f"    dq_abs = abs(new_q - Q_{i}_{a}) * sq_{a}",
                    f"    dp_abs = abs(new_p - P_{i}_{a}) * sp_{a}",
                    "    if not dq_abs <= change_q:",
                    "        change_q = dq_abs",
                    "    if not dp_abs <= change_p:",
                    "        change_p = dp_abs",
                    f"Q_{i}_{a} = new_q",
                    f"P_{i}_{a} = new_p",
                ]
        return out

    # the first iterate's stage positions and momenta (the shared loop's pass at its = 0)
    step += stage_values(compare=False)
    sweep = ["its += 1"]
    for i in stages:
        sweep += [f"t = tk + {literal(c[i])} * h"]
        sweep += [f"V_{i}_{a} = 0.0" for a in coords] + [f"F_{i}_{a} = 0.0" for a in coords]
        sweep += _at(text["velocity"], {"q": f"Q_{i}", "p": f"P_{i}", "V": f"V_{i}", "F": f"F_{i}"})
    sweep += ["change_q = 0.0", "change_p = 0.0", "moved = False", *stage_values(compare=True)]
    sweep += [
        "change = max(change_q, change_p)",
        "if not moved:",
        f"    status = {_STATUS_OK}",
        "    break",
        "if not change < 1e300:",
        f"    status = {_STATUS_NONFINITE}",
        "    break",
        "if its >= 2 and change >= previous and (change < ROUNDOFF_FLOOR or (change <"
        " ROUNDOFF_CHANGE and change >= ROUNDOFF_STALL * earlier)):",
        f"    status = {_STATUS_OK}",
        "    break",
        "if its >= maxiter:",
        "    break",
        "if contraction < np.inf and too_slow(change, previous, its, contraction, maxiter, tol):",
        "    break",
        "earlier = previous",
        "previous = change",
    ]
    step += ["while True:", *indented(sweep, 1)]
    step += ["if its > row_its:", "    row_its = its", "total += its"]
    end = []
    for a in coords:
        end.append(f"dq_{a} = h * ({combination(b, 'V', a)})")
        end.append(f"dp_{a} = h * ({combination(b, 'F', a)})")
    finite = " and ".join(f"abs(dq_{a}) < 1e300 and abs(dp_{a}) < 1e300" for a in coords)
    end += [f"if not ({finite}):", f"    status = {_STATUS_NONFINITE}"]
    step += [f"if status == {_STATUS_OK}:", *indented(end, 1)]
    step += [
        f"if status == {_STATUS_OK}:",
        "    if k <= 1:",
        "        mean_sweeps = float(its)",
        "    else:",
        "        mean_sweeps = SWEEP_MEMORY * mean_sweeps + (1 - SWEEP_MEMORY) * its",
        f"    if k >= 1 and mean_sweeps > allowance + {r}:",
        f"        status = {_STATUS_NEWTON_FAILED}",
    ]
    kept = kept_row_lines(n, periodic, "change")
    step += [f"if status != {_STATUS_OK}:", *indented(kept, 1)]
    step += compensated_lines("p", "e", "dp", n) + compensated_lines("q", "l", "dq", n)
    step += step_end_lines(n, periodic)
    return lines + indented([*body, *indented(step, 1), *RETURN_LINES], 1)


def render_velocity_module(text: dict, tables, key: str) -> str:
    """Source of the module holding ``velocity_steps`` for the system whose point module
    recorded ``text`` and the method of ``tables``; ``key`` opens and closes it."""
    head = [
        f"# galerkin_vi per-method velocity-stage loop {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
        "import numpy as np",
        "",
        *IMPORTS,
    ]
    body = render_velocity_steps(text, *tables.loop_arguments)
    tail = ["", "", f"# end of galerkin_vi per-method velocity-stage loop {key}", ""]
    return "\n".join([*head, *body, *tail])
