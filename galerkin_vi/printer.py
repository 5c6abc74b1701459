"""The printer of point functions: SymPy expressions as numba-compilable Python.

Strict (an unsupported function fails at generation, not at run time),
round-trip float literals, and the few rewrites that numba needs or that pay
at run time (half-integer powers as square roots, no integer literals beyond
64 bits, NaN for an undefined Piecewise).
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from .expression_walk import distinct_nodes

__all__ = ["KernelPrinter", "unsupported_functions"]


class KernelPrinter(PythonCodePrinter):
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
    printer = KernelPrinter()
    names = set()
    kinds = (sp.Function, *_UNEVALUATED)
    # each distinct subexpression once: a lattice's derivatives share most of theirs
    for f in (node for node in distinct_nodes([expr]) if isinstance(node, kinds)):
        if isinstance(f, _UNEVALUATED):
            names.add(type(f).__name__)
            continue
        try:
            printer.doprint(f)
        except (NotImplementedError, TypeError, ValueError):
            names.add(type(f).__name__)
    return sorted(names)
