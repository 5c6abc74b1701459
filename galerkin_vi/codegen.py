r"""From the point-wise SymPy pieces of a system to kernel source text.

Stages (each a pure function of the previous one's output):

1. :func:`kernel_spec` collects the expressions of :math:`L`, :math:`L_q`,
   :math:`L_v`, :math:`L_{qq}`, :math:`L_{qv}`, :math:`L_{vv}`, drops the
   entries that are identically zero and renames the user's symbols to array
   slots ``q[a]``, ``v[a]``, ``prm[j]``.
2. :func:`signature` hashes the spec with the generator version and the
   sources of the time loop, naming the cache entry.
3. :func:`render_module` runs one joint common-subexpression elimination per
   point function, prints it strictly (an unsupported function fails here, not
   at run time) and appends the time loop of :mod:`.backends.kernel_template`.

This module only prints; compiling and caching are the backends' job.
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from .separable import has_stage_form

if TYPE_CHECKING:
    from .system import LagrangianSystem

__all__ = [
    "GENERATOR_VERSION",
    "KernelSpec",
    "kernel_spec",
    "render_module",
    "signature",
    "sparsity_pattern",
    "use_banded",
    "unsupported_functions",
]

GENERATOR_VERSION = "4"
_KERNEL_MARKER = "\n# ---- kernel ----\n"
_END_MARKER = "\n# ---- end kernel ----\n"


@dataclass(frozen=True)
class KernelSpec:
    """Language-neutral description of one system's point functions.

    Each ``*_entries`` is a tuple of ``(target, expression)`` with target an
    array slot such as ``"Lqq[0, 1]"``; identically zero entries are absent.
    """

    n: int
    n_params: int
    autonomous: bool
    has_Lqv: bool
    lagrangian: sp.Expr
    gradient_entries: tuple[tuple[str, sp.Expr], ...]
    hessian_entries: tuple[tuple[str, sp.Expr], ...]
    pattern: tuple[tuple[int, int], ...] = ()
    half_bandwidth: int = 0
    banded: bool = False
    has_fv: bool = False
    m: int = 0
    periodic: tuple[bool, ...] = ()
    separable: bool = False
    diagonal_mass: bool = False
    constraint_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_jacobian_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_rate_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_hessian_entries: tuple[tuple[str, sp.Expr], ...] = ()

    @property
    def constraint_parts(self) -> tuple[tuple[str, sp.Expr], ...]:
        """Every constraint entry, in a fixed order (for hashing)."""
        return (
            self.constraint_entries
            + self.constraint_jacobian_entries
            + self.constraint_rate_entries
            + self.constraint_hessian_entries
        )

    @property
    def nnz(self) -> int:
        """Number of stored entries of each second-derivative block."""
        return len(self.pattern) if self.banded else self.n * self.n


def sparsity_pattern(pieces, n: int, has_lqv: bool) -> tuple[tuple[int, int], ...]:
    """Union of the structural nonzeros of L_qq + f_q, L_vv, L_qv, f_v and transposes, row-major."""
    blocks = [pieces.force_q, pieces.Lvv] + ([pieces.Lqv] if has_lqv else [])
    if pieces.fv is not None:
        blocks.append(pieces.fv)
    pairs = set()
    for block in blocks:
        for (a, b), e in block.todok().items():
            if e != 0:
                pairs.add((a, b))
                pairs.add((b, a))
    pairs.update((a, a) for a in range(n))  # the diagonal, so every coordinate has a row
    return tuple(sorted(pairs))


def use_banded(n: int, half_bandwidth: int) -> bool:
    """Banded storage and LU pay when the coupling band is narrow against n.

    With s control points the stage Jacobian, ordered coordinate-major, has
    half-bandwidth (w + 1) s - 1 for coordinate coupling |a - b| <= w: a banded LU
    costs O(n s^3 w^2) instead of O(n^3 s^3).
    """
    return n >= 8 and 4 * (half_bandwidth + 1) <= n


def kernel_spec(system: LagrangianSystem) -> KernelSpec:
    """Collect the expressions of ``system`` with symbols renamed to array slots."""
    n = system.n
    rename: dict[sp.Symbol, sp.Symbol] = {}
    for a, s in enumerate(system.q):
        rename[s] = sp.Symbol(f"q[{a}]", real=True)
    for a, s in enumerate(system.v):
        rename[s] = sp.Symbol(f"v[{a}]", real=True)
    for j, s in enumerate(system.params):
        rename[s] = sp.Symbol(f"prm[{j}]", real=True)
    if system.t is not None:
        rename[system.t] = sp.Symbol("t", real=True)
    p = system.pieces
    has_lqv = not system.structure.zero_Lqv
    pattern = sparsity_pattern(p, n, has_lqv)
    half_bandwidth = max(abs(a - b) for a, b in pattern) if pattern else 0
    m = system.m
    # the constrained loop is dense: multipliers couple every coordinate they touch
    banded = use_banded(n, half_bandwidth) and m == 0
    position = {pair: k for k, pair in enumerate(pattern)}

    def vector(name: str, column: sp.Matrix) -> list[tuple[str, sp.Expr]]:
        return [(f"{name}[{a}]", e.xreplace(rename)) for a, e in enumerate(column) if e != 0]

    def matrix(name: str, block: sp.MatrixBase) -> list[tuple[str, sp.Expr]]:
        # flat storage: slot a*n + b (dense), or the pattern position of (a, b) (banded)
        out = []
        for (a, b), e in sorted(block.todok().items()):
            if e != 0:
                k = position[(a, b)] if banded else a * n + b
                out.append((f"{name}[{k}]", e.xreplace(rename)))
        return out

    has_fv = not system.structure.zero_fv
    # forces enter where L_q does: the kernels see L_q + f and L_qq + f_q
    gradient = vector("Lq", p.force) + vector("Lv", p.Lv)
    hessian = (
        gradient
        + matrix("Lqq", p.force_q)
        + (matrix("Lqv", p.Lqv) if has_lqv else [])
        + matrix("Lvv", p.Lvv)
        + (matrix("Fv", p.fv) if has_fv else [])
    )
    return KernelSpec(
        n=n,
        n_params=len(system.params),
        autonomous=system.structure.autonomous,
        has_Lqv=has_lqv,
        lagrangian=p.L.xreplace(rename),
        gradient_entries=tuple(gradient),
        hessian_entries=tuple(hessian),
        pattern=pattern if banded else (),
        half_bandwidth=half_bandwidth,
        banded=banded,
        has_fv=has_fv,
        periodic=system.periodic,
        separable=has_stage_form(system),
        diagonal_mass=system.structure.constant_mass
        and all(a == b for (a, b), e in p.Lvv.todok().items() if e != 0),
        **_constraint_entries(system, rename),
    )


def _constraint_entries(system: LagrangianSystem, rename: dict) -> dict:
    r"""Entries of the constraint point functions (empty without constraints).

    ``g[j]``, ``Gq[j n + a]`` (dense Jacobian), ``gt[j]`` and
    ``Hg[a n + b]`` :math:`= \sum_j \lambda_j \partial^2 g_j/\partial q_a\partial q_b`
    with the multipliers read from ``lam[j]``.
    """
    pieces = system.constraint_pieces
    if pieces is None:
        return {}
    m = system.m
    rename = dict(rename)
    rename[system.time_symbol] = sp.Symbol("t", real=True)
    lam = [sp.Symbol(f"lam[{j}]", real=True) for j in range(m)]

    def flat(name: str, matrix: sp.Matrix) -> tuple[tuple[str, sp.Expr], ...]:
        return tuple((f"{name}[{k}]", e.xreplace(rename)) for k, e in enumerate(matrix) if e != 0)

    return {
        "m": m,
        "constraint_entries": flat("g", pieces.g),
        "constraint_jacobian_entries": flat("Gq", pieces.jacobian),
        "constraint_rate_entries": flat("gt", pieces.rate),
        "constraint_hessian_entries": flat("Hg", pieces.contracted_hessian(lam)),
    }


def _loop_sources() -> str:
    """Every source that shapes a generated module: the printer and the time loop."""
    pkg = resources.files("galerkin_vi")
    return "".join(
        (pkg / path).read_text()
        for path in (
            "codegen.py",
            "newton.py",
            "backends/kernel_template.py",
            "backends/constrained_template.py",
            "backends/separable_template.py",
        )
    )


def signature(spec: KernelSpec, backend: str, backend_version: str) -> str:
    """SHA-256 naming the cache entry of ``spec`` for ``backend``."""
    h = hashlib.sha256()
    for part in (
        GENERATOR_VERSION,
        backend,
        backend_version,
        sys.version,
        repr((spec.n, spec.n_params, spec.autonomous, spec.has_Lqv, spec.banded, spec.has_fv)),
        repr(
            (
                spec.half_bandwidth,
                spec.pattern,
                spec.m,
                spec.periodic,
                spec.separable,
                spec.diagonal_mass,
            )
        ),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.constraint_parts),
        sp.srepr(spec.lagrangian),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.hessian_entries),
        _loop_sources(),
    ):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


class _KernelPrinter(PythonCodePrinter):
    """Python printer with round-trip float literals and strict function support."""

    def __init__(self, ordered: bool = True) -> None:
        settings = {"strict": True, "fully_qualified_modules": True}
        if not ordered:
            settings["order"] = "none"
        super().__init__(settings)

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        return expr.name

    def _print_Integer(self, expr: sp.Integer) -> str:
        # numba cannot type an integer literal beyond 64 bits ((2/3)**100 is exact in SymPy)
        return str(expr.p) if abs(expr.p) < 2**63 else repr(float(expr))

    def _print_Rational(self, expr: sp.Rational) -> str:
        if max(abs(expr.p), expr.q) < 2**63:
            return f"{expr.p}/{expr.q}"
        return repr(float(expr))

    def _print_Piecewise(self, expr: sp.Piecewise) -> str:
        # without an otherwise branch Python's printer ends in "else None", which numba
        # cannot type: undefined is NaN, as in the NumPy evaluator (a ConvergenceError)
        if expr.args[-1].cond != sp.true:
            expr = sp.Piecewise(*expr.args, (sp.nan, True), evaluate=False)
        return super()._print_Piecewise(expr)

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        # half-integer powers (gravity, r**(-3/2)) as sqrt and integer powers:
        # a call to pow costs several times a sqrt and a few multiplications
        exponent = expr.exp
        if isinstance(exponent, sp.Rational) and exponent.q == 2 and abs(exponent.p) <= 9:
            base = self.parenthesize(expr.base, sp.printing.precedence.PRECEDENCE["Pow"])
            whole = (abs(exponent.p) - 1) // 2
            magnitude = f"math.sqrt({self._print(expr.base)})"
            if whole:
                power = base if whole == 1 else f"{base}**{whole}"
                magnitude = f"({power}*{magnitude})"
            return magnitude if exponent.p > 0 else f"(1.0/{magnitude})"
        if exponent.is_Integer and exponent < 0:
            # numba raises ZeroDivisionError for 0.0**-n whatever its error model; a
            # division gives inf, which the kernel reports as a ConvergenceError
            base = self.parenthesize(expr.base, sp.printing.precedence.PRECEDENCE["Pow"])
            return f"(1.0/{base})" if exponent == -1 else f"(1.0/{base}**{-exponent})"
        return super()._print_Pow(expr, rational=rational)


# operations SymPy leaves unevaluated (an integral without a closed form, the
# derivative of floor): no printer evaluates them
_UNEVALUATED = (sp.Derivative, sp.Integral, sp.Subs, sp.Product, sp.Limit, sp.Order)


def unsupported_functions(expr: sp.Basic) -> list[str]:
    """Names of the functions (and unevaluated operations) in ``expr`` that the kernel
    printer cannot print."""
    printer = _KernelPrinter()
    names = set()
    for f in expr.atoms(sp.Function, *_UNEVALUATED):
        if isinstance(f, _UNEVALUATED):
            names.add(type(f).__name__)
            continue
        try:
            printer.doprint(f)
        except (NotImplementedError, TypeError, ValueError):
            names.add(type(f).__name__)
    return sorted(names)


def _function_body(
    entries: list[tuple[str, sp.Expr]], returns: sp.Expr | None = None, large: bool = False
) -> list[str]:
    # SymPy's "basic" CSE optimisations and sorted printing cost minutes on thousands
    # of entries (a chain of 1000 masses: 18 s against 1.2 s without); large systems
    # go without them
    small = not large
    printer = _KernelPrinter(ordered=small)
    exprs = [e for _, e in entries] + ([returns] if returns is not None else [])
    temporaries, reduced = sp.cse(
        exprs,
        symbols=sp.numbered_symbols("_x"),
        optimizations="basic" if small else None,
        order="canonical" if small else "none",
    )
    lines = []
    for sym, rhs in temporaries:
        lines += _assignment(str(sym), rhs, printer)
    for (slot, _), expr in zip(entries, reduced[: len(entries)], strict=True):
        lines += _assignment(slot, expr, printer)
    if returns is not None:
        lines += _assignment("_result", reduced[-1], printer)
        lines.append("    return _result")
    return lines or ["    pass"]


# numba's compile time grows faster than linearly with a function's length: large
# point functions are split into parts of this many entries, compiled separately
POINT_CHUNK = 200


def _point_function(
    name: str,
    params: str,
    entries: list[tuple[str, sp.Expr]],
    large: bool,
    returns: sp.Expr | None = None,
) -> list[str]:
    """Source lines of one point function, split into parts when ``large``."""
    if not large:
        body = _function_body(entries, returns=returns)
        return ["", "", "@point_kernel", f"def {name}({params}):", *body]
    if returns is not None:
        terms = sp.Add.make_args(returns)
        pieces = [
            ([], sp.Add(*terms[k : k + POINT_CHUNK])) for k in range(0, len(terms), POINT_CHUNK)
        ]
    else:
        pieces = [(entries[k : k + POINT_CHUNK], None) for k in range(0, len(entries), POINT_CHUNK)]
    lines: list[str] = []
    calls = []
    for k, (chunk, partial) in enumerate(pieces):
        part = f"{name}_part{k}"
        lines += ["", "", "@point_kernel", f"def {part}({params}):"]
        lines += _function_body(chunk, returns=partial, large=True)
        calls.append(f"{part}({params})")
    lines += ["", "", "@point_kernel", f"def {name}({params}):"]
    if returns is not None:
        lines.append("    total = 0.0")
        lines += [f"    total += {call}" for call in calls]
        lines.append("    return total")
    else:
        lines += [f"    {call}" for call in calls] or ["    pass"]
    return lines


# Python's parser nests a + b + c + ... one level per operator: long sums are
# accumulated in chunks (a Lagrangian of 1000 springs otherwise fails to compile)
_SUM_CHUNK = 32


def _assignment(target: str, expr: sp.Expr, printer: _KernelPrinter) -> list[str]:
    terms = sp.Add.make_args(expr)
    if len(terms) <= _SUM_CHUNK:
        return [f"    {target} = {printer.doprint(expr)}"]
    chunks = [sp.Add(*terms[k : k + _SUM_CHUNK]) for k in range(0, len(terms), _SUM_CHUNK)]
    lines = [f"    {target} = {printer.doprint(chunks[0])}"]
    lines += [f"    {target} += {printer.doprint(chunk)}" for chunk in chunks[1:]]
    return lines


# point functions with more statements than this are not inlined (compile time)
INLINE_LIMIT = 120


def _point_decorator(spec: KernelSpec, decorator: str) -> str:
    if len(spec.hessian_entries) <= INLINE_LIMIT or "inline" not in decorator:
        return decorator
    return decorator.replace(', inline="always"', "")


def _pattern_lines(spec: KernelSpec) -> list[str]:
    """Row, column and transposed position of each stored entry (banded storage only)."""
    pattern = spec.pattern or ((0, 0),)  # numba needs a typed, non-empty constant
    position = {pair: k for k, pair in enumerate(pattern)}
    rows = ", ".join(str(a) for a, _ in pattern)
    cols = ", ".join(str(b) for _, b in pattern)
    transposed = ", ".join(str(position.get((b, a), 0)) for a, b in pattern)
    return [
        f"PATTERN_ROW = np.array([{rows}], dtype=np.int64)",
        f"PATTERN_COL = np.array([{cols}], dtype=np.int64)",
        f"PATTERN_T = np.array([{transposed}], dtype=np.int64)",
    ]


def _kernel_section(path: str) -> str:
    text = (resources.files("galerkin_vi") / path).read_text()
    body = text.split(_KERNEL_MARKER, 1)[1]
    return body.split(_END_MARKER, 1)[0]


def _constraint_functions(spec: KernelSpec) -> list[str]:
    """Point functions of the constraints (none without constraints)."""
    if not spec.m:
        return []
    return [
        *_point_function("point_constraint", "t, q, prm, g", list(spec.constraint_entries), False),
        *_point_function(
            "point_constraint_jacobian",
            "t, q, prm, Gq",
            list(spec.constraint_jacobian_entries),
            False,
        ),
        *_point_function(
            "point_constraint_rate", "t, q, prm, gt", list(spec.constraint_rate_entries), False
        ),
        *_point_function(
            "point_constraint_hessian",
            "t, q, lam, prm, Hg",
            list(spec.constraint_hessian_entries),
            False,
        ),
    ]


def render_module(
    spec: KernelSpec,
    key: str,
    decorator: str = 'njit(cache=True, inline="always", error_model="numpy")',
) -> str:
    """Source text of the kernel module for ``spec``.

    Parameters
    ----------
    spec : KernelSpec
    key : str
        The cache key; written on the first and last line so that a truncated
        or foreign file is recognised.
    decorator : str
        Expression applied to every kernel function. The compiled backend's
        uses numba's NumPy error model: a division by zero gives inf or NaN (and
        a ConvergenceError with the partial trajectory) instead of raising
        ZeroDivisionError out of the kernel.
    """
    large = len(spec.hessian_entries) > INLINE_LIMIT
    head = [
        f"# galerkin_vi generated kernel {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
        "",
        "import numpy as np",
        "from numba import njit",
        "",
        f"kernel = {decorator}",
        # large point functions are compiled once and called, not inlined at every call site
        f"point_kernel = {_point_decorator(spec, decorator)}",
        f"N = {spec.n}",
        f"N_PARAMS = {spec.n_params}",
        f"AUTONOMOUS = {spec.autonomous}",
        f"HAS_LQV = {spec.has_Lqv}",
        f"HAS_FV = {spec.has_fv}",
        f"DIAGONAL_MASS = {spec.diagonal_mass}",
        f"M_CONSTRAINTS = {spec.m}",
        f"HAS_PERIODIC = {any(spec.periodic)}",
        "PERIODIC = np.array([{}], dtype=np.bool_)".format(
            ", ".join(str(x) for x in (spec.periodic or (False,)))
        ),
        "TWO_PI_HI = 6.283185307179586",
        "TWO_PI_LO = 2.4492935982947064e-16",
        f"BANDED = {spec.banded}",
        f"BAND = {spec.half_bandwidth}",
        f"NNZ = {spec.nnz}",
        *_pattern_lines(spec),
        "",
        "",
        *_point_function(
            "point_gradient", "t, q, v, prm, Lq, Lv", list(spec.gradient_entries), large
        ),
        *_point_function(
            "point_hessian",
            "t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv",
            list(spec.hessian_entries),
            large,
        ),
        *_point_function("lagrangian", "t, q, v, prm", [], large, returns=spec.lagrangian),
        *_constraint_functions(spec),
        "",
    ]
    newton = _kernel_section("newton.py")
    loop = _kernel_section("backends/kernel_template.py")
    if spec.m:
        loop += _kernel_section("backends/constrained_template.py")
    if spec.separable:
        loop += _kernel_section("backends/separable_template.py")
    # newton's helpers are plain functions; the loop calls them from jitted code
    newton = newton.replace("\ndef ", "\n@kernel\ndef ")
    tail = [f"# end of generated kernel {key}", ""]
    return "\n".join(head) + newton + loop + "\n".join(tail)
