r"""The stage-form loop generated for one small system and one method: coordinates,
stage values and the method's tables as scalars.

:mod:`.stage_steps` writes the constant-mass fixed point of the stage form once per
system, with the method's tables as arguments and loops over its stages. Here the
same loop is written once more for one Gauss or Lobatto method: every loop over
the quadrature points, the implicit stages and the control points is unrolled,
the stage increments :math:`Z_i`, the forces :math:`F_j` and the control points
are local scalars, and each table entry is a literal (its shortest round-trip
decimal, so the same double). Products of a table entry with :math:`h` or
:math:`h^2` are formed once per call. A term whose table entry is exactly zero is
left out (:math:`x + 0\cdot F = x` for finite :math:`F`), and a sum the shared loop
starts from ``0.0`` starts from its first term; every other sum adds its terms in the
shared loop's order, so states, sweeps and rows are the shared loop's bit for bit, up
to the sign of an exact zero (where the shared loop's sum gives ``0.0``, this one may
give ``-0.0``).

The iteration, per step :math:`k`, is that of :mod:`.stage_steps`:

.. math::

    Z_i \leftarrow M^{-1}\Big(h\,\hat c_i\,p_k + h^2\sum_{j\ \text{known}} \hat W_{ij} F_j
        + h^2 \sum_{j\ \text{implicit}} \hat W_{ij}\,F(t_k + c_j h,\ q_k + Z_j)\Big),

from the first iterate of extrapolated forces, with the shared stopping rule
(``too_slow``, ``newton_status``); at the end of the step the control points
:math:`C_\mu = M^{-1}(h\hat c_\mu p_k + h^2\sum_j \hat W_{\mu j}F_j)` that are
needed, the forces at the remaining points, and
:math:`p_{k+1} = p_k + h\sum_j b_j F_j`, :math:`q_{k+1} = q_k + C_s` with
compensated sums. A step the fixed point cannot take ends the function with
status 1, as :mod:`.stage_steps` does, for the shared loop to continue.
"""

from __future__ import annotations

import hashlib

import numpy as np

from .explicit_steps import (
    compensated_lines,
    indented,
    initial_state_lines,
    row_lines,
    saved_row_lines,
    wrap_lines,
)
from .stage_steps import IMPORTS, SWEEP_END, force_at

__all__ = [
    "LOOP_TEXT",
    "RETURN_LINES",
    "METHOD_UNROLLED",
    "step_end_lines",
    "has_method_steps",
    "kept_row_lines",
    "literal",
    "weighted_sum",
    "loop_text_lines",
    "method_digest",
    "render_method_module",
    "render_method_steps",
]

#: the name of the point module's record of what its per-method loops are written from
LOOP_TEXT = "STAGE_LOOP_TEXT"

#: the most stage unknowns (implicit points times coordinates) a loop is written out for:
#: numba's compile time grows with the text, about 0.6 s + 0.11 s per unknown
#: (docs/design-notes.md); beyond it the system's own loop (:mod:`.stage_steps`) serves
METHOD_UNROLLED = 24

_STATUS_OK = 0
_STATUS_NEWTON_FAILED = 1
_STATUS_SINGULAR = 2
_STATUS_NONFINITE = 3


#: the return of a loop that counts its sweeps in locals, after its last step
RETURN_LINES = ["iteration_total[0] += total", f"return {_STATUS_OK}, n_steps, saved, worst, 0.0"]


def step_end_lines(n: int, periodic: tuple[bool, ...]) -> list[str]:
    """The end of a step of a loop that counts its sweeps in locals (``row_its``,
    ``total``): the angles wrapped, and the row due after step ``k`` saved with its
    sweeps, found by a count down (``countdown``, from ``save_every``) rather than
    ``(k + 1) % save_every``, whose integer division is a share of a small system's step."""
    row = row_lines("saved", "t0 + (k + 1) * h", "q", "p", n, periodic, "l", "r")
    wraps = [line for a in range(n) if periodic[a] for line in wrap_lines(a)]
    return [
        *wraps,
        "countdown -= 1",
        "if countdown == 0 or k + 1 == n_steps:",
        "    if row_its > iterations_out[saved - 1]:",
        "        iterations_out[saved - 1] = row_its",
        "    row_its = 0",
        *indented([*row, "saved += 1", "countdown = save_every"], 1),
    ]


def kept_row_lines(n: int, periodic: tuple[bool, ...], change: str) -> list[str]:
    """The return of a loop that counts its sweeps in locals, at a step ``k`` it does not
    take: the sweeps written into the rows' records, the state before the step saved as
    the last row (due or not), and the loop's 5-tuple with ``change`` last."""
    return [
        "if row_its > iterations_out[saved - 1]:",
        "    iterations_out[saved - 1] = row_its",
        "iteration_total[0] += total",
        *saved_row_lines("k % save_every != 0", "tk", "q", "p", n, periodic, "l", "r"),
        f"return status, k, saved, worst, {change}",
    ]


def has_method_steps(n: int, tables) -> bool:
    """Whether a system of ``n`` coordinates gets a loop written for the method of
    ``tables`` (its implicit points times ``n`` at most :data:`METHOD_UNROLLED`)."""
    return len(tables.implicit) * n <= METHOD_UNROLLED


def method_digest(b, c, tables) -> str:
    """A digest of a method's stage-form tables (``b``, ``c`` and
    :class:`~galerkin_vi.method.stage_form.SeparableTables`): the part of a per-method
    loop's cache key that names the method."""
    h = hashlib.sha256()
    for array in (b, c, *tables.loop_arguments):
        a = np.ascontiguousarray(array)
        h.update(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes())
    return h.hexdigest()[:24]


def literal(x: float) -> str:
    """``x`` as a literal that parses to the same double (negative ones in brackets)."""
    text = repr(float(x))
    return f"({text})" if text.startswith("-") else text


def weighted_sum(terms: list[tuple[str, str]], start: str | None = None) -> str:
    """``start + w1 * x1 + w2 * x2 + ...`` added left to right (the shared loop's
    order); ``"0.0"`` for no terms and no start."""
    parts = [] if start is None else [start]
    parts += [f"{w} * {x}" for w, x in terms]
    return " + ".join(parts) if parts else "0.0"


def render_method_steps(
    force: list[str],
    mass: list[str],
    n: int,
    periodic: tuple[bool, ...],
    autonomous: bool,
    b,
    c,
    tables,
) -> list[str]:
    """Source lines of ``method_steps``, the stage-form loop of one system and one method.

    The arguments and result are those of :func:`.stage_steps.render_stage_steps`'s
    ``stage_steps`` (the table arguments are accepted and not read: the method's
    tables ``b``, ``c`` and ``tables``, a
    :class:`~galerkin_vi.method.stage_form.SeparableTables`, are written into the text).
    """
    b = [float(x) for x in b]
    c = [float(x) for x in c]
    implicit = [int(j) for j in tables.implicit]
    known = [int(j) for j in tables.known]
    rest = [int(j) for j in tables.rest]
    stage_p = np.asarray(tables.stage_p, dtype=float)
    stage_force = np.asarray(tables.stage_force, dtype=float)
    control_p = np.asarray(tables.control_p, dtype=float)
    control_force = np.asarray(tables.control_force, dtype=float)
    Phi1 = np.asarray(tables.Phi1, dtype=float)  # noqa: N806
    X = np.asarray(tables.force_extrapolation, dtype=float)  # noqa: N806
    reuse = bool(tables.reuse_endpoint)
    r, u, s = len(b), len(implicit), control_p.shape[0]
    coords = range(n)

    def time(j: int) -> str:
        return "0.0" if autonomous else f"tk + {literal(c[j])} * h"

    def forces_at(j: int, point: str, target: str) -> list[str]:
        lines = [f"t = {time(j)}", *force_at(point, force)]
        return lines + [f"{target}_{a} = g_{a}" for a in coords]

    needed = {s - 1} | {mu for j in rest for mu in range(s) if Phi1[j, mu] != 0.0}
    lines = [
        "",
        "",
        "def method_steps(q0, p0, v0, t0, h, n_steps, save_every, prm, b, c, implicit, known,"
        " rest, stage_p, stage_a, stage_force, control_p, control_a, control_force, Phi1, X,"
        " reuse_endpoint, tol, maxiter, cheap_first, t_out, q_out, p_out, turns_out,"
        " iterations_out, iteration_total):",
    ]
    body = initial_state_lines(n, periodic, ["t = t0", *mass])
    regular = " and ".join(f"m_{a} != 0.0" for a in coords)
    body += [f"if not ({regular}):", f"    return {_STATUS_SINGULAR}, 0, saved, 0.0, np.inf"]
    body += [f"w_{a} = 1.0 / m_{a}" for a in coords]
    body += [
        f"Z_{i}_{a} = {literal(c[implicit[i]])} * h * v0[{a}]" for i in range(u) for a in coords
    ]
    body += ["h2 = h * h"]
    # the table entries times h or h^2, once per call (the shared loop's products)
    body += [f"hp_{i} = h * {literal(stage_p[i])}" for i in range(u)]
    body += [f"hc_{mu} = h * {literal(control_p[mu])}" for mu in sorted(needed)]
    weights: dict[tuple[int, int], str] = {}
    for i in range(u):
        for j in range(r):
            if stage_force[i, j] != 0.0:
                weights[i, j] = f"W_{i}_{j}"
                body.append(f"W_{i}_{j} = h2 * {literal(stage_force[i, j])}")
    body += [f"F_{j}_{a} = 0.0" for j in range(r) for a in coords]
    body += [f"X_{i}_{a} = 0.0" for i in range(u) for a in coords]
    if X.shape[1] == 3 * r and u:
        body += [f"L_{j}_{a} = 0.0" for j in range(r) for a in coords if X[:, r + j].any()]
    body += [
        f"contraction = min(MASS_CONTRACTION_MAX, MASS_CONTRACTION * {u} * {n})",
        "budget = max(maxiter // 2, maxiter - NEWTON_RESERVE)",
        "worst = 0.0",
        "have_start_force = False",
        "increment = 0.0",
        "countdown = save_every",
        "row_its = 0",
        "total = 0",
        "for k in range(n_steps):",
    ]
    step = ["tk = t0 + k * h"]
    start_forces = [line for j in known for line in forces_at(j, "q", f"F_{j}")]
    if reuse and autonomous:
        step += ["if not have_start_force:", *indented(start_forces, 1)]
    else:
        step += start_forces
    for i in range(u):
        for a in coords:
            terms = [(weights[i, j], f"F_{j}_{a}") for j in known if (i, j) in weights]
            step.append(f"o_{i}_{a} = {weighted_sum(terms, f'hp_{i} * p_{a}')}")
    first = []
    for i in range(u):
        for a in coords:
            terms = [(weights[i, implicit[m]], f"X_{m}_{a}") for m in range(u)
                     if (i, implicit[m]) in weights]  # fmt: skip
            first.append(f"Z_{i}_{a} = ({weighted_sum(terms, f'o_{i}_{a}')}) * w_{a}")
    if first:
        step += ["if k > 0:", *indented(first, 1)]
    step += [
        "its = 0",
        "increment = 0.0",
        "residual = 0.0",
        "current = False",
        f"status = {_STATUS_NEWTON_FAILED if u else _STATUS_OK}",
        "previous = np.inf",
        "base = 0.0",
    ]
    step += [f"base = max(base, abs(q_{a}))" for a in coords]
    step += ["step_size = 0.0"]
    step += [f"step_size = max(step_size, abs(Z_{i}_{a}))" for i in range(u) for a in coords]
    # the stage positions q_k + Z_i, formed once per update and read by the force, the
    # test of a bit-identical sweep and the next sweep
    step += [f"P_{i}_{a} = q_{a} + Z_{i}_{a}" for i in range(u) for a in coords]
    implicit_forces = []
    for m, j in enumerate(implicit):
        implicit_forces += forces_at(j, f"P_{m}", f"F_{j}")
    sweep = ["its += 1", *implicit_forces]
    sweep += ["residual = 0.0", "increment = 0.0", "size = step_size", "shift = 0.0"]
    for i in range(u):
        for a in coords:
            terms = [(weights[i, j], f"F_{j}_{a}") for j in implicit if (i, j) in weights]
            sweep += [
                f"old = Z_{i}_{a}",
                f"updated = ({weighted_sum(terms, f'o_{i}_{a}')}) * w_{a}",
                "dz = abs(updated - old)",
                "if dz > increment:",
                "    increment = dz",
                f"if m_{a} * dz > residual:",
                f"    residual = m_{a} * dz",
                f"moved = q_{a} + updated",
                f"shift += abs(moved - P_{i}_{a})",
                f"Z_{i}_{a} = updated",
                f"P_{i}_{a} = moved",
            ]
    sweep += SWEEP_END
    if u:
        step += ["while its < maxiter:", *indented(sweep, 1)]
    kept = kept_row_lines(n, periodic, "increment")
    step += [f"if status == {_STATUS_NEWTON_FAILED}:", *indented(kept, 1)]
    step += [
        "if its > row_its:",
        "    row_its = its",
        "total += its",
        f"if status == {_STATUS_OK}:",
    ]
    end = ["if not current:", *indented(implicit_forces, 1)] if u else []
    for mu in sorted(needed):
        for a in coords:
            terms = [(literal(control_force[mu, j]), f"F_{j}_{a}") for j in range(r)
                     if control_force[mu, j] != 0.0]  # fmt: skip
            end.append(f"C_{mu}_{a} = (hc_{mu} * p_{a} + h2 * ({weighted_sum(terms)})) * w_{a}")
    for j in rest:
        for a in coords:
            terms = [(literal(Phi1[j, mu]), f"C_{mu}_{a}") for mu in range(s) if Phi1[j, mu] != 0.0]
            end.append(f"Q_{a} = q_{a} + ({weighted_sum(terms)})")
        end += forces_at(j, "Q", f"F_{j}")
    for a in coords:
        terms = [(literal(b[j]), f"F_{j}_{a}") for j in range(r) if b[j] != 0.0]
        end.append(f"d_{a} = h * ({weighted_sum(terms)})")
    finite = " and ".join(f"abs(C_{s - 1}_{a}) < 1e300 and abs(d_{a}) < 1e300" for a in coords)
    end += [f"if not ({finite}):", f"    status = {_STATUS_NONFINITE}"]
    step += indented(end, 1)
    step += [f"if status != {_STATUS_OK}:", *indented(kept, 1)]
    step += ["if residual > worst:", "    worst = residual"]
    step += compensated_lines("p", "e", "d", n)
    # the next step's forces from this step's, or with a two-step table
    # (SeparableTables.force_extrapolation of shape (u, 3 r)) after the first step from
    # this step's and the last step's (older first)
    two_step = X.shape[1] == 3 * r and u > 0
    old_forces = [j for j in range(r) if two_step and X[:, r + j].any()]
    one, two = [], []
    for i in range(u):
        for a in coords:
            terms = [(literal(X[i, j]), f"F_{j}_{a}") for j in range(r) if X[i, j] != 0.0]
            one.append(f"X_{i}_{a} = {weighted_sum(terms)}")
            if two_step:
                terms = [(literal(X[i, r + j]), f"L_{j}_{a}") for j in old_forces
                         if X[i, r + j] != 0.0]  # fmt: skip
                terms += [(literal(X[i, 2 * r + j]), f"F_{j}_{a}") for j in range(r)
                          if X[i, 2 * r + j] != 0.0]  # fmt: skip
                two.append(f"X_{i}_{a} = {weighted_sum(terms)}")
    if u and two_step:
        step += ["if k > 0:", *indented(two, 1), "else:", *indented(one, 1)]
    else:
        step += one
    step += [f"L_{j}_{a} = F_{j}_{a}" for j in old_forces for a in coords]
    if reuse:
        step += [f"F_0_{a} = F_{r - 1}_{a}" for a in coords] + ["have_start_force = True"]
    step += compensated_lines("q", "l", f"C_{s - 1}", n)
    step += step_end_lines(n, periodic)
    return lines + indented([*body, *indented(step, 1), *RETURN_LINES], 1)


def loop_text_lines(
    force: list[str], mass: list[str], n: int, periodic: tuple[bool, ...], autonomous: bool
) -> list[str]:
    """Lines of the point module recording what its per-method loops are written from:
    the force and mass lines of :mod:`.stage_steps` and the system's shape."""
    record = {
        "force": tuple(force),
        "mass": tuple(mass),
        "n": n,
        "periodic": tuple(bool(x) for x in periodic),
        "autonomous": bool(autonomous),
    }
    return [f"{LOOP_TEXT} = {record!r}"]


def render_method_module(text: dict, b, c, tables, key: str) -> str:
    """Source of the module holding ``method_steps`` for the system whose point module
    recorded ``text`` (:func:`loop_text_lines`) and the method of tables ``b``, ``c``,
    ``tables``; ``key`` opens and closes it, as in a point module."""
    head = [
        f"# galerkin_vi per-method stage loop {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
        "import numpy as np",
        "",
        *IMPORTS,
    ]
    body = render_method_steps(
        list(text["force"]), list(text["mass"]), text["n"], text["periodic"],
        text["autonomous"], b, c, tables,
    )  # fmt: skip
    tail = ["", "", f"# end of galerkin_vi per-method stage loop {key}", ""]
    return "\n".join([*head, *body, *tail])
