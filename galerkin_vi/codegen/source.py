"""Stage 2 of code generation: the point functions of one system as Python source.

:func:`render_module` runs one joint common-subexpression elimination per
point function and prints it with :class:`~galerkin_vi.printer.KernelPrinter`. The
functions are plain Python over indexable arguments: numba compiles each as a
C-callable function (:mod:`.compiled`), and the same text runs uncompiled on
NumPy arrays, which the tests use. Large systems are split into parts of
``POINT_CHUNK`` entries, each compiled once and called (numba's compile time
grows faster than linearly with a function's length).

The point functions' contract (:mod:`galerkin_vi.loops.point` has the C
signatures): they evaluate at one point ``(t, q, v)`` with parameter vector
``prm`` and write into preallocated arrays; entries that are identically zero
are never written (the caller zeroes those arrays once); second derivatives
are stored flat, dense (entry (a, b) at ``a n + b``) or, for banded systems,
in the order of the sparsity pattern.
"""

from __future__ import annotations

import re
from functools import lru_cache

import numpy as np
import sympy as sp

from ..printer import KernelPrinter
from .explicit_steps import render_explicit_steps
from .lanes import IDENTIFIER, lane_lines, lifted_statements
from .lanes import IMPORT as LANES_IMPORT
from .method_steps import METHOD_UNROLLED, loop_text_lines
from .repeats import Run, find_runs
from .scatter import ScatterGroup
from .spec import LARGE, KernelSpec, has_stage_steps
from .stage_steps import IMPORTS as STAGE_IMPORTS
from .stage_steps import render_stage_steps
from .velocity_steps import velocity_text_lines

__all__ = ["FUNCTIONS", "POINT_CHUNK", "render_module"]

#: the point functions a module may define: name -> parameters
FUNCTIONS = {
    "point_gradient": "t, q, v, prm, Lq, Lv",
    "point_hessian": "t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv",
    "lagrangian": "t, q, v, prm",
    "point_constraint": "t, q, prm, g",
    "point_constraint_jacobian": "t, q, prm, Gq",
    "point_constraint_rate": "t, q, prm, gt",
    "point_constraint_hessian": "t, q, lam, prm, Hg",
    "point_mass": "t, q, v, prm, Lq, Lv, Lqv, Lvv",
    "point_velocity": "t, q, p, prm, F, V",
    "point_contact": "t, q, v, prm, cg, cG, cH",
    "point_slip": "t, q, v, prm, w, Wq, Wv, Wvq",
}

# numba's compile time grows faster than linearly with a function's length: large
# point functions are split into parts of this many entries, compiled separately
POINT_CHUNK = 200
# Python's parser nests a + b + c + ... one level per operator: long sums are
# accumulated in chunks (a Lagrangian of 1000 springs otherwise fails to compile)
_SUM_CHUNK = 32


def _assignment(
    target: str, expr: sp.Expr, printer: KernelPrinter, accumulate: bool = False
) -> list[str]:
    terms = sp.Add.make_args(expr)
    op = "+=" if accumulate else "="
    if len(terms) <= _SUM_CHUNK:
        return [f"    {target} {op} {printer.doprint(expr)}"]
    chunks = [sp.Add(*terms[k : k + _SUM_CHUNK]) for k in range(0, len(terms), _SUM_CHUNK)]
    lines = [f"    {target} {op} {printer.doprint(chunks[0])}"]
    lines += [f"    {target} += {printer.doprint(chunk)}" for chunk in chunks[1:]]
    return lines


def shared_quarter_roots(exprs: list[sp.Expr]) -> tuple[list[sp.Expr], list[tuple]]:
    r"""Rewrite every :math:`b^{k/4}` as :math:`\rho_b^{\,k}`, one root :math:`\rho_b = b^{1/4}`.

    A step-size function :math:`g = r^{3/2} = (x^2 + y^2)^{3/4}` puts powers
    :math:`b^{-1/4}, b^{3/4}, b^{7/4}` of one base into the transformed
    Lagrangian's derivatives: one ``pow`` call each (20-40 ns). With the root
    computed once as two square roots, the others are products. Returns the
    rewritten expressions and the ``(symbol, base)`` pairs of the roots, in the
    order they must be computed.
    """
    roots: dict[sp.Expr, sp.Symbol] = {}

    def root(base: sp.Expr) -> sp.Symbol:
        if base not in roots:
            roots[base] = sp.Symbol(f"_r{len(roots)}", positive=True)
        return roots[base]

    def quarter(z: sp.Basic) -> bool:
        return bool(z.is_Pow and z.exp.is_Rational and z.exp.q == 4)

    rewritten = [e.replace(quarter, lambda z: root(z.base) ** z.exp.p) for e in exprs]
    if roots:
        # the square roots of a base with a quarter root are its squares: b^(k/2) = rho^(2k)
        def half(z: sp.Basic) -> bool:
            return bool(z.is_Pow and z.exp.is_Rational and z.exp.q == 2 and z.base in roots)

        rewritten = [e.replace(half, lambda z: roots[z.base] ** (2 * z.exp.p)) for e in rewritten]
    return rewritten, [(symbol, base) for base, symbol in roots.items()]


def shared_reciprocals(
    exprs: list[sp.Expr], roots: list[tuple]
) -> tuple[list[sp.Expr], list[tuple]]:
    r"""Rewrite every :math:`\rho^{-k}` of a root :math:`\rho` as :math:`\iota^{k}`,
    one reciprocal :math:`\iota = 1/\rho`.

    The transformed Lagrangian's derivatives divide by several powers of one root
    (:math:`\rho^{-1}, \rho^{-2}, \rho^{-6}, \dots`): a division each (4-20 times
    a multiplication), which numba does not merge without fast-math. With one
    reciprocal the others are products. Returns the rewritten expressions and the
    ``(symbol, root)`` pairs, computed after the roots.
    """
    reciprocals: dict[sp.Symbol, sp.Symbol] = {}
    symbols = {symbol for symbol, _ in roots}

    def inverse(z: sp.Basic) -> bool:
        return bool(z.is_Pow and z.base in symbols and z.exp.is_Integer and z.exp.is_negative)

    def rewrite(z: sp.Pow) -> sp.Expr:
        if z.base not in reciprocals:
            reciprocals[z.base] = sp.Symbol(f"_i{str(z.base)[2:]}", positive=True)
        return reciprocals[z.base] ** (-z.exp)

    rewritten = [e.replace(inverse, rewrite) for e in exprs]
    return rewritten, [(symbol, base) for base, symbol in reciprocals.items()]


def _function_body(
    entries: list[tuple[str, sp.Expr]],
    returns: sp.Expr | None = None,
    large: bool = False,
    accumulate: frozenset[str] = frozenset(),
) -> list[str]:
    # SymPy's "basic" CSE optimisations and sorted printing cost minutes on thousands
    # of entries (a chain of 1000 masses: 18 s against 1.2 s without); large systems
    # go without them
    small = not large
    printer = KernelPrinter(ordered=small)
    exprs = [e for _, e in entries] + ([returns] if returns is not None else [])
    exprs, roots = shared_quarter_roots(exprs)
    exprs, reciprocals = shared_reciprocals(exprs, roots)
    temporaries, reduced = sp.cse(
        exprs,
        symbols=sp.numbered_symbols("_x"),
        optimizations="basic" if small else None,
        order="canonical" if small else "none",
    )
    lines = [
        f"    {symbol} = math.sqrt(math.sqrt({printer.doprint(base)}))" for symbol, base in roots
    ]
    lines += [f"    {symbol} = 1.0 / {root}" for symbol, root in reciprocals]
    for sym, rhs in temporaries:
        lines += _assignment(str(sym), rhs, printer)
    for (slot, _), expr in zip(entries, reduced[: len(entries)], strict=True):
        lines += _assignment(slot, expr, printer, accumulate=slot in accumulate)
    if returns is not None:
        lines += _assignment("_result", reduced[-1], printer)
        lines.append("    return _result")
    return lines or ["    pass"]


def _loop_body(runs: list[Run]) -> list[str]:
    """Source lines of the loops over repeated entries (:mod:`.repeats`)."""
    printer = KernelPrinter(ordered=False)
    lines = []
    for run in runs:
        temporaries, (reduced,) = sp.cse(
            [run.template], symbols=sp.numbered_symbols("_y"), optimizations=None
        )
        index = f"{run.stride} * _i + {run.offset}" if run.offset else f"{run.stride} * _i"
        lines.append(f"    for _i in range({run.start}, {run.stop}):")
        for symbol, rhs in temporaries:
            lines += ["    " + line for line in _assignment(str(symbol), rhs, printer)]
        lines += ["    " + line for line in _assignment(f"{run.array}[{index}]", reduced, printer)]
    return lines


#: the arrays each point function writes (scatter loops add only into these)
WRITES = {
    "point_gradient": ("Lq", "Lv"),
    "point_hessian": ("Lq", "Lv", "Lqq", "Lqv", "Lvv"),
    "point_mass": ("Lq", "Lv", "Lqv", "Lvv"),
}


def _table_literal(name: str, table: np.ndarray) -> str:
    """One statement defining ``table`` (int64, 1-D or 2-D) as a module constant.

    numba freezes a global array into the compiled code as constant data: the
    loops read their indices without an argument, and the statement is one
    line whatever the number of rows.
    """
    values = ",".join(map(str, table.ravel().tolist()))
    shape = ", ".join(map(str, table.shape))
    return f"{name} = np.array([{values}], dtype=np.int64).reshape({shape})"


def _scattered_entries(group: ScatterGroup, arrays: tuple[str, ...]) -> list[int]:
    """Indices of ``group``'s derivative entries that add into ``arrays``."""
    return [e for e, (array, _) in enumerate(group.entries) if array in arrays]


def _touched(groups: tuple[ScatterGroup, ...], arrays: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Per array, the sorted slots some scatter loop adds into."""
    out: dict[str, list[np.ndarray]] = {}
    for group in groups:
        for e in _scattered_entries(group, arrays):
            out.setdefault(group.entries[e][0], []).append(group.slots[:, e])
    return {array: np.unique(np.concatenate(cols)) for array, cols in out.items()}


@lru_cache(maxsize=64)
def _group_code(group: ScatterGroup) -> tuple[list[str], list[str], str]:
    """One group's loop body, shared by every point function: the temporaries of a joint
    common-subexpression elimination of the template and all its derivatives, then
    per derivative the expression it adds, and the template's value.

    A point function that needs only some of the derivatives still computes
    every temporary in the source; the compiler drops the unused ones.
    """
    printer = KernelPrinter(ordered=False)
    exprs = [group.value] + [expr for _, expr in group.entries]
    temporaries, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"{group.name}_y"))
    lines = []
    for symbol, rhs in temporaries:
        lines += _assignment(str(symbol), rhs, printer)
    adds = [printer.doprint(expr) for expr in reduced[1:]]
    return lines, adds, printer.doprint(reduced[0])


def _group_statements(group: ScatterGroup, columns: list[int]) -> tuple[list, list[str]]:
    """The statements of one instance of ``group`` that the entries ``columns`` need,
    square roots and divisions lifted (:func:`.lanes.lifted_statements`), and the
    names of the entries' values (``{group}_a{e}``)."""
    temporaries, adds, _ = _group_code(group)
    pairs: list[tuple[str, str]] = []
    for line in temporaries:
        target, op, expression = line.split(maxsplit=2)
        if op == "+=":
            # a long sum written in chunks (_assignment): one assignment, the same order
            pairs[-1] = (target, f"({pairs[-1][1]}) + ({expression})")
        else:
            pairs.append((target, expression))
    targets = [f"{group.name}_a{e}" for e in columns]
    needed: set[str] = set()
    for e in columns:
        needed |= set(IDENTIFIER.findall(adds[e]))
    kept = []
    for name, expression in reversed(pairs):
        if name in needed:
            needed |= set(IDENTIFIER.findall(expression))
            kept.append((name, expression))
    assignments = kept[::-1] + [(t, adds[e]) for t, e in zip(targets, columns, strict=True)]
    return lifted_statements(assignments, f"{group.name}_l"), targets


def _local_names(group: ScatterGroup, statements: list) -> frozenset[str]:
    return frozenset([var for var, _ in group.reads] + [s.target for s in statements])


def _scatter_loop(group: ScatterGroup, columns: list[int], value: bool) -> list[str]:
    r"""Source lines of one group's loop: read the arguments, add the derivatives.

    ``value``: add the template itself into ``_total`` (the Lagrangian) instead.
    Instances run one at a time: written side by side (:mod:`.lanes`), a loop's
    body is four times as long and compiles several times slower
    (docs/design-notes.md), which a large system's build cannot afford.
    """
    temporaries, adds, total = _group_code(group)
    lines = [f"    for _k in range({group.count}):"]
    for i, (var, array) in enumerate(group.reads):
        lines.append(f"        {var} = {array}[{group.name}_args[_k, {i}]]")
    body = list(temporaries)
    if value:
        body.append(f"    _total += {total}")
    else:
        for e in columns:
            target = f"{group.entries[e][0]}[{group.name}_slots[_k, {e}]]"
            body.append(f"    {target} += {adds[e]}")
    return lines + ["    " + line for line in body]


def repeated_force_lines(spec: KernelSpec) -> list[str]:
    r"""Lines setting ``g_a`` to :math:`L_q` at the scalars ``q_a``, at :math:`v = 0`,
    for a system whose :math:`L_q` is its repeated terms alone (``spec.repeated_loop``).

    Each group's scatter loop unrolled: every instance's arguments read as scalars,
    the template's statements written for all instances side by side (square roots
    and divisions :data:`.lanes.LANES` at a time, :mod:`.lanes`), then per instance,
    in table order, the adds into the coordinates its slots name, so that every
    entry is the same sum in the same order as the point gradient's scatter loops
    compute it, bit for bit.
    """
    lines = [f"g_{a} = 0.0" for a in range(spec.n)]
    for group in spec.repeats:
        columns = [e for e, (array, _) in enumerate(group.entries) if array == "Lq"]
        if not columns:
            continue
        statements, targets = _group_statements(group, columns)
        suffixes = [f"_k{k}" for k in range(group.count)]
        for k, suffix in enumerate(suffixes):
            for i, (var, array) in enumerate(group.reads):
                index = int(group.table[k, i])
                read = {"q": f"q_{index}", "v": "0.0"}.get(array, f"{array}[{index}]")
                lines.append(f"{var}{suffix} = {read}")
        lines += lane_lines(statements, _local_names(group, statements), suffixes)
        for k, suffix in enumerate(suffixes):
            lines += [
                f"g_{int(group.slots[k, e])} += {target}{suffix}"
                for e, target in zip(columns, targets, strict=True)
            ]
    return lines


def _scatter_function(name: str, spec: KernelSpec, value: bool) -> tuple[list[str], list[str]]:
    """The part of point function ``name`` that runs the scatter loops, and its tables.

    It first zeroes every slot the loops add into (the caller zeroes the arrays
    only once), then runs one loop per group. Returns ``(lines, tables)``.
    """
    params = FUNCTIONS[name]
    lines = ["", "", "@part", f"def {name}_repeats({params}):"]
    tables = []
    if value:
        lines.append("    _total = 0.0")
        for group in spec.repeats:
            lines += _scatter_loop(group, [], value=True)
        return [*lines, "    return _total"], tables
    arrays = tuple(a for a in WRITES[name] if a != "Lqv" or spec.has_Lqv or name == "point_mass")
    for array, slots in _touched(spec.repeats, arrays).items():
        table = f"_zero_{name}_{array}"
        tables.append(_table_literal(table, slots))
        lines += [f"    for _k in range({slots.size}):", f"        {array}[{table}[_k]] = 0.0"]
    for group in spec.repeats:
        columns = _scattered_entries(group, arrays)
        if columns:
            lines += _scatter_loop(group, columns, value=False)
    return lines, tables


def _accumulated(name: str, spec: KernelSpec) -> frozenset[str]:
    """The slots of point function ``name`` that its scatter loops add into."""
    if not spec.repeats or name not in WRITES:
        return frozenset()
    arrays = tuple(a for a in WRITES[name] if a != "Lqv" or spec.has_Lqv or name == "point_mass")
    return frozenset(
        f"{array}[{slot}]"
        for array, slots in _touched(spec.repeats, arrays).items()
        for slot in slots.tolist()
    )


def _point_function(
    name: str,
    entries: list[tuple[str, sp.Expr]],
    large: bool,
    returns: sp.Expr | None = None,
    spec: KernelSpec | None = None,
) -> tuple[list[str], list[str]]:
    """Source lines of one point function, split into parts when ``large``, and its tables.

    In a large function, runs of entries that repeat one expression along the
    coordinates become loops (:mod:`.repeats`), in a part of their own; the
    repeated terms of the spec (:mod:`.scatter`) become scatter loops, in a
    part that runs first, and the entries they share slots with add to them.
    """
    params = FUNCTIONS[name]
    if not large:
        return ["", "", f"def {name}({params}):", *_function_body(entries, returns=returns)], []
    lines: list[str] = []
    tables: list[str] = []
    calls = []
    accumulate = frozenset()
    if spec is not None and spec.repeats and (returns is not None or name in WRITES):
        lines, tables = _scatter_function(name, spec, value=returns is not None)
        calls.append(f"{name}_repeats({params})")
        accumulate = _accumulated(name, spec)
    runs: list[Run] = []
    if returns is None and spec is not None:
        # a slot a scatter loop adds into is not a run's: runs assign
        free = [entry for entry in entries if entry[0] not in accumulate]
        runs, rest = find_runs(free, spec.n, spec.pattern if spec.banded else ())
        entries = rest + [entry for entry in entries if entry[0] in accumulate]
    if returns is not None:
        terms = sp.Add.make_args(returns)
        pieces = [
            ([], sp.Add(*terms[k : k + POINT_CHUNK])) for k in range(0, len(terms), POINT_CHUNK)
        ]
    else:
        pieces = [(entries[k : k + POINT_CHUNK], None) for k in range(0, len(entries), POINT_CHUNK)]
    if runs and not calls and returns is None and len(pieces) <= 1:
        # the loops and at most one part's entries: one function, compiled as one part
        # would be (calling parts costs an atomic reference count increment and
        # decrement per array argument and call, twice the loops' own work on a chain)
        chunk = pieces[0][0] if pieces else []
        body = _loop_body(runs) + (_function_body(chunk, large=True) if chunk else [])
        return ["", "", f"def {name}({params}):", *body], tables
    if runs:
        part = f"{name}_loops"
        lines += ["", "", "@part", f"def {part}({params}):", *_loop_body(runs)]
        calls.append(f"{part}({params})")
    for k, (chunk, partial) in enumerate(pieces):
        part = f"{name}_part{k}"
        lines += ["", "", "@part", f"def {part}({params}):"]
        lines += _function_body(chunk, returns=partial, large=True, accumulate=accumulate)
        calls.append(f"{part}({params})")
    if calls == [f"{name}_repeats({params})"]:
        # the scatter loops alone: they are the function (numba compiles one function,
        # not a part and a caller)
        return ["", "", f"def {name}({params}):", *lines[4:]], tables
    lines += ["", "", f"def {name}({params}):"]
    if returns is not None:
        lines.append("    total = 0.0")
        lines += [f"    total += {call}" for call in calls]
        lines.append("    return total")
    else:
        lines += [f"    {call}" for call in calls] or ["    pass"]
    return lines, tables


def _constraint_functions(spec: KernelSpec) -> list[str]:
    """Point functions of the constraints (none without constraints)."""
    if not spec.m:
        return []
    parts = (
        ("point_constraint", spec.constraint_entries),
        ("point_constraint_jacobian", spec.constraint_jacobian_entries),
        ("point_constraint_rate", spec.constraint_rate_entries),
        ("point_constraint_hessian", spec.constraint_hessian_entries),
    )
    return [
        line for name, entries in parts for line in _point_function(name, list(entries), False)[0]
    ]


def _contact_functions(spec: KernelSpec) -> list[str]:
    """Point functions of the contacts' gaps and slips (those the system has)."""
    parts = []
    if spec.contact_entries:
        parts.append(("point_contact", spec.contact_entries))
    if spec.slip_entries:
        parts.append(("point_slip", spec.slip_entries))
    return [
        line for name, entries in parts for line in _point_function(name, list(entries), False)[0]
    ]


_SLOT = re.compile(r"^    (\w+)(\[\d+\])? (\+?=) (.*)$")


def at_rest(body: list[str], targets: dict[str, str]) -> list[str]:
    """A point function's body as lines of a generated loop: at the scalars ``q_a``,
    at ``v = 0``, unindented, keeping the assignments to ``targets``.

    ``targets`` maps an array (``"Lq"``: every entry ``Lq[a]`` to ``g_a``) or one
    entry (``"Lvv[3]"``) to the scalar it becomes; assignments to other slots are
    left out (their temporaries stay: numba drops what nothing reads). The
    expressions are the point function's text, so they round as it does.
    """
    return scalar_lines(body, targets, {"q": "q", "v": None})


def scalar_lines(
    body: list[str], targets: dict[str, str], reads: dict[str, str | None]
) -> list[str]:
    """A point function's body as lines of a generated loop, unindented: each entry
    ``x[a]`` of an array ``x`` of ``reads`` read as the scalar ``{reads[x]}_a`` (as
    ``0.0`` where ``reads[x]`` is None), the assignments to ``targets`` kept as in
    :func:`at_rest`."""
    out = []
    for line in body:
        if line == "    pass":
            continue
        match = _SLOT.match(line)
        if match is None:
            raise ValueError(f"unexpected line in a point function: {line!r}")
        target, index, op, expr = match.groups()
        if index is not None:
            slot = target + index
            if slot in targets:
                target = targets[slot]
            elif target in targets:
                target = f"{targets[target]}_{index[1:-1]}"
            else:
                continue
        for array, scalar in reads.items():
            pattern = rf"\b{array}\[(\d+)\]"
            expr = re.sub(pattern, "0.0" if scalar is None else rf"{scalar}_\1", expr)
        out.append(f"{target} {op} {expr}")
    return out


def render_module(spec: KernelSpec, key: str) -> str:
    """Source text of the point-function module of ``spec``.

    Parameters
    ----------
    spec : KernelSpec
    key : str
        The cache key; written on the first and last line so that a truncated
        or foreign file is recognised.
    """
    large = len(spec.hessian_entries) > LARGE or bool(spec.repeats)
    head = [
        f"# galerkin_vi point functions {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
    ]
    if large:
        head += [
            "",
            "import numpy as np",
            "from numba import njit",
            "",
            "# the parts of a large point function: compiled once each, and called",
            'part = njit(cache=True, error_model="numpy")',
        ]
    functions = [
        _point_function("point_gradient", list(spec.gradient_entries), large, spec=spec),
        _point_function("point_hessian", list(spec.hessian_entries), large, spec=spec),
        _point_function("lagrangian", [], large, returns=spec.lagrangian, spec=spec),
        _point_function("point_mass", list(spec.mass_entries), large, spec=spec),
    ]
    if spec.velocity_entries:
        # straight-line code (no scatter loops: systems with repeated terms have none)
        functions.append(_point_function("point_velocity", list(spec.velocity_entries), large))
    steps = []
    if spec.repeated_loop:
        # the explicit loop with the repeated terms' force unrolled (specialize="system");
        # the roots and quotients of its pairs bound a small pair force, and numba
        # vectorises none of them on its own
        head += ["import numpy as np", LANES_IMPORT]
        steps += render_explicit_steps(
            repeated_force_lines(spec), spec.n, spec.periodic, spec.diagonal_mass,
            spec.autonomous, name="repeated_explicit_steps",
        )  # fmt: skip
    if spec.velocity_entries and not large and spec.n <= METHOD_UNROLLED:
        # what a velocity-stage loop generated per method (:mod:`.velocity_steps`) is
        # written from: the closed-form velocity and the force of the first step
        velocity = scalar_lines(functions[4][0][3:], {"V": "V", "F": "F"}, {"q": "q", "p": "p"})
        force = scalar_lines(functions[3][0][3:], {"Lq": "F"}, {"q": "q", "v": "v"})
        steps += ["", "", *velocity_text_lines(velocity, force, spec.n, spec.periodic)]
    if spec.generated_loops:
        # the force and the mass as the point functions compute them (their text, so the
        # same rounding; straight-line code, as a system with generated loops is not
        # large), at v = 0, into scalars
        head.append("import numpy as np")
        gradient, hessian = functions[0][0][3:], functions[1][0][3:]
        force = [f"g_{a} = 0.0" for a in range(spec.n)] + at_rest(gradient, {"Lq": "g"})
        steps += render_explicit_steps(
            force, spec.n, spec.periodic, spec.diagonal_mass, spec.autonomous
        )
        if has_stage_steps(spec):
            head += ["", *STAGE_IMPORTS]
            diagonal = {
                f"Lvv[{spec.pattern.index((a, a)) if spec.banded else a * spec.n + a}]": f"m_{a}"
                for a in range(spec.n)
            }
            mass = [f"m_{a} = 0.0" for a in range(spec.n)] + at_rest(hessian, diagonal)
            steps += render_stage_steps(force, mass, spec.n, spec.periodic, spec.autonomous)
            # what a loop generated per method (:mod:`.method_steps`) is written from
            steps += ["", "", *loop_text_lines(force, mass, spec.n, spec.periodic, spec.autonomous)]
    tables = [
        _table_literal(f"{group.name}_{what}", array)
        for group in spec.repeats
        for what, array in (("args", group.table), ("slots", group.slots))
    ]
    tables += [table for _, function_tables in functions for table in function_tables]
    body = [line for lines, _ in functions for line in lines] + _constraint_functions(spec)
    body += _contact_functions(spec)
    body += steps
    if tables:
        head += ["", "# index tables of the repeated terms' scatter loops", *tables]
    tail = ["", "", f"# end of galerkin_vi point functions {key}", ""]
    return "\n".join(head + body + tail)
