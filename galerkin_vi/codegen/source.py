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

import sympy as sp

from ..printer import KernelPrinter
from .repeats import Run, find_runs
from .spec import KernelSpec

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
}

# numba's compile time grows faster than linearly with a function's length: large
# point functions are split into parts of this many entries, compiled separately
POINT_CHUNK = 200
# a function with more entries than this is split into parts
LARGE = 120
# Python's parser nests a + b + c + ... one level per operator: long sums are
# accumulated in chunks (a Lagrangian of 1000 springs otherwise fails to compile)
_SUM_CHUNK = 32


def _assignment(target: str, expr: sp.Expr, printer: KernelPrinter) -> list[str]:
    terms = sp.Add.make_args(expr)
    if len(terms) <= _SUM_CHUNK:
        return [f"    {target} = {printer.doprint(expr)}"]
    chunks = [sp.Add(*terms[k : k + _SUM_CHUNK]) for k in range(0, len(terms), _SUM_CHUNK)]
    lines = [f"    {target} = {printer.doprint(chunks[0])}"]
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
    return rewritten, [(symbol, base) for base, symbol in roots.items()]


def _function_body(
    entries: list[tuple[str, sp.Expr]], returns: sp.Expr | None = None, large: bool = False
) -> list[str]:
    # SymPy's "basic" CSE optimisations and sorted printing cost minutes on thousands
    # of entries (a chain of 1000 masses: 18 s against 1.2 s without); large systems
    # go without them
    small = not large
    printer = KernelPrinter(ordered=small)
    exprs = [e for _, e in entries] + ([returns] if returns is not None else [])
    exprs, roots = shared_quarter_roots(exprs)
    temporaries, reduced = sp.cse(
        exprs,
        symbols=sp.numbered_symbols("_x"),
        optimizations="basic" if small else None,
        order="canonical" if small else "none",
    )
    lines = [
        f"    {symbol} = math.sqrt(math.sqrt({printer.doprint(base)}))" for symbol, base in roots
    ]
    for sym, rhs in temporaries:
        lines += _assignment(str(sym), rhs, printer)
    for (slot, _), expr in zip(entries, reduced[: len(entries)], strict=True):
        lines += _assignment(slot, expr, printer)
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


def _point_function(
    name: str,
    entries: list[tuple[str, sp.Expr]],
    large: bool,
    returns: sp.Expr | None = None,
    spec: KernelSpec | None = None,
) -> list[str]:
    """Source lines of one point function, split into parts when ``large``.

    In a large function, runs of entries that repeat one expression along the
    coordinates become loops (:mod:`.repeats`), in a part of their own.
    """
    params = FUNCTIONS[name]
    if not large:
        return ["", "", f"def {name}({params}):", *_function_body(entries, returns=returns)]
    runs: list[Run] = []
    if returns is None and spec is not None:
        runs, entries = find_runs(entries, spec.n, spec.pattern if spec.banded else ())
    if returns is not None:
        terms = sp.Add.make_args(returns)
        pieces = [
            ([], sp.Add(*terms[k : k + POINT_CHUNK])) for k in range(0, len(terms), POINT_CHUNK)
        ]
    else:
        pieces = [(entries[k : k + POINT_CHUNK], None) for k in range(0, len(entries), POINT_CHUNK)]
    lines: list[str] = []
    calls = []
    if runs:
        part = f"{name}_loops"
        lines += ["", "", "@part", f"def {part}({params}):", *_loop_body(runs)]
        calls.append(f"{part}({params})")
    for k, (chunk, partial) in enumerate(pieces):
        part = f"{name}_part{k}"
        lines += ["", "", "@part", f"def {part}({params}):"]
        lines += _function_body(chunk, returns=partial, large=True)
        calls.append(f"{part}({params})")
    lines += ["", "", f"def {name}({params}):"]
    if returns is not None:
        lines.append("    total = 0.0")
        lines += [f"    total += {call}" for call in calls]
        lines.append("    return total")
    else:
        lines += [f"    {call}" for call in calls] or ["    pass"]
    return lines


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
    return [line for name, entries in parts for line in _point_function(name, list(entries), False)]


def render_module(spec: KernelSpec, key: str) -> str:
    """Source text of the point-function module of ``spec``.

    Parameters
    ----------
    spec : KernelSpec
    key : str
        The cache key; written on the first and last line so that a truncated
        or foreign file is recognised.
    """
    large = len(spec.hessian_entries) > LARGE
    head = [
        f"# galerkin_vi point functions {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
    ]
    if large:
        head += [
            "",
            "from numba import njit",
            "",
            "# the parts of a large point function: compiled once each, and called",
            'part = njit(cache=True, error_model="numpy")',
        ]
    body = [
        *_point_function("point_gradient", list(spec.gradient_entries), large, spec=spec),
        *_point_function("point_hessian", list(spec.hessian_entries), large, spec=spec),
        *_point_function("lagrangian", [], large, returns=spec.lagrangian),
        *_point_function("point_mass", list(spec.mass_entries), large, spec=spec),
        *_constraint_functions(spec),
    ]
    tail = ["", "", f"# end of galerkin_vi point functions {key}", ""]
    return "\n".join(head + body + tail)
