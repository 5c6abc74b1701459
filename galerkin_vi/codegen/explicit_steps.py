r"""The explicit loop generated for one small system: its coordinates as scalars,
its force inline.

The shared explicit loop (:mod:`galerkin_vi.loops.explicit`) runs every system's
compositions of Störmer–Verlet through arrays of run-time length and one call
of the point function per sub-step. For a system of a few coordinates that
bookkeeping is most of a sub-step. For such systems the generator writes the
same loop once more, for this system alone: the coordinates and momenta are
local scalars, the force :math:`F(t, q) = L_q + f` is the point function's own
text at :math:`v = 0` (:func:`.source.at_rest`: the same common subexpressions,
so the same rounding) written where it is used, and only the parameters,
:math:`M^{-1}` and the sub-step fractions stay arguments (one compiled function
serves every composition, step and parameter value). The states are the shared
loop's bit for bit.

A sub-step with drift :math:`a_i` and kicks :math:`\beta^\pm_i` is the shared
loop's, with :math:`a(t) = L_v(t, q, 0) \equiv 0` (systems with a gyroscopic
term keep the shared loop):

.. math::

    u = p + \beta^-_i h\,F(\tau_{i-1}, q),\quad
    q' = q + a_i h\,M^{-1}u,\quad
    p' = p + h\big(\beta^-_i F(\tau_{i-1}, q) + \beta^+_i F(\tau_i, q')\big),

the force at a sub-step's end being the next one's start. With any angle
among the coordinates every coordinate is drifted with compensated summation,
and the angles are wrapped into :math:`[-\pi, \pi)` once per step, as in the
shared loop, whose arguments, outputs and 5-tuple result the
generated function shares (:mod:`galerkin_vi.loops.abi`).
"""

from __future__ import annotations

import sympy as sp

__all__ = [
    "EXPLICIT_UNROLLED",
    "compensated_lines",
    "has_generated_loops",
    "initial_state_lines",
    "indented",
    "render_explicit_steps",
    "row_lines",
    "saved_row_lines",
    "wrap_lines",
]

#: the largest system whose explicit loop is generated with scalar coordinates: beyond
#: it the force dominates a sub-step and the shared loop's arrays cost little
EXPLICIT_UNROLLED = 24

# the loops' status codes (galerkin_vi.loops.abi), written into the generated text
_STATUS_OK = 0
_STATUS_NONFINITE = 3
# 2 pi as a sum of two doubles (galerkin_vi.loops.common): a turn removed exactly
_TWO_PI_HI = 6.283185307179586
_TWO_PI_LO = 2.4492935982947064e-16


def has_generated_loops(system, pieces) -> bool:
    r"""Whether the generator writes the system's own explicit loop (and, with a
    diagonal mass, stage-form loop).

    For a separable :math:`L = \tfrac12 v^TMv - V(t, q)` (constant :math:`M`, no
    gyroscopic term, forces free of :math:`v`) without constraints, of at most
    :data:`EXPLICIT_UNROLLED` coordinates. :func:`.spec.kernel_spec` also asks for
    straight-line point functions, which the loops copy: no repeated terms (where
    the point functions loop over a pair potential, the force is most of a
    sub-step, and written out it takes seconds to compile: docs/design-notes.md).
    """
    structure = system.structure
    if system.m or system.n > EXPLICIT_UNROLLED:
        return False
    if not (structure.separable and structure.zero_fv):
        return False
    at_rest = {v: sp.Integer(0) for v in system.v}
    return all(e.xreplace(at_rest) == 0 for e in pieces.Lv)


def indented(lines: list[str], depth: int) -> list[str]:
    """``lines`` indented by ``depth`` levels of four spaces."""
    pad = "    " * depth
    return [pad + line for line in lines]


def row_lines(
    row: str, t: str, q: str, p: str, n: int, periodic: tuple[bool, ...], lost: str, turns: str
) -> list[str]:
    """Lines saving ``(t, q, p)`` into output row ``row`` (angles with their compensation)."""
    lines = [f"t_out[{row}] = {t}"]
    for a in range(n):
        if periodic[a]:
            lines.append(f"q_out[{row}, {a}] = {q}_{a} - {lost}_{a}")
            lines.append(f"turns_out[{row}, {a}] = {turns}_{a}")
        else:
            lines.append(f"q_out[{row}, {a}] = {q}_{a}")
        lines.append(f"p_out[{row}, {a}] = {p}_{a}")
    return lines


def saved_row_lines(
    condition: str, t: str, q: str, p: str, n: int, periodic: tuple[bool, ...], lost: str,
    turns: str,
) -> list[str]:  # fmt: skip
    """Lines saving ``(t, q, p)`` as the next row (``saved``) when ``condition`` holds."""
    row = row_lines("saved", t, q, p, n, periodic, lost, turns)
    return [f"if {condition}:", *indented(row, 1), "    saved += 1"]


def initial_state_lines(n: int, periodic: tuple[bool, ...], setup: list[str]) -> list[str]:
    """The start of an implicit loop of one system: ``q_a``, ``p_a`` from ``q0``, ``p0``,
    the lines ``setup`` (at ``t = t0``, before the angles wrap), the compensations
    ``l_a``, ``e_a`` and turns ``r_a`` zeroed, the angles wrapped, row 0 saved."""
    angles = [a for a in range(n) if periodic[a]]
    lines = [f"q_{a} = q0[{a}]" for a in range(n)] + [f"p_{a} = p0[{a}]" for a in range(n)]
    lines += setup
    lines += [f"l_{a} = 0.0" for a in range(n)] + [f"e_{a} = 0.0" for a in range(n)]
    lines += [f"r_{a} = 0.0" for a in angles]
    for a in angles:
        lines += wrap_lines(a)
    return [*lines, *row_lines("0", "t0", "q", "p", n, periodic, "l", "r"), "saved = 1"]


def compensated_lines(x: str, lost: str, d: str, n: int) -> list[str]:
    """Lines adding ``{d}_a`` to ``{x}_a`` for every coordinate with Kahan compensation
    in ``{lost}_a``, as the shared loops' ``compensated_add`` and ``advance_position``."""
    lines = []
    for a in range(n):
        lines += [
            f"_y = {d}_{a} - {lost}_{a}",
            f"_s = {x}_{a} + _y",
            f"{lost}_{a} = (_s - {x}_{a}) - _y",
            f"{x}_{a} = _s",
        ]
    return lines


def wrap_lines(a: int) -> list[str]:
    """Lines translating angle ``q_a`` by whole turns into [-pi, pi) (:func:`wrap_angles`)."""
    # the corrections run only for an angle outside the interval: one test per step
    return [
        f"if not -math.pi <= q_{a} < math.pi:",
        f"    _k = np.floor((q_{a} + math.pi) / {_TWO_PI_HI!r})",
        f"    q_{a} -= _k * {_TWO_PI_HI!r}",
        f"    l_{a} += _k * {_TWO_PI_LO!r}",
        f"    r_{a} += _k",
        f"    while q_{a} >= math.pi:",
        f"        q_{a} -= {_TWO_PI_HI!r}",
        f"        l_{a} += {_TWO_PI_LO!r}",
        f"        r_{a} += 1.0",
        f"    while q_{a} < -math.pi:",
        f"        q_{a} += {_TWO_PI_HI!r}",
        f"        l_{a} -= {_TWO_PI_LO!r}",
        f"        r_{a} -= 1.0",
    ]


def render_explicit_steps(
    force: list[str],
    n: int,
    periodic: tuple[bool, ...],
    diagonal_mass: bool,
    autonomous: bool,
    name: str = "explicit_steps",
) -> list[str]:
    """Source lines of ``explicit_steps`` (or ``name``), the explicit loop of one system.

    Its arguments are those of :func:`galerkin_vi.loops.explicit.explicit_loop`
    less the point functions and the compiled switches: ``(q0, p0, t0, h, n_steps,
    save_every, prm, Minv, drift, kick_before, kick_after, nodes, t_out, q_out,
    p_out, turns_out)``. ``force`` holds the lines, unindented, that set ``g_a`` from
    ``t``, the scalars ``q_a`` and ``prm`` (the point function's text, :func:`.source.at_rest`).
    """
    angles = [a for a in range(n) if periodic[a]]
    # with any angle the shared loop drifts every coordinate with compensation (its
    # switch is the whole mask), and so does this one
    compensated = list(range(n)) if angles else []
    lines = [
        "",
        "",
        f"def {name}(q0, p0, t0, h, n_steps, save_every, prm, Minv, drift, kick_before,"
        " kick_after, nodes, t_out, q_out, p_out, turns_out):",
    ]
    body = [f"q_{a} = q0[{a}]" for a in range(n)] + [f"p_{a} = p0[{a}]" for a in range(n)]
    body += [f"l_{a} = 0.0" for a in compensated] + [f"r_{a} = 0.0" for a in angles]
    for a in angles:
        body += wrap_lines(a)
    weights = {
        (a, b): f"w_{a}_{b}" for a in range(n) for b in range(n) if a == b or not diagonal_mass
    }
    body += [f"{name} = Minv[{a}, {b}]" for (a, b), name in weights.items()]
    body += ["m = drift.shape[0]", "t = t0"]
    body += force + [f"f_{a} = g_{a}" for a in range(n)]
    body += row_lines("0", "t0", "q", "p", n, periodic, "l", "r")
    body += ["saved = 1", "for k in range(n_steps):"]
    step = [f"b_{a} = q_{a}" for a in range(n)] + [f"c_{a} = p_{a}" for a in range(n)]
    step += [f"bl_{a} = l_{a}" for a in angles] + [f"br_{a} = r_{a}" for a in angles]
    step += ["for i in range(m):"]
    sub = ["eta = drift[i] * h", "before = kick_before[i] * h", "after = kick_after[i] * h"]
    if not autonomous:
        sub.append("t = t0 + (k + nodes[i]) * h")
    sub += [f"u_{a} = p_{a} + before * f_{a}" for a in range(n)]
    for a in range(n):
        product = " + ".join(f"{weights[a, b]} * u_{b}" for b in range(n) if (a, b) in weights)
        if compensated:
            # compensated, so that whole turns can be removed exactly
            sub += [
                f"_y = eta * ({product}) - l_{a}",
                f"_s = q_{a} + _y",
                f"l_{a} = (_s - q_{a}) - _y",
                f"q_{a} = _s",
            ]
        else:
            sub.append(f"q_{a} += eta * ({product})")
    if angles:
        sub.append("if i == m - 1:")
        sub += indented([line for a in angles for line in wrap_lines(a)], 1)
    sub += force
    sub += [f"p_{a} += before * f_{a} + after * g_{a}" for a in range(n)]
    sub += [f"f_{a} = g_{a}" for a in range(n)]
    step += indented(sub, 1)
    # the step's end state is tested, as in the shared loop
    bounded = " and ".join(f"abs({x}_{a}) < 1e300" for a in range(n) for x in ("p", "q"))
    step += [f"finite = {bounded}"]
    # the state before a step that overflows is the last row, due or not
    kept = saved_row_lines("k % save_every != 0", "t0 + k * h", "b", "c", n, periodic, "bl", "br")
    step += ["if not finite:", *indented(kept, 1)]
    step += [f"    return {_STATUS_NONFINITE}, k, saved, 0.0, np.nan"]
    due = "(k + 1) % save_every == 0 or k + 1 == n_steps"
    step += saved_row_lines(due, "t0 + (k + 1) * h", "q", "p", n, periodic, "l", "r")
    body += indented(step, 1)
    body.append(f"return {_STATUS_OK}, n_steps, saved, 0.0, np.nan")
    return lines + indented(body, 1)
